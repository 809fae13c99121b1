"""Pictures of terrain worlds are written in the format the file name asks for."""

import numpy as np
import pytest
from PIL import Image

from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.gym_env import terrain_image
from mindgap.plotting.terrain import save_fields, save_panels, save_rollout_gif, save_world


def test_map_colours_terrains_and_darkens_easier_sand():
    d3, d4 = load_world("d3"), load_world("d4")
    img3, img4 = terrain_image(d3.params), terrain_image(d4.params)
    r, c = 2, 1  # sand in both
    assert img4[r, c].sum() < img3[r, c].sum()
    assert not np.allclose(img3[1, 2], img3[2, 1])  # ice and sand differ


@pytest.mark.parametrize("ext", ["png", "svg"])
def test_world_with_trajectories(tmp_path, ext):
    w = load_world("nav1")
    paths = {"PrefBias": [np.array([[12.5, 3.5], [11.0, 2.0], [2.0, 2.0], [1.5, 3.5]])], "PEBBLE": [np.ones((3, 2))]}
    out = save_world(tmp_path / f"map.{ext}", w.params, paths, title="nav1")
    assert out.stat().st_size > 1000
    if ext == "svg":
        text = out.read_text()
        assert "<svg" in text and "PrefBias" in text and "PEBBLE" in text


def test_panels_fields_and_gif(tmp_path):
    w = load_world("d2")
    save_panels(tmp_path / "p.png", [("a", w.params, {}), ("b", w.belief(), {"x": [np.ones((2, 2)) * 2]})])
    field = np.random.default_rng(0).random((7 * 4, 7 * 4))
    save_fields(tmp_path / "f.png", w.params, [("truth", field), ("belief", field * 2)])
    path = np.stack([np.linspace(1.5, 5.5, 6), np.full(6, 1.5)], -1)
    gif = save_rollout_gif(tmp_path / "r.gif", w.params, path)
    with Image.open(gif) as im:
        assert im.format == "GIF" and getattr(im, "n_frames", 1) == 6
    assert not list(tmp_path.glob("*.part*"))
    # zoomed to the 5 × 2 cells around the path at 1.1 inches a cell: about 110 px a cell, not the whole map's 45
    zoom = save_rollout_gif(tmp_path / "z.gif", w.params, path, view=(1.0, 6.0, 0.5, 2.5), cell_inches=1.1)
    with Image.open(zoom) as im, Image.open(gif) as whole:
        assert im.n_frames == 6 and abs(im.size[0] - (5 * 1.1 + 0.4) * 100) <= 2
        assert im.size[0] / 5 > 2 * whole.size[0] / w.params.grid.shape[1]


def test_unknown_picture_format_is_an_error(tmp_path):
    with pytest.raises(ValueError, match=r"\.png or \.svg"):
        save_world(tmp_path / "map.jpg", load_world("d1").params)
