"""Reward and policy heatmaps of grid worlds (Fig. 4)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

_ARROWS = {0: (0, 1), 1: (0, -1), 2: (-1, 0), 3: (1, 0)}  # Up, Down, Left, Right in plot coordinates


def draw_grid(ax, values, size: int, title: str, policy=None, vmax=None):
    """One heatmap of ``values`` ``[S]``; optional ``policy`` ``[S, A]`` drawn as arrows."""
    grid = np.asarray(values).reshape(size, size)
    vmax = vmax or float(np.abs(grid).max()) or 1.0
    im = ax.imshow(grid, cmap="RdBu", vmin=-vmax, vmax=vmax)
    if policy is not None:
        best = np.asarray(policy).argmax(-1).reshape(size, size)
        for r in range(size):
            for c in range(size):
                dx, dy = _ARROWS[int(best[r, c])]
                ax.arrow(c - 0.25 * dx, r + 0.25 * dy, 0.4 * dx, -0.4 * dy, head_width=0.15, color="k")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    return im


def save_reward_panels(path: Path, panels: list[tuple[str, np.ndarray]], size: int, policies=None):
    """Save side-by-side reward heatmaps sharing one colour scale."""
    vmax = max(float(np.abs(v).max()) for _, v in panels) or 1.0
    fig, axes = plt.subplots(1, len(panels), figsize=(2.9 * len(panels), 2.9))
    axes = np.atleast_1d(axes)
    for i, (ax, (title, vals)) in enumerate(zip(axes, panels)):
        im = draw_grid(ax, vals, size, title, None if policies is None else policies[i], vmax)
    fig.colorbar(im, ax=axes.tolist(), shrink=0.8)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
