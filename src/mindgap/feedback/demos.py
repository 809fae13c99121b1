"""Demonstrations drawn from a tabular world: rollouts of a policy (or a uniform one) under its true
dynamics (§2.3.1). The containers are :mod:`mindgap.data.demos`'s."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..data.demos import Demonstrations
from ..envs.tabular import TabularMDP, rollout


def random_demonstrations(key, mdp: TabularMDP, count: int, length: int = 10) -> Demonstrations:
    """Uniform-random-policy rollouts under the true dynamics (Fig. 3, §2.3.1)."""
    uniform = jnp.full((mdp.n_states, mdp.n_actions), 1.0 / mdp.n_actions)
    return policy_demonstrations(key, mdp, uniform, count, length)


def policy_demonstrations(key, mdp: TabularMDP, policy, count: int, length: int = 10) -> Demonstrations:
    """Rollouts of ``policy`` ``[S, A]`` under the true dynamics of ``mdp``."""
    states, actions = jax.jit(rollout, static_argnums=(4, 5))(key, mdp.transitions, policy, mdp.initial, count, length)
    return Demonstrations(states, actions, jnp.ones(states.shape, bool))
