"""Layouts: parsing, errors that name the row and column, the geodesic distance field."""

import numpy as np
import pytest

from mindgap.envs.terrain import LayoutError, parse_layout
from mindgap.envs.terrain.layout import GOAL, ICE, SAND, WALL, geodesic_distance


def test_parses_codes_and_starts():
    lay = parse_layout(
        """
        #####
        #S~:#
        #.PG#
        #####
        """
    )
    assert lay.shape == (4, 5)
    assert lay.grid[1, 2] == ICE and lay.grid[1, 3] == SAND and lay.grid[2, 3] == GOAL and lay.grid[0, 0] == WALL
    assert lay.starts.tolist() == [[1, 1]]


@pytest.mark.parametrize(
    "text,pattern",
    [
        ("#####\n#S.G#\n####\n", r"row 3 has 4 columns, row 1 has 5"),
        ("#####\n#S.x#\n#..G#\n#####", r"row 2, column 4: unknown character 'x'"),
        ("#####\n#..G#\n#####", r"no start cell"),
        ("#####\n#S..#\n#####", r"no goal cell"),
        ("#######\n#S.#.G#\n#######", r"goal \(row 2, column 6\) cannot be reached from the start at row 2, column 2"),
        ("#####\n#SPG#\n#####", r"cannot be reached"),  # only through a pit
        ("######\n#S.#.#\n#..#G#\n######", r"cannot be reached"),
        ("", r"empty layout"),
    ],
)
def test_malformed_layouts_name_the_place(text, pattern):
    with pytest.raises(LayoutError, match=pattern):
        parse_layout(text)


def test_diagonal_gap_closed_by_two_walls_does_not_connect():
    with pytest.raises(LayoutError, match="cannot be reached"):
        parse_layout("#####\n#S###\n##.G#\n#####")  # S touches the floor only at a corner between walls


def test_geodesic_distance_goes_around_walls():
    lay = parse_layout(
        """
        #####
        #S#G#
        #...#
        #####
        """
    )
    d = geodesic_distance(lay.grid)
    assert d[1, 3] == 0
    assert d[2, 3] == pytest.approx(1.0)
    assert d[2, 2] == pytest.approx(np.sqrt(2))  # diagonal past the wall's corner (one side is open)
    assert d[1, 1] == pytest.approx(2 * np.sqrt(2))  # S → (2,2) → G: two diagonal steps
    assert np.isinf(d[0, 0]) and np.isinf(d[1, 2])
