"""Finite MDPs as JAX pytrees (dissertation §2.2.1).

A :class:`TabularMDP` holds the dynamics as data, so a person's *belief* about the
dynamics is simply another ``TabularMDP`` with other transitions (SPEC §3). All
arrays may carry extra leading batch axes; the planning functions in
:mod:`mindgap.planning` broadcast over them.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np


class TabularMDP(NamedTuple):
    """A finite MDP with state-based linear rewards ``R(s) = w · φ(s)``.

    Attributes:
        transitions: ``[S, A, S]`` array, ``transitions[s, a, s'] = T(s' | s, a)``.
        features: ``[S, K]`` state features ``φ(s)``.
        discount: scalar discount factor ``λ`` in ``[0, 1)``.
        initial: ``[S]`` initial-state distribution.
    """

    transitions: jnp.ndarray
    features: jnp.ndarray
    discount: jnp.ndarray
    initial: jnp.ndarray

    @property
    def n_states(self) -> int:
        return self.transitions.shape[-3]

    @property
    def n_actions(self) -> int:
        return self.transitions.shape[-2]

    @property
    def n_features(self) -> int:
        return self.features.shape[-1]

    def reward(self, weights: jnp.ndarray) -> jnp.ndarray:
        """State rewards ``R(s) = w · φ(s)``; ``weights`` is ``[..., K]``, result ``[..., S]``."""
        return jnp.einsum("...k,sk->...s", weights, self.features)

    def with_transitions(self, transitions: jnp.ndarray) -> TabularMDP:
        """The same world under other dynamics (e.g. a person's belief)."""
        return self._replace(transitions=transitions)


def check_transitions(transitions: np.ndarray, *, name: str = "transitions") -> np.ndarray:
    """Validate a ``[S, A, S]`` stochastic tensor and return it as float32.

    Raises:
        ValueError: naming the first problem found (shape, negative entries, rows
            that do not sum to one).
    """
    t = np.asarray(transitions, dtype=np.float64)
    if t.ndim != 3 or t.shape[0] != t.shape[2]:
        raise ValueError(f"{name} must have shape [S, A, S], got {t.shape}")
    if np.any(~np.isfinite(t)) or np.any(t < 0):
        raise ValueError(f"{name} has negative or non-finite entries")
    sums = t.sum(-1)
    bad = np.argwhere(np.abs(sums - 1.0) > 1e-4)
    if len(bad):
        s, a = bad[0]
        raise ValueError(f"{name}[{s}, {a}, :] sums to {sums[s, a]:.6f}, not 1")
    return t.astype(np.float32)
