"""Pictures of terrain worlds: the map, trajectories on it (Figs. 21, 27), noise fields, GIFs.

The format follows the file name: ``.png`` or ``.svg`` for still pictures, ``.gif`` for
an animation.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..envs.terrain.gym_env import terrain_image  # noqa: E402
from ..envs.terrain.layout import WALL  # noqa: E402

METHOD_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


def draw_world(ax, params, starts: bool = True) -> None:
    """Draw the map of ``params`` on ``ax`` in cell coordinates (y downwards)."""
    h, w = np.asarray(params.grid).shape
    ax.imshow(terrain_image(params), extent=(0, w, h, 0), interpolation="nearest")
    if starts:
        for r, c in np.asarray(params.starts):
            ax.add_patch(plt.Rectangle((c + 0.1, r + 0.1), 0.8, 0.8, fill=False, ec="#333333", lw=1.2, ls="--"))
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_aspect("equal")


def draw_trajectories(ax, trajectories: Mapping[str, Sequence[np.ndarray]], colours=None, alpha: float = 0.6):
    """Draw ``{label: [positions [T, 2], …]}``, one colour per label, with a legend."""
    colours = dict(colours or {})
    for i, (label, paths) in enumerate(trajectories.items()):
        col = colours.get(label, METHOD_COLOURS[i % len(METHOD_COLOURS)])
        for j, path in enumerate(paths):
            p = np.asarray(path)
            ax.plot(p[:, 0], p[:, 1], "-", color=col, lw=1.4, alpha=alpha, label=label if j == 0 else None)
            ax.plot(p[-1, 0], p[-1, 1], "o", color=col, ms=3, alpha=alpha)
    if trajectories:
        ax.legend(loc="lower left", fontsize=7, framealpha=0.85)


def save_world(
    path: str | Path,
    params,
    trajectories: Mapping[str, Sequence[np.ndarray]] | None = None,
    title: str | None = None,
    colours=None,
) -> Path:
    """Save the map with trajectories drawn on it (PNG or SVG by extension)."""
    path = Path(path)
    h, w = np.asarray(params.grid).shape
    fig, ax = plt.subplots(figsize=(0.45 * w + 1, 0.45 * h + 0.6))
    draw_world(ax, params)
    draw_trajectories(ax, trajectories or {}, colours)
    if title:
        ax.set_title(title, fontsize=9)
    _save(fig, path)
    return path


def save_panels(
    path: str | Path, panels: Sequence[tuple[str, object, Mapping]], colours=None, ncols: int | None = None
) -> Path:
    """Several maps side by side: ``[(title, params, {label: paths}), …]``, ``ncols`` to a row (default: one row).

    ``params`` of a world without a map (no ``grid``: a user's world) gives plain axes, the
    paths drawn in the first two coordinates of what the world traces.
    """
    path = Path(path)
    mapped = hasattr(panels[0][1], "grid")
    h, w = np.asarray(panels[0][1].grid).shape if mapped else (8, 8)
    ncols = min(ncols or len(panels), len(panels))
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(ncols * (0.45 * w + 0.6), nrows * (0.45 * h + 0.8)), squeeze=False)
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    for ax, (title, params, trajs) in zip(axes.ravel(), panels):
        if mapped:
            draw_world(ax, params)
        else:
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
        draw_trajectories(ax, trajs, colours)
        ax.set_title(title, fontsize=9)
    _save(fig, path)
    return path


def save_fields(
    path: str | Path,
    params,
    fields: Sequence[tuple[str, np.ndarray]],
    label: str = "noise σ",
    vmin: float | None = 0.0,
    cmap: str = "magma_r",
) -> Path:
    """Heatmaps of per-position quantities (e.g. the noise scale under the truth and a belief).

    Args:
        fields: ``[(title, values [h·k, w·k]), …]`` sampled on a k×k grid per cell; walls masked.
        vmin: bottom of the shared colour scale (None: the smallest value shown).
    """
    path = Path(path)
    grid = np.asarray(params.grid)
    h, w = grid.shape
    vmax = max(float(np.nanmax(f)) for _, f in fields)
    if vmin is None:
        vmin = min(float(np.nanmin(f)) for _, f in fields)
    fig, axes = plt.subplots(1, len(fields), figsize=(len(fields) * (0.45 * w + 1.2), 0.45 * h + 0.8), squeeze=False)
    for ax, (title, f) in zip(axes[0], fields):
        draw_world(ax, params)
        k = f.shape[0] // h
        wall = np.repeat(np.repeat(grid == WALL, k, 0), k, 1)
        im = ax.imshow(np.ma.masked_where(wall, f), extent=(0, w, h, 0), cmap=cmap, vmin=vmin, vmax=vmax, alpha=0.75)
        ax.set_title(title, fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label=label)
    _save(fig, path)
    return path


def save_rollout_gif(
    path: str | Path, params, positions: np.ndarray, fps: int = 8, title: str | None = None, view=None,
    cell_inches: float = 0.45,
) -> Path:  # fmt: skip
    """Animate one rollout ``positions [T, 2]`` as a GIF (the trail grows, a dot marks the agent).

    ``view``: ``(x0, x1, y0, y1)`` in cells, the part of the map shown (default all of it), drawn at
    ``cell_inches`` a cell.
    """
    from matplotlib.animation import FuncAnimation, PillowWriter

    path = Path(path)
    p = np.asarray(positions)
    h, w = np.asarray(params.grid).shape
    x0, x1, y0, y1 = view or (0.0, float(w), 0.0, float(h))
    fig, ax = plt.subplots(figsize=(cell_inches * (x1 - x0) + 0.4, cell_inches * (y1 - y0) + 0.5))
    draw_world(ax, params)
    if view is not None:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y1, y0)
    if title:
        ax.set_title(title, fontsize=9)
    (trail,) = ax.plot([], [], "-", color=METHOD_COLOURS[0], lw=1.5)
    (dot,) = ax.plot([], [], "o", color=METHOD_COLOURS[0], ms=7)

    def frame(i):
        trail.set_data(p[: i + 1, 0], p[: i + 1, 1])
        dot.set_data(p[i : i + 1, 0], p[i : i + 1, 1])
        return trail, dot

    anim = FuncAnimation(fig, frame, frames=len(p), blit=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part.gif")
    anim.save(tmp, writer=PillowWriter(fps=fps))
    plt.close(fig)
    tmp.replace(path)
    return path


def _save(fig, path: Path) -> None:
    """Write through a temporary file so an interrupted save leaves nothing half-written."""
    if path.suffix.lower() not in (".png", ".svg"):
        plt.close(fig)
        raise ValueError(f"{path}: pictures are written as .png or .svg")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".part" + path.suffix)
    fig.savefig(tmp, dpi=150)
    plt.close(fig)
    tmp.replace(path)
