"""Sleety braking: the stochastic part of the ego car's dynamics, and its exact density.

Written by hand because the scenario needs a braking model whose transition density is exact
and cheap for the simulated person (§4.4.2: on sleet "the vehicle's domain dynamics became
more stochastic"); highway-env's vehicles are deterministic.

**The model.** At each decision step the ego draws a braking factor

    μ ~ Beta(m(s) κ(s), (1 − m(s)) κ(s)),  m(s) = m_dry + (m_sleet − m_dry) s,
                                            κ(s) = κ_dry^(1−s) κ_sleet^s,

(:class:`~mindgap.envs.driving.params.Grip`; s the sleet level). When the step brakes —
the speed is above the controller's target by more than :data:`BRAKING_MARGIN` after the
meta-action — every one of its ``n`` = 15 integration steps achieves μ times the commanded
deceleration ``(v − v_target)/τ``; otherwise the speed controller acts as on a dry road and
μ plays no part. Steering is not affected, so on sleet changing lane keeps working while
braking does not. With ``k = K_A · dt`` (K_A = 1/τ) the speed after the step is

    v' = v_T + (v − v_T) (1 − μ k)^n,

a decreasing function of μ on (0, 1) (``k`` = 1/9 < 1, so the speed never crosses the
target), hence μ is recovered from v' and the density of the next speed is the Beta density
with the Jacobian of that map:

    μ(v') = (1 − g^(1/n)) / k,   g = (v' − v_T)/(v − v_T) ∈ ((1 − k)^n, 1),
    log p(v' | v, v_T) = log Beta(μ(v')) + log |dμ/dv'|,  |dμ/dv'| = g^(1/n − 1) / (n k (v − v_T)).

Everything else in a step (positions, heading, the other cars) is a deterministic function of
the state, the action, μ and the front car's braking onset (world.py), so this density and the
onset's probability are the whole stochastic part.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.scipy.special import betaln

from .params import DT, KP_A, SUBSTEPS, Grip

BRAKING_MARGIN = 0.05
"""A step brakes (and draws on the grip) when the speed exceeds its target by more than this [m/s]; below it the
controller's residual approach is left deterministic (and the inverse map above stays well conditioned)."""
K = KP_A * DT
"""The speed controller's gain per integration step (1/9)."""


def beta_params(sleet: jax.Array, grip: Grip) -> tuple[jax.Array, jax.Array]:
    """(α, β) of the braking factor's Beta distribution at sleet level ``sleet``."""
    mean = grip.dry_mean + (grip.sleet_mean - grip.dry_mean) * sleet
    conc = jnp.exp(jnp.log(grip.dry_concentration) * (1 - sleet) + jnp.log(grip.sleet_concentration) * sleet)
    return mean * conc, (1 - mean) * conc


def factor_mean_std(sleet, grip: Grip) -> tuple[jax.Array, jax.Array]:
    """Mean and standard deviation of the braking factor."""
    a, b = beta_params(sleet, grip)
    n = a + b
    return a / n, jnp.sqrt(a * b / (n**2 * (n + 1)))


def sample_factor(key: jax.Array, sleet, grip: Grip) -> jax.Array:
    """One braking factor μ in (0, 1), kept strictly inside so that its density stays finite."""
    a, b = beta_params(sleet, grip)
    tiny = jnp.finfo(jnp.float32).eps
    return jnp.clip(jax.random.beta(key, a, b), tiny, 1 - tiny)


def log_prob_factor(mu, sleet, grip: Grip) -> jax.Array:
    """log Beta(μ | α(s), β(s)); −inf outside (0, 1)."""
    a, b = beta_params(sleet, grip)
    inside = (mu > 0) & (mu < 1)
    m = jnp.clip(mu, 1e-30, 1 - 1e-7)
    lp = (a - 1) * jnp.log(m) + (b - 1) * jnp.log1p(-m) - betaln(a, b)
    return jnp.where(inside, lp, -jnp.inf)


def brakes(speed, target_speed) -> jax.Array:
    """Whether a step from ``speed`` towards ``target_speed`` brakes (and so depends on the grip)."""
    return speed - target_speed > BRAKING_MARGIN


def braked_speed(speed, target_speed, mu, n: int = SUBSTEPS) -> jax.Array:
    """The closed form of the speed after ``n`` braking integration steps with factor μ."""
    return target_speed + (speed - target_speed) * (1 - mu * K) ** n


def factor_of_speed(speed, target_speed, next_speed, n: int = SUBSTEPS) -> tuple[jax.Array, jax.Array]:
    """(μ, log |dμ/dv'|): the braking factor that turns ``speed`` into ``next_speed``, and the Jacobian's log."""
    span = speed - target_speed
    g = (next_speed - target_speed) / span
    gp = jnp.clip(g, 1e-30, None)
    root = gp ** (1.0 / n)
    mu = jnp.where(g > 0, (1 - root) / K, jnp.inf)
    log_jac = (1.0 / n - 1) * jnp.log(gp) - jnp.log(n * K * span)
    return mu, log_jac


def log_prob_speed(speed, target_speed, next_speed, sleet, grip: Grip) -> jax.Array:
    """log p(v' | v, v_T) of a braking step (module docstring); −inf where no factor in (0, 1) gives v'."""
    mu, log_jac = factor_of_speed(speed, target_speed, next_speed)
    return log_prob_factor(mu, sleet, grip) + log_jac
