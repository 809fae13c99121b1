"""Pictures of study items, drawn by mindgap's own plotting and cached on disk.

* coffee demonstrations: Fig. 11's strip as one picture per step (the states drawn by
  :func:`mindgap.plotting.coffee.draw_state`, in the participant's robot condition), with
  the captions ("1. GetUmbrella", "spilled!") as text on the page, so that they stay
  readable on a phone, where the steps wrap into rows;
* grid7 demonstrations: the grid with the demonstrated path (drawn here: the grid
  heatmaps of :mod:`mindgap.plotting.heatmaps` show values, not paths);
* terrain segments: the map of :mod:`mindgap.plotting.terrain`, zoomed to the part the
  segment covers, with its path and, as white arrows outlined in black, what the agent pushed
  for at each step (so an expectation question can be judged), or an animated GIF
  (``animation: true`` in ``items``);
* gymnasium segments (``domain: {name: gym, env: gym:ID}``): always an animated GIF, the env
  drawing itself in each state of the segment
  (:func:`mindgap.plotting.animation.observation_frames`: MuJoCo envs whose observations
  hold their whole state);
* driving segments and rollouts (``domain: {name: driving}``, §4.4.2): always an animated GIF
  drawn by highway-env, every integration step of every decision
  (:func:`mindgap.envs.driving.highway.segment_frames`, which states how the scene is set from
  the segment's observations), cropped to the road with brake lights and sleet drawn on
  (:func:`mindgap.study.driving.frames`); both clips of a pair last as long.

Matplotlib is not thread-safe, so drawing holds one lock; each picture is drawn once
and written through a rename, then served from the cache folder. A cached file is named
by a hash of everything that decides the picture (the domain, the item's data, the part,
the condition and the format), so a store started again under an old name with other
items never shows the old pictures.
"""

from __future__ import annotations

import hashlib
import json
import re
import threading
from pathlib import Path

import numpy as np

_LOCK = threading.Lock()
PART_COLOURS = {"a": "#d62728", "b": "#1f77b4"}


# Bumped when a drawing changes, so that pictures cached by an older mindgap are drawn again.
DRAWING_VERSION = 3
_STEP = re.compile(r"step-([0-9]{1,4})")


class Renderer:
    """Draws items of one study into ``cache`` (``<cache>/<condition>/<item>-<part>-<key>.<ext>``)."""

    def __init__(self, study, cache: Path):
        self.study = study
        self.cache = Path(cache)
        self._world = None
        self._world_digest: str | None = None

    @property
    def world(self):
        if self._world is None:
            from .items import load_study_world

            self._world = load_study_world(self.study)
        return self._world

    def _world_file(self) -> str:
        """A hash of a terrain world given as a file (its content, not only its name, decides the map)."""
        if self._world_digest is None:
            self._world_digest = ""
            name = self.study.domain.get("world")
            if isinstance(name, str):
                path = Path(name) if Path(name).is_absolute() else Path(self.study.base_dir) / name
                if path.is_file():
                    self._world_digest = hashlib.sha256(path.read_bytes()).hexdigest()
        return self._world_digest

    def ext(self) -> str:
        return "gif" if self.study.items.get("animation") or self.study.domain["name"] in ("gym", "driving") else "png"

    def parts(self, item: dict) -> tuple[tuple[str, str], ...]:
        """An item's pictures as ``(part, caption)``: a coffee demonstration's steps
        (``step-0``, ``step-1``, ...), a grid demonstration's one picture (``demo``), or a
        comparison's two behaviours (``a``, ``b``)."""
        if item["kind"] != "demo":
            return (("a", "A"), ("b", "B"))
        if self.study.domain["name"] == "coffee":
            d = item["data"]
            return tuple((f"step-{k}", c) for k, c in enumerate(step_captions(d["states"], d["actions"])))
        return (("demo", ""),)

    def key(self, item: dict, part: str, condition: str, ext: str) -> str:
        """A hash of what decides the picture: the domain, the item's data, the part, the condition, the format."""
        what = [DRAWING_VERSION, self.study.domain, self._world_file(), item["data"], part, condition, ext]
        return hashlib.sha256(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()[:16]

    def path(self, item: dict, part: str, condition: str) -> Path:
        """The picture of ``part`` (one of :meth:`parts`) of ``item``, drawn on first use."""
        ext = self.ext() if item["kind"] != "demo" or self.study.domain["name"] == "driving" else "png"
        key = self.key(item, part, condition, ext)
        out = self.cache / (condition or "all") / f"{item['id']}-{part}-{key}.{ext}"
        if out.exists():
            return out
        with _LOCK:
            if not out.exists():
                out.parent.mkdir(parents=True, exist_ok=True)
                self._draw(item, part, condition, out)
        return out

    def _draw(self, item: dict, part: str, condition: str, out: Path) -> None:
        domain = self.study.domain["name"]
        tmp = out.with_name(out.stem + ".part" + out.suffix)
        d = item["data"]
        if domain == "coffee":
            k = int(_STEP.fullmatch(part).group(1))
            spilled = k > 0 and step_captions(d["states"][k - 1 : k + 1], d["actions"][k - 1 : k])[1].endswith(
                "spilled!"
            )
            save_coffee_step(tmp, d["states"][k], condition or "mobile", spilled)
        elif domain == "grid7":
            save_grid_demo(tmp, d["states"], d["size"])
        elif domain == "driving":  # highway-env's animation of the segment (or the rated rollout)
            from ..plotting.animation import save_gif
            from .driving import clip_length, frames

            if part == "demo":
                clip = frames(self.study, d["segment"])
            else:  # both clips of a pair as long as the longer one, plus a pause, so that they loop in step
                clip = frames(self.study, d[part], max(clip_length(d["a"]), clip_length(d["b"])) + DRIVING_PAUSE)
            save_gif(tmp, clip, fps=DRIVING_FPS, scale=1.0)
        elif domain == "gym":
            from ..plotting.animation import observation_frames, save_gif

            save_gif(tmp, observation_frames(self.world, gym_segment_states(d[part])), fps=GYM_FPS)
        else:
            seg = d[part]
            if out.suffix == ".gif":
                from ..plotting.terrain import save_rollout_gif

                pos = segment_positions(self.world.params, seg)  # zoomed as the still pictures are
                save_rollout_gif(tmp, self.world.params, pos, fps=4, view=segment_view(self.world.params, pos),
                                 cell_inches=TERRAIN_CELL_INCHES)  # fmt: skip
            else:
                # both behaviours of a pair in one window when they are close (an expectation
                # question's two outcomes from one start), so that they compare at a glance
                both = np.concatenate([segment_positions(self.world.params, d[k]) for k in ("a", "b")])
                view = segment_view(self.world.params, both) if np.ptp(both, 0).max() <= SHARED_VIEW else None
                save_segment(tmp, self.world.params, seg, PART_COLOURS[part], part.upper(), view)
        tmp.replace(out)


DRIVING_FPS = 15.0
"""Frames a second of a driving animation: highway-env's 15 integration steps a decision, in real time."""
DRIVING_PAUSE = 10
"""Frames (2/3 s) a pair's driving clips hold their last frame before they loop."""
GYM_FPS = 10.0
"""Frames a second of a gymnasium segment's animation (slower than the envs' own 25–125 Hz, so a
ten-step segment lasts about a second)."""


def gym_segment_states(seg: dict) -> np.ndarray:
    """The observations a segment passes through: its first, then each real step's next one ([n + 1, d])."""
    obs, nxt, mask = (np.asarray(seg[k]) for k in ("obs", "next_obs", "mask"))
    n = int(np.asarray(mask, bool).sum())
    return np.concatenate([obs[:1], nxt[:n]]) if n else obs[:1]


def step_captions(states, actions) -> list[str]:
    """The caption of each step of a coffee demonstration: ``start``, then the action taken
    and what went wrong on the way (the captions of Fig. 11's strip)."""
    from ..envs.coffee import ACTIONS
    from ..plotting.coffee import step_events

    events = step_events(states, actions)
    return ["start"] + [
        f"{k}. {ACTIONS[actions[k - 1]]}" + (f", {events[k]}" if events[k] else "") for k in range(1, len(states))
    ]


def save_coffee_step(path: Path, state: int, robot: str, spilled: bool = False) -> None:
    """One step of a coffee demonstration (its caption is on the page), a spill as a puddle."""
    import matplotlib.pyplot as plt
    from matplotlib import patches

    from ..envs.coffee import IN_CAFE, bits
    from ..plotting.coffee import draw_state

    fig = plt.figure(figsize=(1.1, 1.1))
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(-0.01, 1.01)
    ax.set_ylim(-0.01, 1.01)
    ax.set_axis_off()
    draw_state(ax, int(state), robot)
    if spilled:
        x = 0.8 if bits(int(state))[IN_CAFE] else 0.2
        ax.add_patch(patches.Ellipse((x, 0.25), 0.2, 0.04, fc="#7a4a21"))
    fig.savefig(path, dpi=220, format="png")
    plt.close(fig)


def segment_positions(params, seg: dict) -> np.ndarray:
    """Positions [n + 1, 2] (cells) visited by a segment: its start, then each real step's arrival."""
    from .items import world_pos

    mask = np.asarray(seg["mask"], bool)
    obs, nxt = np.asarray(seg["obs"]), np.asarray(seg["next_obs"])
    return world_pos(params, np.concatenate([obs[:1], nxt[mask]]))


TERRAIN_MARGIN = 1.0
"""Cells of map shown around a terrain segment's positions (:func:`segment_view`)."""
SHARED_VIEW = 3.0
"""Cells: a pair's behaviours are drawn in one window when their positions span at most this."""
TERRAIN_CELL_INCHES = 1.1
"""The size of a map cell in a zoomed terrain picture (110 px at its 100 dpi)."""


def segment_view(params, pos: np.ndarray, margin: float = TERRAIN_MARGIN, min_cells: float = 3.0):
    """The part of the map that positions ``pos`` [n, 2] cover: ``(x0, x1, y0, y1)`` in cells, their
    bounding box with ``margin`` cells around it, at least ``min_cells`` wide and high, within the map."""
    h, w = np.asarray(params.grid).shape
    lo, hi = np.asarray(pos, float).min(0) - margin, np.asarray(pos, float).max(0) + margin
    grow = np.maximum(min_cells - (hi - lo), 0.0) / 2
    lo, hi = lo - grow, hi + grow
    size = np.array([w, h], float)
    shift = np.maximum(0.0, -lo) - np.maximum(0.0, hi - size)  # slide back inside the map before clipping
    lo, hi = np.clip(lo + shift, 0.0, size), np.clip(hi + shift, 0.0, size)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def save_segment(path: Path, params, seg: dict, colour: str, label: str, view=None) -> None:
    """One terrain segment, zoomed to ``view`` (default: the part of the map it covers,
    :func:`segment_view`): path, start ring, end dot, and the pushes as white arrows outlined in
    black (seen on the dark walls too)."""
    import matplotlib.pyplot as plt
    from matplotlib import patheffects

    from ..plotting.terrain import draw_world

    pos = segment_positions(params, seg)
    act = np.asarray(seg["act"])[np.asarray(seg["mask"], bool)]
    x0, x1, y0, y1 = view or segment_view(params, pos)
    c = TERRAIN_CELL_INCHES
    fig, ax = plt.subplots(figsize=(c * (x1 - x0) + 0.2, c * (y1 - y0) + 0.45))
    draw_world(ax, params, starts=False)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y1, y0)
    outline = [patheffects.withStroke(linewidth=3.5, foreground="white")]
    ax.plot(pos[:, 0], pos[:, 1], "-", color=colour, lw=3, path_effects=outline, zorder=4)
    ax.quiver(
        pos[:-1, 0],
        pos[:-1, 1],
        act[:, 0],
        act[:, 1],
        color="white",
        edgecolor="black",
        linewidth=1.0,
        angles="xy",
        scale_units="xy",
        scale=3.0,
        width=0.014,
        headwidth=3.5,
        headlength=4,
        headaxislength=3.5,
        zorder=3,
    )
    ax.plot(pos[0, 0], pos[0, 1], "o", mfc="white", mec=colour, ms=14, mew=3, zorder=5)
    ax.plot(pos[-1, 0], pos[-1, 1], "o", color=colour, mec="white", ms=11, mew=1.5, zorder=5)
    ax.set_title(f"behaviour {label}", fontsize=12)
    fig.tight_layout(pad=0.3)
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)


def save_grid_demo(path: Path, states, size: int) -> None:
    """A grid7 demonstration: the grid, the path through the cell centres, start ring and end dot."""
    import matplotlib.pyplot as plt

    rows, cols = np.divmod(np.asarray(states), size)
    fig, ax = plt.subplots(figsize=(3.2, 3.2))
    ax.set_xlim(-0.5, size - 0.5)
    ax.set_ylim(size - 0.5, -0.5)
    ax.set_xticks(np.arange(-0.5, size), minor=True)
    ax.set_yticks(np.arange(-0.5, size), minor=True)
    ax.grid(which="minor", color="#bbbbbb")
    ax.tick_params(which="both", length=0, labelbottom=False, labelleft=False)
    ax.plot(cols, rows, "-", color="#d62728", lw=2, alpha=0.8)
    ax.plot(cols[0], rows[0], "o", mfc="none", mec="#d62728", ms=12, mew=2)
    ax.plot(cols[-1], rows[-1], "o", color="#d62728", ms=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)
