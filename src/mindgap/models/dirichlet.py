"""Dirichlet distributions over a masked support, in log space.

Written by hand because GeReL needs what ``jax.scipy.stats.dirichlet`` does not give:
a per-factor *mask* (a state-action pair's support has a varying number of next
states, padded to a fixed width), the entropy and cross-entropy in closed form, the
score ``∇_α log q(θ|α)`` for the score-function estimator, and samples in log space
so that tiny components do not underflow.

:func:`loggamma` replaces ``jax.random.loggamma``, whose rejection loop takes seconds
to compile and whose exact gradient costs ten times the rest of a GeReL step. It
augments the shape by :data:`BOOST` (``Gamma(α) = Gamma(α + B) · Π_i U_i^{1/(α+i)}``,
Naesseth et al. 2017) and draws ``Gamma(α + B)`` by Marsaglia–Tsang with
:data:`PROPOSALS` proposals in parallel (no loop; at shape ≥ 3 each is accepted with
probability above 0.98, so keeping a rejected one has odds below 1e-7). The gradient
differentiates the boost factors exactly and the ``Gamma(α + B)`` draw through the
Wilson–Hilferty transform held fixed. Its expected gradients match ``ψ'(α)`` to within
Monte Carlo error for ``α`` from 0.05 to 3000 (``tests/models/test_dirichlet.py``).

Shapes: ``alpha`` and ``mask`` are ``[..., M]``; masked-out components have zero
probability and contribute nothing.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jax.scipy.special import digamma, gammaln

NEG = -1e30
BOOST = 3
"""Shape augmentation of the Gamma sampler."""
PROPOSALS = 4
"""Parallel Marsaglia–Tsang proposals per draw."""


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def loggamma(key, alpha) -> jnp.ndarray:
    """``log x`` with ``x ~ Gamma(α, 1)``, elementwise, with a cheap implicit gradient."""
    return _loggamma(key, alpha)[0]


def _log_gamma_large(key, shape):
    """``log y``, ``y ~ Gamma(shape)`` for ``shape >= 1`` (Marsaglia & Tsang 2000), loop-free."""
    k_z, k_u = jax.random.split(key)
    d = shape - 1.0 / 3.0
    c = 1.0 / jnp.sqrt(9.0 * d)
    z = jax.random.normal(k_z, (PROPOSALS,) + shape.shape, shape.dtype)
    log_u = jnp.log(jax.random.uniform(k_u, z.shape, shape.dtype, minval=1e-37))
    v = 1.0 + c * z
    v3 = jnp.maximum(v, 1e-6) ** 3
    ok = (v > 0) & (log_u < 0.5 * z**2 + d - d * v3 + d * jnp.log(v3))
    first = jnp.argmax(ok, axis=0)
    log_v3 = jnp.take_along_axis(jnp.log(v3), first[None], axis=0)[0]
    return jnp.log(d) + log_v3


def _loggamma(key, alpha):
    k_g, k_u = jax.random.split(key)
    shape = alpha + BOOST
    log_y = _log_gamma_large(k_g, shape)
    log_u = jnp.log(jax.random.uniform(k_u, (BOOST,) + alpha.shape, minval=1e-37))
    shifts = jnp.arange(BOOST, dtype=alpha.dtype).reshape((BOOST,) + (1,) * alpha.ndim)
    return log_y + (log_u / (alpha + shifts)).sum(0), (log_y, log_u, shifts, shape)


@loggamma.defjvp
def _loggamma_jvp(key, primals, tangents):
    (alpha,), (d_alpha,) = primals, tangents
    out, (log_y, log_u, shifts, k) = _loggamma(key, alpha)
    # Wilson–Hilferty: z = ((y/k)^(1/3) − 1 + 1/(9k)) · 3√k is ~N(0, 1); hold z fixed.
    root_k = jnp.sqrt(k)
    z = (jnp.exp(log_y / 3.0) / k ** (1.0 / 3.0) - 1.0 + 1.0 / (9.0 * k)) * 3.0 * root_k
    m = 1.0 - 1.0 / (9.0 * k) + z / (3.0 * root_k)
    d_log_y = 1.0 / k + 3.0 * (1.0 / (9.0 * k**2) - z / (6.0 * k * root_k)) / m
    d_boost = (-log_u / (alpha + shifts) ** 2).sum(0)
    return out, (d_log_y + d_boost) * d_alpha


def sample_log(key, alpha, mask, shape=()) -> jnp.ndarray:
    """``log θ`` for ``θ ~ Dir(α)``; ``shape`` is prepended; masked entries are ``NEG``.

    Differentiable in ``alpha`` (implicit reparameterisation of the Gamma sampler).
    """
    a = jnp.where(mask, alpha, 1.0)
    lg = loggamma(key, jnp.broadcast_to(a, shape + a.shape))
    lg = jnp.where(mask, lg, -jnp.inf)
    log_theta = lg - jax.nn.logsumexp(lg, axis=-1, keepdims=True)
    return jnp.where(mask, log_theta, NEG)


def log_normaliser(alpha, mask) -> jnp.ndarray:
    """``log B(α) = Σ log Γ(α_m) − log Γ(Σ α_m)`` over the unmasked components."""
    a = jnp.where(mask, alpha, 1.0)
    return jnp.where(mask, gammaln(a), 0.0).sum(-1) - gammaln(jnp.where(mask, a, 0.0).sum(-1))


def log_prob(log_theta, alpha, mask) -> jnp.ndarray:
    """``log Dir(θ | α)`` from ``log θ``, summed over the last axis."""
    a = jnp.where(mask, alpha, 1.0)
    return jnp.where(mask, (a - 1.0) * log_theta, 0.0).sum(-1) - log_normaliser(alpha, mask)


def score(log_theta, alpha, mask) -> jnp.ndarray:
    """``∇_α log Dir(θ | α) = ψ(Σα) − ψ(α) + log θ`` (zero on masked entries)."""
    a = jnp.where(mask, alpha, 1.0)
    total = jnp.where(mask, a, 0.0).sum(-1, keepdims=True)
    return jnp.where(mask, digamma(total) - digamma(a) + log_theta, 0.0)


def expected_log_theta(alpha, mask) -> jnp.ndarray:
    """``E_q[log θ_m] = ψ(α_m) − ψ(Σα)``."""
    a = jnp.where(mask, alpha, 1.0)
    total = jnp.where(mask, a, 0.0).sum(-1, keepdims=True)
    return jnp.where(mask, digamma(a) - digamma(total), 0.0)


def cross_entropy_term(alpha_q, alpha_p, mask) -> jnp.ndarray:
    """``E_{Dir(α_q)}[log Dir(θ | α_p)]`` in closed form."""
    elog = expected_log_theta(alpha_q, mask)
    return jnp.where(mask, (alpha_p - 1.0) * elog, 0.0).sum(-1) - log_normaliser(alpha_p, mask)


def entropy(alpha, mask) -> jnp.ndarray:
    """Differential entropy of ``Dir(α)`` over the unmasked components."""
    return -cross_entropy_term(alpha, alpha, mask)


def mean(alpha, mask) -> jnp.ndarray:
    """``E[θ] = α / Σα`` (zero on masked entries)."""
    a = jnp.where(mask, alpha, 0.0)
    return a / a.sum(-1, keepdims=True)
