"""Teachers that answer outside jitted code: people through the study app, or any Python callable.

A host teacher takes K pairs of segments as NumPy arrays (the layout of
:class:`~mindgap.data.segments.Segments`, ``[K, L, ·]``) and returns
``(labels [K] float32, answered [K] bool)`` with the label convention of
:func:`mindgap.teachers.preference.answer`: 1 = first preferred, 0 = second, 0.5 = equal.
The engine (:func:`mindgap.algorithms.engine.run`) then runs a feedback round in
three steps — jitted query selection, this call, jitted reward fitting — instead of
one jitted function; PrefBias and EPS ask people through the same interface.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import jax
import numpy as np

from ..data.segments import Segments
from ..envs.interface import Env
from .preference import TeacherConfig, answer


@runtime_checkable
class HostTeacher(Protocol):
    """Answers K queries: ``(seg_a, seg_b) → (labels [K], answered [K])``; ``name`` goes into run records."""

    name: str

    def __call__(self, seg_a: Segments, seg_b: Segments) -> tuple[np.ndarray, np.ndarray]: ...


class SimulatedHostTeacher:
    """The simulated person of :mod:`~mindgap.teachers.preference` behind the host interface.

    For tests and dry runs of live studies: with a deterministic configuration (``beta``
    None, no mistakes) it answers exactly as the jitted teacher does.
    """

    def __init__(
        self, env: Env, world_params, belief_params, cfg: TeacherConfig, *, key: jax.Array, name: str = "simulated"
    ):
        self.env, self.world_params, self.belief_params, self.cfg = env, world_params, belief_params, cfg
        self.key, self.name = key, name
        self.calls = 0

    def __call__(self, seg_a: Segments, seg_b: Segments) -> tuple[np.ndarray, np.ndarray]:
        self.key, k = jax.random.split(self.key)
        self.calls += 1
        labels, answered = answer(k, seg_a, seg_b, self.env, self.world_params, self.belief_params, self.cfg)
        return np.asarray(labels, np.float32), np.asarray(answered, bool)
