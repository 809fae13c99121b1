"""Learning curves of RL runs: return under the true reward against environment steps (Figs. 16–20)."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .terrain import METHOD_COLOURS  # noqa: E402


def curve_stats(rows) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(steps, mean return, std over seeds, mean queries) from rows (seed, step, return, queries)."""
    a = np.asarray(rows, np.float64).reshape(-1, 4)
    steps = np.unique(a[:, 1])
    mean = np.array([a[a[:, 1] == s, 2].mean() for s in steps])
    std = np.array([a[a[:, 1] == s, 2].std() for s in steps])
    queries = np.array([a[a[:, 1] == s, 3].mean() for s in steps])
    return steps, mean, std, queries


def save_learning_curves(
    path: str | Path, runs: Mapping[str, list], title: str = "", reference: float | None = None, note: str = ""
) -> Path:
    """Mean ± std over seeds of each run's return; ``reference`` (e.g. the planning check's) dashed;
    ``note`` a caption under the axes (what the figure is read beside)."""
    path = Path(path)
    caption = textwrap.fill(note, 95) if note else ""
    lines = caption.count("\n") + 1 if caption else 0
    fig, ax = plt.subplots(figsize=(5.2, 3.4 + 0.11 * lines))  # a 6-point line of caption: about 0.1 inch
    for i, (label, rows) in enumerate(runs.items()):
        steps, mean, std, _ = curve_stats(rows)
        col = METHOD_COLOURS[i % len(METHOD_COLOURS)]
        ax.plot(steps, mean, color=col, label=label)
        ax.fill_between(steps, mean - std, mean + std, color=col, alpha=0.2)
    if reference is not None:
        ax.axhline(reference, color="#555555", ls="--", lw=1, label="planning reference")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("return (true reward)")
    if title:
        ax.set_title(textwrap.fill(title, 70), fontsize=9)  # a long title on two lines, not cut at the edges
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    if caption:
        fig.text(0.02, 0.01, caption, fontsize=6, va="bottom", ha="left")
    fig.tight_layout(rect=(0, (0.11 * lines + 0.04 * bool(lines)) / (3.4 + 0.11 * lines), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part" + path.suffix)
    fig.savefig(tmp, dpi=150)
    plt.close(fig)
    tmp.replace(path)
    return path
