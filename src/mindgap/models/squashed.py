"""Densities of the tanh-squashed Gaussian policies of SAC at given actions.

:func:`~mindgap.algorithms.sac.sample_action` returns the log density of the action it
draws; the expected policy of a simulated person, the explicability score and policy
shaping also need the density of an action someone else took. A diagonal Gaussian over
``u`` and ``a = tanh(u)`` give

    log π(a|s) = log N(u; μ(s), σ(s)²) − Σ_i log(1 − tanh² u_i),   u = atanh(a).

Written by hand (a few lines) in the same stable form as ``sample_action``, so the two
agree to rounding; the repository carries no distribution library.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

EDGE = 1e-6
"""Actions are kept ``EDGE`` inside (−1, 1) before ``atanh``: float32 ``tanh`` reaches ±1
exactly for |u| > 9, where the density of the squashed action would be infinite."""


def gaussian_log_prob(mean: jax.Array, log_std: jax.Array, u: jax.Array) -> jax.Array:
    """log N(u; mean, diag exp(log_std)²) summed over the last axis: [..., a] → [...]."""
    z = (u - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z**2 - log_std - 0.5 * jnp.log(2 * jnp.pi), axis=-1)


def tanh_log_det(u: jax.Array) -> jax.Array:
    """Σ_i log(1 − tanh² u_i) = Σ_i 2 (log 2 − u_i − softplus(−2 u_i)), stable for large |u|: [..., a] → [...]."""
    return jnp.sum(2.0 * (jnp.log(2.0) - u - jax.nn.softplus(-2.0 * u)), axis=-1)


def pre_tanh(act: jax.Array) -> jax.Array:
    """atanh of the action, kept finite at the bounds (see :data:`EDGE`)."""
    return jnp.arctanh(jnp.clip(act, -1.0 + EDGE, 1.0 - EDGE))


def squashed_log_prob(mean: jax.Array, log_std: jax.Array, act: jax.Array) -> jax.Array:
    """log π(a|s) of the tanh-squashed Gaussian with pre-tanh ``mean, log_std`` at ``act``: [..., a] → [...]."""
    u = pre_tanh(act)
    return gaussian_log_prob(mean, log_std, u) - tanh_log_det(u)
