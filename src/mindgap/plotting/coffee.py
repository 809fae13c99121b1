"""Figures of the coffee-robot study: demonstration strips (Fig. 11) and learned values (Fig. 12)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib import patches

from ..envs.coffee import ACTIONS, GO, IN_CAFE, ROBOT_COFFEE, ROBOTS, VARIABLES, WET, bits

_BLUE, _BROWN, _GREY = "#3a78c2", "#7a4a21", "#555555"


def _robot(ax, x: float, robot: str, wet: bool) -> None:
    colour = "#8fb3d9" if wet else "#d0d0d0"
    if robot == "humanoid":
        ax.add_patch(patches.Circle((x, 0.62), 0.07, fc=colour, ec="k", lw=0.8))
        ax.add_patch(patches.Rectangle((x - 0.07, 0.36), 0.14, 0.19, fc=colour, ec="k", lw=0.8))
        ax.plot([x - 0.04, x - 0.05, np.nan, x + 0.04, x + 0.05], [0.36, 0.22, np.nan, 0.36, 0.22], color="k", lw=1.5)
    else:
        ax.add_patch(patches.Rectangle((x - 0.11, 0.3), 0.22, 0.2, fc=colour, ec="k", lw=0.8))
        ax.scatter([x - 0.07, x + 0.07], [0.27, 0.27], s=14, color="k")
    if wet:
        ax.scatter([x - 0.12, x + 0.12, x], [0.55, 0.5, 0.72], marker="v", s=12, color=_BLUE)


def _cup(ax, x: float, y: float) -> None:
    ax.add_patch(patches.Rectangle((x - 0.025, y), 0.05, 0.06, fc=_BROWN, ec="k", lw=0.5))


def draw_state(ax, state: int, robot: str, caption: str = "", x0: float = 0.0) -> None:
    """One picture of a coffee-world state in the unit square at ``(x0, 0)`` of ``ax``.

    Office on the left, café on the right, sun or rain, the robot (``mobile`` or
    ``humanoid``; bluish and dripping when wet) with what it holds, and the user's cup
    once delivered; ``caption`` above it.
    """
    b = dict(zip(VARIABLES, bits(state).tolist()))
    ax.add_patch(patches.Rectangle((x0, 0), 1, 1, fill=False, ec=_GREY, lw=0.6))
    for x, name in ((0.2, "office"), (0.8, "café")):
        ax.add_patch(patches.Rectangle((x0 + x - 0.17, 0.12), 0.34, 0.1, fc="#eeeeee", ec=_GREY, lw=0.6))
        ax.text(x0 + x, 0.03, name, ha="center", fontsize=7)
    if b["raining"]:
        xs = x0 + np.linspace(0.05, 0.95, 10)
        ax.scatter(xs, 0.92 - 0.04 * (np.arange(10) % 2), marker="|", s=30, color=_BLUE)
    else:
        ax.add_patch(patches.Circle((x0 + 0.9, 0.88), 0.06, fc="#f5c518", ec="none"))
    x = x0 + (0.8 if b["in_cafe"] else 0.2)
    _robot(ax, x, robot, bool(b["wet"]))
    if b["umbrella"]:
        ax.add_patch(patches.Wedge((x + 0.08, 0.8), 0.1, 0, 180, fc="#c23a3a", ec="k", lw=0.5))
        ax.plot([x + 0.08, x + 0.08], [0.8, 0.5], color="k", lw=0.8)
    if b["robot_coffee"]:
        _cup(ax, x - 0.16, 0.42)
    if b["user_coffee"]:
        _cup(ax, x0 + 0.08, 0.23)
        ax.text(x0 + 0.08, 0.31, "you", fontsize=6, ha="center")
    if caption:
        ax.text(x0 + 0.5, 1.04, caption, ha="center", va="bottom", fontsize=7)


def step_events(states, actions) -> list[str]:
    """What went wrong on each step of a coffee demonstration: ``spilled!``, ``got wet`` or ``""``
    (the first state's is ``""``); Fig. 11's captions add it to the action taken."""
    events = [""]
    for k in range(1, len(states)):
        event = ""
        if actions[k - 1] == GO:
            before, after = bits(int(states[k - 1])), bits(int(states[k]))
            if before[ROBOT_COFFEE] and not after[ROBOT_COFFEE]:
                event = "spilled!"
            elif after[WET]:
                event = "got wet"
        events.append(event)
    return events


def save_demo_strip(path: Path, states, actions, robot: str, title: str = "") -> None:
    """A demonstration as a strip of pictures, one per state, captioned with the action taken (Fig. 11)."""
    n = len(states)
    gap = 0.1
    fig = plt.figure(figsize=(1.35 * n, 1.8))
    ax = fig.add_axes((0.01, 0.02, 0.98, 0.7))  # one axes for all panels: far cheaper than n subplots
    ax.set_xlim(-0.02, n * (1 + gap) - gap + 0.02)
    ax.set_ylim(0, 1)
    ax.set_axis_off()
    for k, (s, event) in enumerate(zip(states, step_events(states, actions))):
        x0 = k * (1 + gap)
        caption = "start" if k == 0 else f"{k}. {ACTIONS[actions[k - 1]]}"
        if event:
            caption += "\n" + event
        if event == "spilled!":
            ax.add_patch(patches.Ellipse((x0 + (0.8 if bits(int(s))[IN_CAFE] else 0.2), 0.25), 0.2, 0.04, fc=_BROWN))
        draw_state(ax, int(s), robot, caption, x0)
    fig.suptitle(title + "   —   rate it from 0 (lowest) to 10 (highest)", fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def save_learned_values(
    path: Path, groups: dict[str, dict[str, list[dict]]], truth: dict[str, dict[str, list]]
) -> None:
    """Fig. 12: learned coffee weight, wetness penalty, their ratio and spill probability per method and robot.

    Args:
        groups: ``{method label: {robot: [row, ...]}}`` with keys ``coffee_weight_learned``,
            ``wet_weight_learned``, ``spill_learned``.
        truth: ``{robot: {"coffee": [...], "wet": [...], "ratio": [...], "spill": [...]}}`` the
            participants' true values (drawn as the first group).
    """
    panels = (
        ("coffee", "coffee_weight_learned", 1.0, "weight of 'user has coffee'"),
        ("wet", "wet_weight_learned", -1.0, "wetness penalty (−weight of 'robot wet')"),
        ("ratio", "wet_per_coffee", 1.0, "wetness penalty / coffee weight"),
        ("spill", "spill_learned", 1.0, "believed spill probability"),
    )
    present = {r for g in groups.values() for r in g}
    robots = [r for r in ROBOTS if r in present]
    labels = ["truth"] + list(groups)
    colours = {"mobile": "#4c72b0", "humanoid": "#dd8452"}
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4))
    width = 0.8 / max(len(robots), 1)
    for ax, (tkey, rkey, sign, ylabel) in zip(axes, panels):
        for i, label in enumerate(labels):
            for j, robot in enumerate(robots):
                if label == "truth":
                    vals = truth.get(robot, {}).get(tkey, [])
                elif rkey == "wet_per_coffee":
                    vals = [-r["wet_weight_learned"] / r["coffee_weight_learned"] for r in groups[label][robot]]
                else:
                    vals = [r[rkey] for r in groups[label][robot]]
                vals = sign * np.asarray([v for v in vals if np.isfinite(v)], float)
                if not len(vals):
                    continue
                x = i + (j - (len(robots) - 1) / 2) * width
                ax.bar(
                    x, vals.mean(), width * 0.9, color=colours.get(robot), alpha=0.5, label=robot if i == 0 else None
                )
                ax.errorbar(x, vals.mean(), vals.std(), color="k", capsize=2, lw=0.8)
                ax.scatter(np.full(len(vals), x), vals, s=6, color="k", zorder=3)
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, fontsize=8, rotation=15)
        ax.set_ylabel(ylabel, fontsize=8)
    axes[0].legend(fontsize=8)
    fig.suptitle("Coffee robot: what each participant cares about and believes (truth vs learned)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def save_ratings_by_demo(path: Path, names, means: dict[str, np.ndarray], stds: dict[str, np.ndarray]) -> None:
    """Mean raw rating of each demonstration per robot type (valid participants)."""
    fig, ax = plt.subplots(figsize=(9, 3.2))
    robots = list(means)
    width = 0.8 / max(len(robots), 1)
    for j, robot in enumerate(robots):
        x = np.arange(len(names)) + (j - (len(robots) - 1) / 2) * width
        ax.bar(x, means[robot], width * 0.9, yerr=stds[robot], capsize=2, label=robot, alpha=0.7)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("rating (0–10)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
