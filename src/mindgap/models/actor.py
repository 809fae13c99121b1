"""The tanh-squashed Gaussian policy network of SAC (Haarnoja et al. 2018): its density, draws and greedy action.

A model, not an algorithm: SAC trains it, the simulated person's expected policy π_H is one,
and the explicability score reads its density.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .mlp import Params, mlp

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0


def actor_dist(actor: Params, obs: jax.Array):
    """Mean and log standard deviation of the pre-tanh Gaussian. obs [..., d] → ([..., a], [..., a])."""
    out = mlp(actor, obs)
    mean, log_std = jnp.split(out, 2, axis=-1)
    return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


def sample_action(actor: Params, obs: jax.Array, key: jax.Array, eps: jax.Array | None = None):
    """A squashed-Gaussian action and its log density. obs [..., d] → (action [..., a], log π [...]).

    ``eps`` (shaped like the action) replaces the standard normal draw, e.g. by one step of
    a coloured-noise sequence; ``key`` is then unused.
    """
    mean, log_std = actor_dist(actor, obs)
    if eps is None:
        eps = jax.random.normal(key, mean.shape, mean.dtype)
    u = mean + jnp.exp(log_std) * eps
    log_gauss = jnp.sum(-0.5 * eps**2 - log_std - 0.5 * jnp.log(2 * jnp.pi), axis=-1)
    # log |d tanh(u)/du| = log(1 − tanh²u) = 2 (log 2 − u − softplus(−2u)), stable for large |u|
    log_det = jnp.sum(2.0 * (jnp.log(2.0) - u - jax.nn.softplus(-2.0 * u)), axis=-1)
    return jnp.tanh(u), log_gauss - log_det


def greedy_action(actor: Params, obs: jax.Array) -> jax.Array:
    """tanh of the Gaussian's mean: the deterministic action used for evaluation."""
    return jnp.tanh(actor_dist(actor, obs)[0])
