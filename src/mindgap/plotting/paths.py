"""Paths through a world without a map: the first two coordinates of each trajectory, start and end marked."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .terrain import METHOD_COLOURS  # noqa: E402


def save_paths(path: str | Path, trajectories: Mapping[str, Sequence[np.ndarray]], title: str = "") -> Path:
    """Each trajectory ``[T+1, d]`` (d ≥ 1) as a line over its first two coordinates (against time when d = 1)."""
    path = Path(path)
    fig, ax = plt.subplots(figsize=(4.6, 4.0))
    for i, (label, paths) in enumerate(trajectories.items()):
        col = METHOD_COLOURS[i % len(METHOD_COLOURS)]
        for j, p in enumerate(paths):
            p = np.asarray(p, np.float64)
            xy = np.stack([np.arange(len(p)), p[:, 0]], -1) if p.shape[-1] == 1 else p[:, :2]
            ax.plot(xy[:, 0], xy[:, 1], color=col, alpha=0.7, lw=1.2, label=label if j == 0 else None)
            ax.plot(*xy[0], "o", color=col, ms=4)
            ax.plot(*xy[-1], "s", color=col, ms=4)
    dims = next((np.asarray(p).shape[-1] for ps in trajectories.values() for p in ps), 2)
    ax.set_xlabel("step" if dims == 1 else "observation 0")
    ax.set_ylabel("observation 0" if dims == 1 else "observation 1")
    if title:
        ax.set_title(title, fontsize=9)
    if trajectories:
        ax.legend(fontsize=7, frameon=False)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
