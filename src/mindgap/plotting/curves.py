"""Metric-against-progress line plots (Figs. 5–7 and the demonstration-count figure)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np


def save_metric_curves(
    path: Path,
    curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]],
    metrics: tuple[str, ...],
    xlabel: str,
    prior: dict[str, float] | None = None,
    logx: bool = False,
    title: str = "",
):
    """One panel per metric; per method a mean line with a ±std band.

    Args:
        curves: ``{method: {metric: (x, mean, std)}}``.
        prior: ``{metric: value}`` drawn as a dashed line (the prior's metric).
    """
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 3.2))
    axes = np.atleast_1d(axes)
    for ax, metric in zip(axes, metrics):
        for method, per_metric in curves.items():
            x, m, s = per_metric[metric]
            (line,) = ax.plot(x, m, marker="o" if len(x) < 8 else None, label=method)
            ax.fill_between(x, m - s, m + s, color=line.get_color(), alpha=0.15)
        if prior and metric in prior:
            ax.axhline(prior[metric], color="grey", ls="--", label="prior")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(metric)
        if logx:
            ax.set_xscale("log")
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
