"""ASCII layouts of terrain worlds: parsing, validation and the geodesic distance field.

A layout is a rectangle of characters, one per cell::

    #  wall      .  floor     ~  ice      :  sand
    P  pit       G  goal      S  start (floor)

Row 0 is the top line; a position ``(x, y)`` lies in column ``floor(x)`` and row
``floor(y)``, so ``x`` grows to the right and ``y`` downwards. Everything outside the
rectangle behaves like wall. Plain NumPy: layouts are parsed once, outside any jitted code.
"""

from __future__ import annotations

import heapq
from typing import NamedTuple

import numpy as np

FLOOR, ICE, SAND, PIT, GOAL, WALL = range(6)
TERRAINS = ("floor", "ice", "sand", "pit", "goal")  # the rows of a dynamics table (walls have none)
CHARS = {".": FLOOR, "S": FLOOR, "~": ICE, ":": SAND, "P": PIT, "G": GOAL, "#": WALL}
CODE_CHARS = {FLOOR: ".", ICE: "~", SAND: ":", PIT: "P", GOAL: "G", WALL: "#"}


class LayoutError(ValueError):
    """A layout that cannot describe a world; the message names the row and column."""


class Layout(NamedTuple):
    """A parsed layout.

    Attributes:
        grid: [H, W] int terrain codes (FLOOR … WALL).
        starts: [n, 2] (row, col) of the start cells.
        text: the layout as given, normalised to one line per row.
    """

    grid: np.ndarray
    starts: np.ndarray
    text: str

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape

    def cells(self, code: int) -> np.ndarray:
        """[n, 2] (row, col) of every cell with terrain ``code``."""
        return np.argwhere(self.grid == code)


def parse_layout(text: str) -> Layout:
    """Parse and validate an ASCII layout.

    Leading/trailing blank lines and the common indentation are ignored. Errors name the
    row and column (counted from 1, as an editor shows them).

    Raises:
        LayoutError: ragged rows, unknown characters, no start, no goal, or a goal that
            cannot be reached from every start.
    """
    lines = [ln.rstrip() for ln in text.strip("\n").splitlines()]
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise LayoutError("empty layout")
    indent = min(len(ln) - len(ln.lstrip()) for ln in lines if ln.strip())
    lines = [ln[indent:] for ln in lines]
    width = len(lines[0])
    for r, ln in enumerate(lines):
        if len(ln) != width:
            raise LayoutError(f"row {r + 1} has {len(ln)} columns, row 1 has {width}: rows must be the same length")
        for c, ch in enumerate(ln):
            if ch not in CHARS:
                known = " ".join(CHARS)
                raise LayoutError(f"row {r + 1}, column {c + 1}: unknown character {ch!r} (known: {known})")
    grid = np.array([[CHARS[ch] for ch in ln] for ln in lines], dtype=np.int32)
    starts = np.argwhere(np.array([[ch == "S" for ch in ln] for ln in lines]))
    if len(starts) == 0:
        raise LayoutError("layout has no start cell 'S'")
    if not (grid == GOAL).any():
        raise LayoutError("layout has no goal cell 'G'")
    dist = geodesic_distance(grid)
    for r, c in starts:
        if not np.isfinite(dist[r, c]):
            goals = ", ".join(f"row {gr + 1}, column {gc + 1}" for gr, gc in np.argwhere(grid == GOAL)[:3])
            raise LayoutError(
                f"the goal ({goals}) cannot be reached from the start at row {r + 1}, column {c + 1} "
                "without crossing walls or pits"
            )
    return Layout(grid, starts.astype(np.int32), "\n".join(lines))


def _passable(grid: np.ndarray, r: int, c: int) -> bool:
    h, w = grid.shape
    return 0 <= r < h and 0 <= c < w and grid[r, c] != WALL


def neighbour_moves(grid: np.ndarray, r: int, c: int):
    """Cells one step from (r, c) that the dynamics can reach, with their centre distance.

    Diagonal moves count unless both orthogonal cells between are walls, the same rule the
    transition model uses (:func:`mindgap.envs.terrain.dynamics.landing_allowed`).
    """
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if (dr or dc) and _passable(grid, r + dr, c + dc):
                if dr and dc and not _passable(grid, r, c + dc) and not _passable(grid, r + dr, c):
                    continue
                yield r + dr, c + dc, float(np.hypot(dr, dc))


def geodesic_distance(grid: np.ndarray) -> np.ndarray:
    """[H, W] shortest distance from each cell centre to a goal cell, around walls and pits.

    Dijkstra on the 8-connected grid of passable cells (cost 1 per orthogonal step, √2
    per diagonal one); pits are not passed through; walls and unreachable cells get inf.
    """
    h, w = grid.shape
    dist = np.full((h, w), np.inf)
    heap = [(0.0, int(r), int(c)) for r, c in np.argwhere(grid == GOAL)]
    for _, r, c in heap:
        dist[r, c] = 0.0
    heapq.heapify(heap)
    while heap:
        d, r, c = heapq.heappop(heap)
        if d > dist[r, c]:
            continue
        for nr, nc, step in neighbour_moves(grid, r, c):
            if grid[nr, nc] in (PIT, GOAL):
                continue
            if d + step < dist[nr, nc]:
                dist[nr, nc] = d + step
                heapq.heappush(heap, (d + step, nr, nc))
    return dist
