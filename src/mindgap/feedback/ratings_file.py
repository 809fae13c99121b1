"""Ratings files: the CSV format every rating-based learner reads.

One row per demonstrated step, long format::

    demo,step,state,action,rating
    0,0,12,3,6.5
    0,1,13,0,6.5
    1,0,40,2,1.0

- ``demo``: any label identifying the demonstration (rows of one demonstration need
  not be adjacent);
- ``step``: position within the demonstration (integers, unique per demonstration;
  rows are ordered by it);
- ``state``, ``action``: integer ids of the domain (grid: ``row * size + col``;
  actions 0 Up, 1 Down, 2 Left, 3 Right);
- ``rating``: the person's rating of the whole demonstration, in ``[0, γ_max]``,
  repeated on each of its rows.

Extra columns (e.g. ``participant``) are kept by :func:`read_ratings` and ignored by
the learners.
"""

from __future__ import annotations

import csv
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._io import atomic_write
from ._errors import RatingsFileError
from .demos import RatedDemonstrations, make_demonstrations

REQUIRED = ("demo", "step", "state", "action", "rating")


def read_ratings(path, *, n_states: int, n_actions: int, gamma_max: float = 10.0) -> RatedDemonstrations:
    """Read and validate a ratings file.

    Raises:
        RatingsFileError: a missing file or column, a non-numeric value, a rating out
            of range or differing within a demonstration, a repeated step, or an
            unknown state or action id — the message names the line.
    """
    path = Path(path)
    if not path.is_file():
        raise RatingsFileError(f"ratings file {path} does not exist")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            raise RatingsFileError(f"{path}: missing column(s) {', '.join(missing)}; need {', '.join(REQUIRED)}")
        demos: dict[str, dict] = {}
        for line, raw in enumerate(reader, start=2):
            row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
            try:
                step, state, action = int(row["step"]), int(row["state"]), int(row["action"])
                rating = float(row["rating"])
            except ValueError:
                raise RatingsFileError(
                    f"{path}, line {line}: step, state and action must be integers and rating a number"
                ) from None
            if not np.isfinite(rating) or not 0.0 <= rating <= gamma_max:
                raise RatingsFileError(f"{path}, line {line}: rating {rating} is outside [0, {gamma_max}]")
            if not 0 <= state < n_states:
                raise RatingsFileError(f"{path}, line {line}: unknown state id {state} (valid: 0..{n_states - 1})")
            if not 0 <= action < n_actions:
                raise RatingsFileError(f"{path}, line {line}: unknown action id {action} (valid: 0..{n_actions - 1})")
            d = demos.setdefault(row["demo"], {"rating": rating, "steps": {}, "line": line})
            if d["rating"] != rating:
                raise RatingsFileError(
                    f"{path}, line {line}: demonstration {row['demo']!r} has two ratings ({d['rating']} and {rating})"
                )
            if step in d["steps"]:
                raise RatingsFileError(f"{path}, line {line}: demonstration {row['demo']!r} repeats step {step}")
            d["steps"][step] = (state, action)
    if not demos:
        raise RatingsFileError(f"{path}: no rows")
    length = max(len(d["steps"]) for d in demos.values())
    n = len(demos)
    states = np.zeros((n, length), np.int32)
    actions = np.zeros((n, length), np.int32)
    mask = np.zeros((n, length), bool)
    ratings = np.zeros(n, np.float32)
    for i, d in enumerate(demos.values()):
        steps = [d["steps"][k] for k in sorted(d["steps"])]
        states[i, : len(steps)] = [s for s, _ in steps]
        actions[i, : len(steps)] = [a for _, a in steps]
        mask[i, : len(steps)] = True
        ratings[i] = d["rating"]
    demo_batch = make_demonstrations(states, actions, mask, n_states=n_states, n_actions=n_actions)
    return RatedDemonstrations(demo_batch, jnp.asarray(ratings))


def write_ratings(path, rated: RatedDemonstrations) -> None:
    """Write rated demonstrations in the format :func:`read_ratings` reads (atomically)."""
    states = np.asarray(rated.demos.states)
    actions = np.asarray(rated.demos.actions)
    mask = np.asarray(rated.demos.mask)
    ratings = np.asarray(rated.ratings)
    lines = [",".join(REQUIRED)]
    for i in range(len(ratings)):
        for t in np.flatnonzero(mask[i]):
            lines.append(f"{i},{t},{states[i, t]},{actions[i, t]},{ratings[i]:.4f}")
    atomic_write(Path(path), "\n".join(lines) + "\n")
