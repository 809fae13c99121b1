"""The agent's dynamics model T_A of EPS and its entropy H_T[s'|s,a] (§4.3.3, Algorithm 3 line 4).

§4.3.3 models T_A as "a two-headed neural network that outputs its mean and logarithm of
standard deviation given the state and action", trained on the agent's transitions. That
network already exists as f_ψ of PrefBias (:mod:`~mindgap.models.gaussian_dynamics`):
two heads, a mean and a scale of the next state, with normalisation and early stopping.
Its scale head is ``floor + softplus(raw)`` rather than ``exp(raw)`` — the same family
of Gaussians, bounded away from 0 where a step is deterministic (a bump into a wall),
where an unbounded log std would send H_T to −∞. It is reused here unchanged: Algorithm 3's
line 4 ("train T_A using D") is :func:`~mindgap.models.gaussian_dynamics.train_dynamics` on
the filled rows of the replay buffer (``valid = arange(capacity) < size``), warm-started
from the previous T_A. Its Gaussian negative log-likelihood trains the mean by the same
squared error as the dissertation's L2 loss and, in addition, the standard deviation
that H_T needs.

For a diagonal Gaussian the environment entropy of Eq. 4.6 is closed-form:

    H_T(s, a) = Σ_i (½ log(2πe) + log σ_i(s, a)).

A differential entropy depends on the units of s': measured in units scaled by ``c_i``
per coordinate it shifts by Σ_i log c_i. :func:`dynamics_entropy` takes that scale, so
a caller can state the units it means (EPS uses the world's cells; see
:mod:`~mindgap.algorithms.eps_reward`).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from .gaussian_dynamics import DynamicsModel, predict

HALF_LOG_2PI_E = 0.5 * math.log(2 * math.pi * math.e)


def gaussian_entropy(std: jax.Array) -> jax.Array:
    """Entropy of a diagonal Gaussian with standard deviations ``std [..., d]`` → [...] (nats)."""
    return jnp.sum(HALF_LOG_2PI_E + jnp.log(std), axis=-1)


def dynamics_entropy(
    model: DynamicsModel, obs: jax.Array, act: jax.Array, min_std: float, unit_scale: jax.Array | float = 1.0
) -> jax.Array:
    """H_T[s'|s,a] of the model's Gaussian: obs [..., d], act [..., a] → [...].

    Args:
        min_std: the floor the model was trained with (``DynamicsConfig.min_std``).
        unit_scale: [d] or scalar, how many units of the wanted scale one unit of ``obs``
            is; the entropy is that of ``unit_scale · s'``.
    """
    std = predict(model, obs, act, min_std)[1]
    return gaussian_entropy(std * unit_scale)
