"""The driving scenario in JAX (§4.4.2): the interface, the episode, braking on a dry and a sleety road, r_A."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.driving import (
    DRIVING_ENV,
    STUDY_IMPORTANCE,
    importance_weights,
    make_params,
    make_world,
    observe,
    reset,
    step,
)
from mindgap.envs.driving.kinematics import apply_meta_action
from mindgap.envs.driving.params import (
    DT,
    FASTER,
    IDLE,
    KP_A,
    LANE_LEFT,
    LANE_RIGHT,
    LENGTH,
    SLOWER,
    SUBSTEPS,
    TARGET_SPEEDS,
)
from mindgap.envs.interface import Discrete, EnvError, check_env
from mindgap.envs.resolve import check_world, resolve_env

step_jit = jax.jit(step)


def test_the_world_follows_the_interface(key):
    world = make_world()
    check_world(world, "driving")  # the checks every --env world passes
    check_env(world.env, continuous_actions=False, density=True, who="driving")
    assert world.env.action_space == Discrete(5) and world.env.observation_space.dim == 11
    assert world.horizon == 15 and float(world.belief("dry").sleet) == 0.0 and float(world.params.sleet) == 1.0
    s = world.env.reset(key, world.params)
    out = step_jit(key, s, jnp.int32(IDLE), world.params)
    assert jax.tree.structure(out.state) == jax.tree.structure(s) and out.reward.shape == ()
    obs = world.env.observe(s, world.params)
    assert obs.shape == (11,) and obs.dtype == jnp.float32
    # the units: lane 1's centre, 25 m/s, the front car 35 m ahead (30 m gap + one car length)
    assert np.allclose(
        np.asarray(obs)[[0, 2, 3, 4, 8, 9, 10]], [1.0, 25 / 30, 1.0, 25 / 30, (42.5 + 5) / 100, 1.0, 25 / 30]
    )
    assert world.obs_units().shape == (11,) and world.trace(obs[None]).shape == (1, 2)
    assert make_world(traffic=2).env.observation_space.dim == 17
    assert make_world().env == DRIVING_ENV  # one Env object: learners compile once for every sleet level


def test_the_env_spec_reaches_the_factory():
    world = resolve_env("mindgap.envs.driving:make_world,sleet=0.25,traffic=2,brake_first=3")
    assert float(world.params.sleet) == 0.25 and world.params.n_traffic == 2 and int(world.params.brake_first) == 3
    assert world.name == "driving,brake_first=3,sleet=0.25,traffic=2" and make_world().name == "driving"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"sleet": 1.5}, "sleet must be in [0, 1] (0 a dry road, 1 full sleet), got 1.5"),
        ({"sleet": -0.1}, "sleet must be in [0, 1]"),
        ({"lanes": 1}, "lanes must be at least 2"),
        ({"start_lane": 3}, "start_lane must be in 0 … 2"),
        ({"brake_first": 5, "brake_last": 2}, "brake_window must satisfy"),
        ({"traffic": 9}, "traffic must be in 0 … 4"),
        ({"weights": [1.0, 2.0]}, "weights must hold 4 numbers"),
    ],
)
def test_bad_scenarios_get_one_line(kwargs, message):
    with pytest.raises(ValueError, match=None) as e:
        make_world(**kwargs)
    assert message in str(e.value) and len(str(e.value).splitlines()) == 1


def test_a_bad_sleet_level_from_the_command_line_is_one_line():
    with pytest.raises(EnvError) as e:
        resolve_env("mindgap.envs.driving:make_world,sleet=2")
    assert "sleet must be in [0, 1]" in str(e.value) and len(str(e.value).splitlines()) == 1
    with pytest.raises(ValueError, match="sleet must be in"):
        make_params().with_sleet(1.01)


def test_meta_actions_follow_highway_env():
    ts = jnp.asarray(TARGET_SPEEDS)

    def act(a, speed=25.0, target_speed=25.0, lane=1, y=4.0):
        lane, v = apply_meta_action(jnp.int32(a), jnp.float32(y), jnp.float32(speed), lane, target_speed, 3, ts)
        return int(lane), float(v)

    assert act(IDLE) == (1, 25.0) and act(FASTER) == (1, 30.0) and act(SLOWER) == (1, 20.0)
    assert act(LANE_LEFT) == (0, 25.0) and act(LANE_RIGHT) == (2, 25.0)
    assert act(LANE_LEFT, lane=0, y=0.0) == (0, 25.0) and act(LANE_RIGHT, lane=2, y=8.0) == (2, 25.0)
    assert act(FASTER, speed=30.0) == (1, 30.0) and act(SLOWER, speed=0.2, target_speed=0.0) == (1, 0.0)
    # SLOWER steps down from the target nearest the *current* speed, so braking can go on below the road speed
    assert act(SLOWER, speed=16.2, target_speed=15.0) == (1, 10.0) and act(FASTER, speed=16.2) == (1, 20.0)


def test_a_finished_episode_stays_put(key):
    p = make_params(sleet=1.0, brake_window=(0, 0), gap=1.0)
    out = step_jit(key, reset(key, p), jnp.int32(FASTER), p)  # speeding up 1 m behind a car that brakes: a collision
    assert bool(out.terminated) and not bool(out.truncated) and float(out.reward) == -5.0
    again = step_jit(key, out.state, jnp.int32(LANE_LEFT), p)
    assert float(again.reward) == 0.0 and not bool(again.terminated) and not bool(again.truncated)
    assert all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(again.state), jax.tree.leaves(out.state)))


def test_the_last_decision_ends_the_task(key):
    """The horizon is terminal, not a truncation: the observation carries the time, so nothing is
    bootstrapped past the clip's last decision (world.py's module docstring)."""
    p = make_params(sleet=0.0)
    s = reset(key, p)
    for t in range(int(p.horizon)):
        out = step_jit(jax.random.fold_in(key, t), s, jnp.int32(SLOWER), p)
        last = t == int(p.horizon) - 1
        assert bool(out.terminated) == last and not bool(out.truncated) and not bool(out.state.crashed), t
        s = out.state
    assert float(observe(s, p)[5]) == 1.0


N = 512
"""Episodes per batch: every test runs batches of this size, so the batch compiles once."""


@jax.jit
def episodes(keys, params, policy):
    """Per key, an episode of 15 decisions taking ``policy`` until the front car brakes and ``react`` after:
    where the ego comes to a stop (x [m]; inf if it does not), whether it crashed, the decision at which the front
    car started braking. ``policy = (before, after)``."""

    def one(k):
        s = reset(k, params)

        def body(c, kk):
            s, stop, first = c
            n = step(kk, s, jnp.where(s.braking, policy[1], policy[0]), params).state
            stop = jnp.where(jnp.isinf(stop) & (n.speed < 0.5), n.x, stop)
            first = jnp.where((first < 0) & n.braking, s.t, first)
            return (n, stop, first), None

        (s, stop, first), _ = jax.lax.scan(body, (s, jnp.float32(jnp.inf), jnp.int32(-1)), jax.random.split(k, 15))
        return stop, s.crashed, first

    return jax.vmap(one)(keys)


def kinematic_stop(v0: float, mu: float, steps: int = 15) -> float:
    """Where highway-env's controller, braking at ``mu`` times its command and stepping its target speed down
    at every decision, stops (speed < 0.5 m/s): the model integrated step by step in float64."""
    ts, x, v = np.asarray(TARGET_SPEEDS), 0.0, v0
    for _ in range(steps):
        idx = int(np.clip(np.round((v - ts[0]) / (ts[-1] - ts[0]) * (len(ts) - 1)), 0, len(ts) - 1))
        target = ts[max(idx - 1, 0)]
        gain = mu if v - target > 0.05 else 1.0
        for _ in range(SUBSTEPS):
            x, v = x + v * DT, v + gain * KP_A * (target - v) * DT
            if v < 0.5:
                return x
    return np.inf


def test_braking_on_a_dry_road_stops_within_the_kinematic_distance_and_sleet_lengthens_and_spreads_it(key):
    """A car alone on the road (the front car far ahead) brakes from 25 m/s at every decision, 512 seeds."""
    keys = jax.random.split(key, N)
    far = dict(gap=1000.0, brake_window=(14, 14))
    always = jnp.array([SLOWER, SLOWER])
    dry, _, _ = episodes(keys, make_params(sleet=0.0, **far), always)
    wet, _, _ = episodes(keys, make_params(sleet=1.0, **far), always)
    dry, wet = np.asarray(dry), np.asarray(wet)
    ideal, poor = kinematic_stop(25.0, 1.0), kinematic_stop(25.0, 0.85)
    assert 50 < ideal < 80  # ≈ 5 m/s² on average, as the 5 m/s steps of a τ = 0.6 s controller give
    # a dry road's braking factor is 0.95 ± 0.02: every stop lies between the ideal one and one at 85 %
    assert np.all(np.isfinite(dry)) and np.all(dry >= ideal - 0.05) and np.all(dry <= poor)
    assert np.isfinite(wet).mean() > 0.9  # sleet still stops most cars within the 15 s
    wet = wet[np.isfinite(wet)]
    assert wet.mean() > 1.5 * dry.mean()  # braking at 0.40 ± 0.19 of its command: much longer …
    assert wet.std() > 10 * dry.std() and wet.std() > 10.0  # … and much less predictable


def test_the_scenario_is_safe_to_brake_in_on_a_dry_road_and_not_on_sleet(key):
    """Braking as soon as the front car's brake lights show: no collision on a dry road, mostly one on sleet,
    none when changing lane instead."""

    def react(params, react_with):
        return np.asarray(episodes(jax.random.split(key, N), params, jnp.array([IDLE, react_with]))[1])

    p = make_params()
    assert react(p.with_sleet(0.0), SLOWER).mean() == 0.0
    assert react(p.with_sleet(1.0), SLOWER).mean() > 0.9
    assert react(p.with_sleet(1.0), LANE_LEFT).mean() == 0.0


def test_the_front_car_brakes_at_a_uniform_moment(key):
    far = make_params(sleet=0.0, gap=1000.0, brake_window=(2, 5))
    first = [episodes(k, far, jnp.array([IDLE, IDLE]))[2] for k in jax.random.split(key, (8, N))]
    counts = np.bincount(np.concatenate(first), minlength=7)
    assert counts[:2].sum() == 0 and counts[6:].sum() == 0
    assert np.all(np.abs(counts[2:6] / (8 * N) - 0.25) < 0.03)  # 4.4 standard errors


def test_rewards_follow_the_features_and_a_collision_costs_the_penalty(key):
    p = make_params(gap=30.0)
    s = reset(key, p)
    obs = observe(s, p)
    w = np.asarray(p.rewards.weights)
    r = float(DRIVING_ENV.reward(obs, IDLE, obs, p))
    # at the start: 25 of 30 m/s; a 30 m gap of the desired 5 + 1.5·25 m; the same speed as the front car; centred
    assert r == pytest.approx(w @ [25 / 30, 30 / 42.5, 1.0, 1.0], abs=1e-5)
    # by default the cars start at the desired gap: steady following, the front-distance feature whole
    d = make_params()
    start = observe(reset(key, d), d)
    assert float(d.gap) == pytest.approx(42.5)
    assert float(DRIVING_ENV.reward(start, IDLE, start, d)) == pytest.approx(w @ [25 / 30, 1.0, 1.0, 1.0], abs=1e-5)
    halfway = s._replace(y=jnp.float32(6.0), others_speed=jnp.asarray([15.0]))
    r2 = float(DRIVING_ENV.reward(obs, IDLE, observe(halfway, p), p))
    # half a lane over: lane 2 by rounding (no car ahead there), on no centre line, 10 m/s faster than the neighbour
    assert r2 == pytest.approx(w @ [25 / 30, 1.0, 0.0, 0.0], abs=1e-5)
    crashed = observe(s._replace(crashed=jnp.asarray(True)), p)
    assert float(DRIVING_ENV.reward(obs, IDLE, crashed, p)) == -5.0


def test_importance_ratings_map_to_weights():
    w = importance_weights(STUDY_IMPORTANCE)
    assert w.sum() == pytest.approx(1.0) and np.argmax(w) == 1  # the distance to the front car weighs most
    assert np.allclose(w, np.asarray(STUDY_IMPORTANCE) / sum(STUDY_IMPORTANCE))
    assert np.allclose(importance_weights([5, 5, 5, 5]), importance_weights([1, 1, 1, 1]))
    batch = importance_weights(np.array([[1, 2, 3, 4], [5, 5, 1, 1]]))
    assert batch.shape == (2, 4) and np.allclose(batch.sum(-1), 1.0)
    p = make_params(weights=importance_weights([1, 5, 1, 1]))
    assert float(p.rewards.weights[1]) == pytest.approx(5 / 8)


@pytest.mark.parametrize(
    "ratings, message",
    [
        ([0, 3, 3, 3], "importance ratings must be in [1, 5] (1 NOT care … 5 Strongly care), got 0"),
        ([3, 3, 3, 6], "got 6"),
        ([3, 3, np.nan, 3], "got nan"),
        ([3, 3, 3], "importance must hold 4 ratings"),
    ],
)
def test_importance_out_of_range_is_one_line(ratings, message):
    with pytest.raises(ValueError) as e:
        importance_weights(ratings)
    assert message in str(e.value) and len(str(e.value).splitlines()) == 1


def test_steps_vmap_over_worlds_and_beliefs(key):
    p = make_params(traffic=4)
    beliefs = jax.tree.map(lambda *x: jnp.stack(x), p.with_sleet(0.0), p.with_sleet(0.5), p)
    keys = jax.random.split(key, 3)
    states = jax.vmap(reset)(keys, beliefs)
    out = jax.jit(jax.vmap(step))(keys, states, jnp.full(3, SLOWER, jnp.int32), beliefs)
    assert out.state.others_x.shape == (3, 5) and out.reward.shape == (3,)
    gaps = np.asarray(out.state.others_x - out.state.x[:, None])[:, 1:]
    assert np.all(np.abs(gaps) > LENGTH)  # the traffic is in the other lanes, away from the ego
