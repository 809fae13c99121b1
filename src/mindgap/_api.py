"""What the public method modules (:mod:`mindgap.sac`, :mod:`mindgap.pebble`, …) share: the result type."""

from __future__ import annotations

from typing import Any, TypedDict

import numpy as np


class RunResult(TypedDict):
    """What every method's ``train`` returns.

    Attributes:
        curve: rows ``(seed, env_steps, mean greedy return, queries shown)``, one per evaluation.
        final_returns: ``[seeds, episodes]`` greedy returns under the true reward after training.
        paths: per seed, a few greedy trajectories (``World.trace`` of their observations).
        config: the run record (world, its fingerprint, teacher, seeds, the method's config).
        carry: the final state of every seed (a leading seed axis on each leaf).
    """

    curve: list[tuple]
    final_returns: np.ndarray
    paths: list[list[np.ndarray]]
    config: dict
    carry: Any
