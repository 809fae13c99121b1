"""The rating model of GeReL (§2.2.2): expected rating and censored Gaussian likelihood.

The person's mean rating of ``ζ`` is ``γ̃ = γ_max · (Π_i π̃(a_i|s_i))^{1/n}``, the
geometric mean of their softmax policy on the demonstrated steps. Observed ratings are
``N(γ̃, σ²)`` clipped to ``[0, γ_max]``; a rating at a bound is a censored observation
(the slider cannot go further), so its likelihood is the Gaussian tail mass beyond the bound.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax.scipy.special import log_ndtr

from ..data.demos import Demonstrations


def mean_log_policy(log_policy, demos: Demonstrations) -> jnp.ndarray:
    """``(1/n) Σ_i log π̃(a_i|s_i)`` per demonstration.

    Args:
        log_policy: ``[..., S, A]`` log action probabilities.
        demos: ``N`` demonstrations.

    Returns:
        ``[..., N]``.
    """
    picked = log_policy[..., demos.states, demos.actions]
    m = demos.mask
    return (picked * m).sum(-1) / m.sum(-1)


def mean_log_policy_from_counts(log_policy, counts) -> jnp.ndarray:
    """:func:`mean_log_policy` from step counts ``[N, S·A]`` (see ``Demonstrations.step_counts``)."""
    flat = log_policy.reshape(log_policy.shape[:-2] + (-1,))
    return jnp.einsum("...x,nx->...n", flat, counts) / counts.sum(-1)


def expected_rating(log_policy, demos: Demonstrations, gamma_max: float = 10.0) -> jnp.ndarray:
    """``γ̃_H = γ_max · exp(mean log π̃)`` per demonstration, ``[..., N]``."""
    return gamma_max * jnp.exp(mean_log_policy(log_policy, demos))


def censored_log_likelihood(ratings, mean, noise: float = 0.5, gamma_max: float = 10.0) -> jnp.ndarray:
    """Per-rating log-likelihood of ``N(mean, noise²)`` clipped to ``[0, γ_max]``.

    A rating of 0 counts as "at most 0" (``log Φ(−mean/σ)``), a rating of ``γ_max``
    as "at least γ_max"; others use the Gaussian density.
    """
    z = (ratings - mean) / noise
    dens = -0.5 * z**2 - jnp.log(noise) - 0.5 * jnp.log(2 * jnp.pi)
    low = log_ndtr(z)
    high = log_ndtr(-z)
    return jnp.where(ratings <= 0.0, low, jnp.where(ratings >= gamma_max, high, dens))
