"""Finite MDPs as JAX pytrees (dissertation §2.2.1), and sampling trajectories in them.

A :class:`TabularMDP` holds the dynamics as data, so a person's *belief* about the
dynamics is simply another ``TabularMDP`` with other transitions (§2.2.1). All
arrays may carry extra leading batch axes; the planning functions in
:mod:`mindgap.planning` broadcast over them.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
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


@partial(jax.jit, static_argnames=("n_episodes", "length"))
def rollout(key, transitions, policy, initial, n_episodes: int, length: int):
    """Sample ``n_episodes`` trajectories of ``length`` steps.

    Args:
        key: PRNG key.
        transitions: ``[S, A, S]`` dynamics the trajectories follow.
        policy: ``[S, A]`` action probabilities.
        initial: ``[S]`` start distribution.
        n_episodes, length: static sizes.

    Returns:
        ``(states, actions)``, each ``[n_episodes, length]`` int32: the state-action
        pairs ``(s_t, a_t)`` of each demonstration.
    """
    k0, k_steps = jax.random.split(key)
    s0 = jax.random.categorical(k0, jnp.log(initial), shape=(n_episodes,))
    log_pi = jnp.log(policy)
    log_t = jnp.log(transitions)

    def step(s, k):
        ka, ks = jax.random.split(k)
        a = jax.random.categorical(ka, log_pi[s])
        s_next = jax.random.categorical(ks, log_t[s, a])
        return s_next, (s, a)

    _, (states, actions) = jax.lax.scan(step, s0, jax.random.split(k_steps, length))
    return states.T.astype(jnp.int32), actions.T.astype(jnp.int32)
