"""Demonstrations and their ratings as frozen, shape-checked containers (§2.2.1).

Plain pytrees in the bottom layer, so that worlds (the coffee robot's scripted demonstrations),
models (the rating model) and teachers build them without importing each other;
:mod:`mindgap.feedback.demos` draws them from a tabular world's policies.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np


class Demonstrations(NamedTuple):
    """A batch of state-action sequences ``ζ = {(s_1, a_1), …, (s_n, a_n)}``.

    Attributes:
        states: ``[N, L]`` int32 state ids.
        actions: ``[N, L]`` int32 action ids.
        mask: ``[N, L]`` bool, False on padding (demonstrations may differ in length).
    """

    states: jnp.ndarray
    actions: jnp.ndarray
    mask: jnp.ndarray

    @property
    def count(self) -> int:
        return self.states.shape[0]

    def step_counts(self, n_states: int, n_actions: int) -> jnp.ndarray:
        """``[N, S·A]`` how often each demonstration visits each ``(s, a)`` pair.

        Turns per-step gathers into one matrix product, which is cheaper to
        differentiate than a scatter when many sampled policies are scored at once.
        """
        flat = self.states * n_actions + self.actions
        onehot = jax.nn.one_hot(flat, n_states * n_actions, dtype=jnp.float32)
        return (onehot * self.mask[..., None]).sum(1)

    def take(self, n: int) -> Demonstrations:
        """The first ``n`` demonstrations."""
        return Demonstrations(self.states[:n], self.actions[:n], self.mask[:n])


class RatedDemonstrations(NamedTuple):
    """Demonstrations with one rating each, ``ratings`` ``[N]`` in ``[0, γ_max]``."""

    demos: Demonstrations
    ratings: jnp.ndarray

    def take(self, n: int) -> RatedDemonstrations:
        return RatedDemonstrations(self.demos.take(n), self.ratings[:n])


def make_demonstrations(states, actions, mask=None, *, n_states: int, n_actions: int) -> Demonstrations:
    """Validate and pack demonstrations.

    Raises:
        ValueError: on shape mismatch, an empty demonstration, or a state/action id
            outside the domain.
    """
    states = np.asarray(states)
    actions = np.asarray(actions)
    mask = np.ones(states.shape, bool) if mask is None else np.asarray(mask, bool)
    if states.ndim != 2 or states.shape != actions.shape or states.shape != mask.shape:
        raise ValueError(f"states {states.shape}, actions {actions.shape} and mask {mask.shape} must be equal [N, L]")
    if np.any(mask.sum(1) == 0):
        raise ValueError(f"demonstration {int(np.argmax(mask.sum(1) == 0))} has no steps")
    for name, ids, n in (("state", states, n_states), ("action", actions, n_actions)):
        bad = mask & ((ids < 0) | (ids >= n))
        if bad.any():
            i, t = np.argwhere(bad)[0]
            raise ValueError(f"unknown {name} id {ids[i, t]} in demonstration {i}, step {t} (valid: 0..{n - 1})")
    return Demonstrations(
        jnp.asarray(np.where(mask, states, 0), jnp.int32),
        jnp.asarray(np.where(mask, actions, 0), jnp.int32),
        jnp.asarray(mask),
    )
