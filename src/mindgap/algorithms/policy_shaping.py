"""Policy Shaping (Griffith et al. 2013) for continuous actions: the normalised product of two policies.

Policy Shaping combines a policy learned from the environment's reward, π_R, with one
learned from the person's feedback, π_F, as ``π(a|s) ∝ π_R(a|s) π_F(a|s)``. The original
has discrete actions, where the product is normalised by a sum. Here both are SAC's
tanh-squashed diagonal Gaussians (π_R: SAC on r_A; π_F: DRLHP's SAC on the reward learned
from expectation preferences), and the product is taken of the **pre-tanh Gaussians**,
then squashed:

    N(u; μ₁, σ₁²) N(u; μ₂, σ₂²) ∝ N(u; μ, σ²),   1/σ² = 1/σ₁² + 1/σ₂²,   μ = σ² (μ₁/σ₁² + μ₂/σ₂²),

per coordinate, and a = tanh(u). Multiplying the squashed densities instead would carry
the Jacobian twice — ``N(u; μ, σ²) / (1 − a²)`` over actions — which has no closed-form
normaliser and piles mass on the bounds of the action box; the pre-tanh product is the
exact normalised product of the two Gaussians that the actors parameterise, stays in
SAC's family (so the shaped policy samples, scores and acts greedily like any actor),
and reduces to Griffith et al.'s rule wherever the squashing is nearly linear.

Weights ``w_R, w_F`` (``π_R^{w_R} π_F^{w_F}``, normalised) scale the precisions; 1 and
1 is the plain product. Like the discrete rule, the product of two confident policies
that disagree is a confident compromise between them (the dissertation's D3 failure):
the product of N(−1, 0.1²) and N(1, 0.1²) is N(0, 0.07²).

Written by hand (a few lines); no library offers the product of two policies.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..models.actor import LOG_STD_MAX, LOG_STD_MIN, actor_dist
from ..models.mlp import Params
from ..models.squashed import gaussian_log_prob, tanh_log_det


class ShapedPolicy(NamedTuple):
    """The two SAC actors and the exponents of their product (a pytree, for jit and vmap).

    Attributes:
        env: actor trained on the environment's reward (π_R).
        feedback: actor trained on the reward learned from feedback (π_F).
        w_env, w_feedback: exponents of each factor (1 and 1: the plain product).
    """

    env: Params
    feedback: Params
    w_env: jax.Array | float = 1.0
    w_feedback: jax.Array | float = 1.0


def gaussian_product(mean1, log_std1, mean2, log_std2, w1=1.0, w2=1.0) -> tuple[jax.Array, jax.Array]:
    """Normalised ``N(μ₁, σ₁²)^{w₁} N(μ₂, σ₂²)^{w₂}`` per coordinate: its mean and log std (broadcasting shapes)."""
    prec1 = w1 * jnp.exp(-2.0 * log_std1)
    prec2 = w2 * jnp.exp(-2.0 * log_std2)
    prec = prec1 + prec2
    mean = (prec1 * mean1 + prec2 * mean2) / prec
    return mean, -0.5 * jnp.log(prec)


def shaped_dist(policy: ShapedPolicy, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Pre-tanh mean and log std of the shaped policy: obs [..., d] → ([..., a], [..., a]) (as ``actor_dist``)."""
    mean, log_std = gaussian_product(
        *actor_dist(policy.env, obs), *actor_dist(policy.feedback, obs), policy.w_env, policy.w_feedback
    )
    return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


def shaped_sample(policy: ShapedPolicy, obs: jax.Array, key: jax.Array) -> tuple[jax.Array, jax.Array]:
    """A squashed action of the shaped policy and its log density: obs [..., d] → ([..., a], [...])."""
    mean, log_std = shaped_dist(policy, obs)
    u = mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape, mean.dtype)
    return jnp.tanh(u), gaussian_log_prob(mean, log_std, u) - tanh_log_det(u)


def shaped_greedy(policy: ShapedPolicy, obs: jax.Array) -> jax.Array:
    """tanh of the product's mean: the deterministic action for evaluation."""
    return jnp.tanh(shaped_dist(policy, obs)[0])
