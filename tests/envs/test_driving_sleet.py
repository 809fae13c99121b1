"""Sleety braking's exact density: it integrates to one, matches the steps' samples, and tells a dry-road belief apart."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.driving import log_prob as _log_prob
from mindgap.envs.driving import make_params, observe, reset
from mindgap.envs.driving import step as _step
from mindgap.envs.driving.params import IDLE, SLOWER, Grip
from mindgap.envs.driving.sleet import K, braked_speed, factor_mean_std, factor_of_speed, log_prob_factor
from mindgap.envs.driving.world import SPEED_SCALE

PARAMS = make_params(sleet=1.0, brake_window=(0, 0))
step, log_prob = jax.jit(_step), jax.jit(_log_prob)
N = 4000
"""Samples per batch: every test draws batches of this size, so the sampler compiles once."""
SPEED = 2  # the observation's speed entry


def braking_state(key):
    """Just after the front car started braking, at 25 m/s: SLOWER from here brakes towards 20 m/s."""
    s = reset(key, PARAMS)
    return s._replace(braking=jnp.asarray(True), t=jnp.int32(1))


@jax.jit
def next_obs_sample(keys, state, params):
    """The observations that SLOWER leads to from ``state``, one per key."""
    return jax.vmap(lambda k: observe(step(k, state, jnp.int32(SLOWER), params).state, params))(keys)


@jax.jit
def log_probs(obs, next_obs, speeds, params):
    """log_prob of ``obs`` → ``next_obs`` with its speed replaced by each of ``speeds`` [m/s]."""
    nxt = jax.vmap(lambda v: next_obs.at[SPEED].set(v / SPEED_SCALE))(speeds)
    return jax.vmap(log_prob, (None, None, 0, None))(obs, jnp.int32(SLOWER), nxt, params)


def speed_grid(n=200_001):
    """The next speeds a braking step from 25 m/s towards 20 m/s can reach: μ ∈ (0, 1)."""
    lo = braked_speed(25.0, 20.0, 1.0)
    return np.linspace(lo, 25.0, n)[1:-1]


@pytest.mark.parametrize("sleet", [0.0, 0.5, 1.0])
def test_the_density_of_the_realised_deceleration_integrates_to_one(key, sleet):
    s = braking_state(key)
    params = PARAMS.with_sleet(sleet)
    obs, nxt = observe(s, params), next_obs_sample(jax.random.split(key, N), s, params)[0]
    v = speed_grid()
    density = np.exp(np.asarray(log_probs(obs, nxt, jnp.asarray(v, jnp.float32), params), np.float64))
    # over the realised deceleration d = (25 − v') / 1 s, dd = dv'
    assert np.trapezoid(density, v) == pytest.approx(1.0, abs=2e-3)
    # and nowhere else: a braking step that ends faster than it started, or below what μ = 1 gives, is impossible
    outside = jnp.asarray([25.5, 19.0, float(braked_speed(25.0, 20.0, 1.0)) - 0.05], jnp.float32)
    assert np.all(np.isneginf(np.asarray(log_probs(obs, nxt, outside, params))))


@pytest.mark.parametrize("sleet", [0.0, 1.0])
def test_the_density_matches_the_steps_samples(key, sleet):
    s = braking_state(key)
    params = PARAMS.with_sleet(sleet)
    n = N
    sampled = next_obs_sample(jax.random.split(key, n), s, params)
    samples = np.sort(np.asarray(sampled[:, SPEED], np.float64)) * 30
    obs, nxt = observe(s, params), sampled[0]
    v = speed_grid()
    density = np.exp(np.asarray(log_probs(obs, nxt, jnp.asarray(v, jnp.float32), params), np.float64))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(v))])
    model = np.interp(samples, v, cdf)
    ks = np.max(np.abs(model - np.arange(1, n + 1) / n))
    assert ks < 1.63 / np.sqrt(n) + 2e-3  # the 1 % Kolmogorov–Smirnov bound, plus the quadrature's error


def test_the_factor_is_recovered_from_the_speed():
    mu = jnp.linspace(0.01, 0.99, 99)
    back, _ = factor_of_speed(25.0, 20.0, braked_speed(25.0, 20.0, mu))
    assert np.allclose(np.asarray(back), np.asarray(mu), atol=2e-4)
    assert K == pytest.approx(1 / 9)


def test_sleet_lowers_and_spreads_the_braking_factor():
    grip = Grip()
    stats = np.array([[float(x) for x in factor_mean_std(s, grip)] for s in (0.0, 0.25, 0.5, 0.75, 1.0)])
    assert np.all(np.diff(stats[:, 0]) < 0) and np.all(np.diff(stats[:, 1]) > 0)
    assert stats[0] == pytest.approx([0.95, 0.0217], abs=1e-3) and stats[-1] == pytest.approx([0.40, 0.185], abs=1e-3)


def test_a_dry_road_belief_finds_sleety_braking_unlikely_but_possible(key):
    """The availability bias (§4.4.2): the person's dry-road belief scores a weak brake far below the truth."""
    s = braking_state(key)
    truth, dry = PARAMS, PARAMS.with_sleet(0.0)
    obs = observe(s, truth)
    nxt = next_obs_sample(jax.random.split(key, N), s, truth)[:64]
    lp_true = np.asarray(jax.vmap(log_prob, (None, None, 0, None))(obs, jnp.int32(SLOWER), nxt, truth))
    lp_dry = np.asarray(jax.vmap(log_prob, (None, None, 0, None))(obs, jnp.int32(SLOWER), nxt, dry))
    assert np.all(np.isfinite(lp_true)) and np.all(np.isfinite(lp_dry))
    assert np.median(lp_true - lp_dry) > 20.0
    assert float(log_prob_factor(0.4, 1.0, Grip()) - log_prob_factor(0.4, 0.0, Grip())) > 20.0


def test_the_front_cars_onset_has_the_uniform_hazard(key):
    p = make_params(brake_window=(2, 5))
    s = reset(key, p)
    for t, hazard in [(0, 0.0), (1, 0.0), (2, 1 / 4), (3, 1 / 3), (4, 1 / 2), (5, 1.0)]:
        here = observe(s._replace(t=jnp.int32(t)), p)
        after = observe(step(key, s._replace(t=jnp.int32(t)), jnp.int32(IDLE), p).state, p)
        on, off = after.at[7].set(1.0), after.at[7].set(0.0)
        p_on, p_off = (float(jnp.exp(log_prob(here, IDLE, o, p))) for o in (on, off))
        assert p_on == pytest.approx(hazard, abs=1e-6) and p_on + p_off == pytest.approx(1.0, abs=1e-6)
    braking = observe(s._replace(braking=jnp.asarray(True)), p)
    assert float(log_prob(braking, IDLE, braking.at[7].set(0.0), p)) == -np.inf  # brake lights do not go off


def test_steps_that_do_not_brake_or_have_ended_are_deterministic(key):
    s = reset(key, PARAMS)._replace(t=jnp.int32(3), braking=jnp.asarray(True))
    obs = observe(s, PARAMS)
    nxt = observe(step(key, s, jnp.int32(IDLE), PARAMS).state, PARAMS)  # cruising at the target speed: no braking
    assert float(log_prob(obs, IDLE, nxt, PARAMS)) == 0.0
    done = obs.at[6].set(1.0)
    assert float(log_prob(done, SLOWER, done, PARAMS)) == 0.0
