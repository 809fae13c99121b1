"""The picture cache: a file is reused only for the same picture."""

from study_helpers import study_file

from mindgap.study.config import load_study
from mindgap.study.render import Renderer


def test_a_cached_picture_is_reused_only_for_the_same_item_data(tmp_path):
    study = load_study(study_file(tmp_path, "grid7-rating"))
    renderer = Renderer(study, tmp_path / "media")
    item = {"id": "demo-00", "kind": "demo", "data": {"states": [0, 1, 2, 9], "size": 7}}
    other = {**item, "data": {"states": [0, 7, 14, 15], "size": 7}}
    first = renderer.path(item, "demo", "")
    assert renderer.path(item, "demo", "") == first  # drawn once, then reused
    second = renderer.path(other, "demo", "")
    assert second != first and second.read_bytes() != first.read_bytes()
    assert renderer.path(item, "demo", "humanoid") != first  # the condition is part of the picture too


def _white_on_wall(px):
    """White pixels inside the map that have a wall's dark grey within 3 px."""
    import numpy as np
    from scipy.ndimage import binary_dilation

    white = (px >= 250).all(-1)
    rows, cols = np.flatnonzero((~white).mean(1) > 0.5), np.flatnonzero((~white).mean(0) > 0.5)
    inside = np.zeros_like(white)
    inside[rows[0] + 2 : rows[-1] - 1, cols[0] + 2 : cols[-1] - 1] = True  # the map, not the title or margins
    wall = (np.abs(px - 77) <= 3).all(-1)
    return int((white & inside & binary_dilation(wall, iterations=3)).sum())


def test_a_terrain_behaviour_is_drawn_zoomed_to_the_part_of_the_map_it_covers(tmp_path):
    """Issue 49: a 10-step behaviour covered about 30 px of a 540-px picture of the whole map."""
    import numpy as np
    from PIL import Image

    from mindgap.study.render import TERRAIN_MARGIN, segment_positions, segment_view
    from mindgap.study.server import open_study

    study, store, renderer = open_study(study_file(tmp_path, "terrain-preference"), tmp_path / "t.sqlite")
    params = renderer.world.params
    h, w = np.asarray(params.grid).shape
    on_wall = 0
    for item in store.items()[:3]:
        for part in "ab":
            pos = segment_positions(params, item["data"][part])
            x0, x1, y0, y1 = segment_view(params, pos)
            lo, hi = pos.min(0), pos.max(0)
            # the segment with a margin around it (where the map goes on), and not the whole map
            assert x0 <= max(0.0, lo[0] - TERRAIN_MARGIN) and x1 >= min(w, hi[0] + TERRAIN_MARGIN)
            assert y0 <= max(0.0, lo[1] - TERRAIN_MARGIN) and y1 >= min(h, hi[1] + TERRAIN_MARGIN)
            assert (x1 - x0) * (y1 - y0) < 0.5 * w * h
            with Image.open(renderer.path(item, part, "")) as im:
                assert im.width / (x1 - x0) >= 90  # px a cell; the whole map was drawn at about 40
                px = np.asarray(im.convert("RGB"), int)
            on_wall += _white_on_wall(px)
    # the pushes into a wall: white arrows outlined in black (they were grey, and vanished on the walls)
    assert on_wall > 100


def test_a_view_is_kept_inside_the_map_and_at_least_three_cells_across():
    import numpy as np

    from mindgap.study.render import segment_view

    params = type("P", (), {"grid": np.zeros((6, 14))})()
    assert segment_view(params, np.array([[0.2, 0.3], [0.4, 0.5]])) == (0.0, 3.0, 0.0, 3.0)
    assert segment_view(params, np.array([[5.0, 2.0], [9.0, 2.5]])) == (4.0, 10.0, 0.75, 3.75)
    assert segment_view(params, np.array([[0.5, 0.5], [13.5, 5.5]])) == (0.0, 14.0, 0.0, 6.0)


def test_an_animated_terrain_behaviour_is_zoomed_as_the_still_one(tmp_path):
    """``animation: true`` draws each behaviour as a GIF of the same window as its still picture."""
    import yaml
    from PIL import Image

    from mindgap.study.render import TERRAIN_CELL_INCHES, segment_positions, segment_view
    from mindgap.study.server import open_study

    path = study_file(tmp_path, "terrain-preference")
    raw = yaml.safe_load(path.read_text())
    raw["items"] = {**raw["items"], "animation": True}
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    study, store, renderer = open_study(path, tmp_path / "t.sqlite")
    item = store.items()[0]
    pos = segment_positions(renderer.world.params, item["data"]["a"])
    x0, x1, _, _ = segment_view(renderer.world.params, pos)
    with Image.open(renderer.path(item, "a", "")) as im:
        assert im.format == "GIF" and im.n_frames > 1
        assert abs(im.width - 100 * (TERRAIN_CELL_INCHES * (x1 - x0) + 0.4)) <= 2  # the window, ~110 px a cell
