"""Bayesian MLPs with factorised Gaussian posteriors (Bayes by backprop, §3.3.3.1).

Every weight and bias ``θ_i`` has its own posterior ``q(θ_i) = N(μ_i, σ_i²)`` with
``σ_i = softplus(ρ_i)`` so that the standard deviation stays positive (Blundell et al.
2015; §3.3.3.4). A posterior is a :class:`Gaussian` of two pytrees, ``mean`` and ``rho``,
each shaped like the deterministic MLP parameters of :mod:`~mindgap.models.mlp` — so the
posterior mean *is* an MLP, and a prior may be centred on any MLP of the same
architecture (a random initialisation, or a learned dynamics model f_ψ).

A Bayesian MLP is evaluated on one draw of all its weights, :func:`sample_params` +
:func:`~mindgap.models.mlp.mlp`: a consistent function sample. PrefBias draws one per
preference (:func:`~mindgap.models.prefbias_nets.draw_per_pair`), so that every step of a
compared pair sees the same function, as the likelihood p(d | w, φ) of Eq. 3.3 requires.

The KL divergence to a factorised Gaussian prior ``N(m_i, s²)`` is in closed form,
``Σ_i log(s/σ_i) + (σ_i² + (μ_i − m_i)²) / (2 s²) − ½`` (:func:`kl_divergence`).

Hand-written: neither distrax nor TensorFlow Probability's JAX substrate is a dependency,
and the two Gaussian formulas above are a few lines each.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from .mlp import Params


class Gaussian(NamedTuple):
    """A factorised Gaussian over MLP parameters: ``mean`` and ``rho`` shaped like :data:`Params`.

    The standard deviation of each parameter is ``softplus(rho)``.
    """

    mean: Params
    rho: Params


def softplus_inverse(sigma: float) -> float:
    """ρ with softplus(ρ) = σ (σ > 0)."""
    return math.log(math.expm1(sigma))


def stddev(post: Gaussian) -> Params:
    """σ = softplus(ρ) of every parameter."""
    return jax.tree.map(jax.nn.softplus, post.rho)


def init_gaussian(mean: Params, sigma: float = 1e-3) -> Gaussian:
    """A posterior centred on ``mean`` (e.g. :func:`~mindgap.models.mlp.init_mlp`) with every σ equal to ``sigma``."""
    rho = softplus_inverse(sigma)
    return Gaussian(mean, jax.tree.map(lambda x: jnp.full_like(x, rho), mean))


def kl_divergence(post: Gaussian, prior_mean: Params | None, prior_std: float | jax.Array) -> jax.Array:
    """Closed-form KL[q ‖ p] summed over all parameters (the two KL terms of Eq. 3.3).

    Args:
        post: the posterior q.
        prior_mean: the centre of the factorised prior p = N(prior_mean, prior_std²), a
            pytree shaped like ``post.mean``; None centres it at zero.
        prior_std: the prior's standard deviation s (> 0): one for every parameter, or one each as a
            flat array in ``ravel_pytree`` order.

    Returns:
        scalar ``Σ_i log(s/σ_i) + (σ_i² + (μ_i − m_i)²) / (2 s²) − ½``.
    """
    mu, rho = ravel_pytree(post.mean)[0], ravel_pytree(post.rho)[0]
    m = 0.0 if prior_mean is None else ravel_pytree(prior_mean)[0]
    sigma = jax.nn.softplus(rho)
    return jnp.sum(jnp.log(prior_std) - jnp.log(sigma) + (sigma**2 + (mu - m) ** 2) / (2 * jnp.square(prior_std)) - 0.5)


def sample_params(post: Gaussian, key: jax.Array) -> Params:
    """One draw θ = μ + σ ε of all parameters, ε ~ N(0, I)."""
    mu, unravel = ravel_pytree(post.mean)
    sigma = jax.nn.softplus(ravel_pytree(post.rho)[0])
    return unravel(mu + sigma * jax.random.normal(key, mu.shape, mu.dtype))
