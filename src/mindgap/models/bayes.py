"""Bayesian MLPs with factorised Gaussian posteriors (Bayes by backprop, §3.3.3.1).

Every weight and bias ``θ_i`` has its own posterior ``q(θ_i) = N(μ_i, σ_i²)`` with
``σ_i = softplus(ρ_i)`` so that the standard deviation stays positive (Blundell et al.
2015; §3.3.3.4). A posterior is a :class:`Gaussian` of two pytrees, ``mean`` and ``rho``,
each shaped like the deterministic MLP parameters of :mod:`~mindgap.models.mlp` — so the
posterior mean *is* an MLP, and a prior may be centred on any MLP of the same
architecture (a random initialisation, or a learned dynamics model f_ψ).

Two ways to evaluate a Bayesian MLP on a batch:

* :func:`bnn_local` — the local reparameterisation trick (Kingma, Salimans & Welling 2015):
  the pre-activations ``x W + b`` of a layer are Gaussian given ``x``, with mean
  ``x μ_W + μ_b`` and variance ``x² σ_W² + σ_b²``, so they are sampled directly, with
  independent noise for every row of the batch. Lower-variance gradients, no weight matrix
  per example.
* :func:`sample_params` + :func:`~mindgap.models.mlp.mlp` — one draw of all weights shared by
  the whole batch: a consistent function sample (used for posterior predictive samples).

The KL divergence to a factorised Gaussian prior ``N(m_i, s²)`` is in closed form,
``Σ_i log(s/σ_i) + (σ_i² + (μ_i − m_i)²) / (2 s²) − ½`` (:func:`kl_divergence`).

Hand-written: neither distrax nor TensorFlow Probability's JAX substrate is a dependency,
and the two Gaussian formulas above are a few lines each.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
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
        prior_std: the prior's standard deviation s (scalar, > 0).

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
    return unravel(mu + sigma * jax.random.normal(key, mu.shape, mu.dtype))  # one draw: see bnn_local


def dense_moments(mean: tuple, sigma: tuple, x: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Mean and variance of the pre-activations ``x W + b`` under q, given ``x [..., in]``.

    Returns:
        (γ = x μ_W + μ_b, δ = x² σ_W² + σ_b²), each [..., out].
    """
    (mw, mb), (sw, sb) = mean, sigma
    return x @ mw + mb, jnp.square(x) @ jnp.square(sw) + jnp.square(sb)


def bnn_local(post: Gaussian, x: jax.Array, key: jax.Array, activation: Callable = jax.nn.relu) -> jax.Array:
    """A sample of the Bayesian MLP's output with the local reparameterisation trick.

    Each layer's pre-activations are drawn as ``γ + √δ ε`` (:func:`dense_moments`), with
    independent ε for every row of ``x [..., in]`` — every example sees its own weights.
    No activation after the last layer. Returns [..., out].
    """
    widths = [b.shape[-1] for _, b in post.mean]
    rows = math.prod(x.shape[:-1])
    # one draw for all layers: each random-number op adds noticeably to the compile time on CPU
    eps = jax.random.normal(key, (rows * sum(widths),), x.dtype)
    ends = list(itertools.accumulate(w * rows for w in widths))
    for i, (mean, sd) in enumerate(zip(post.mean, stddev(post))):
        gamma, delta = dense_moments(mean, sd, x)
        x = gamma + jnp.sqrt(delta) * eps[ends[i] - widths[i] * rows : ends[i]].reshape(gamma.shape)
        if i < len(post.mean) - 1:
            x = activation(x)
    return x
