"""The JAX driving world against the same scenario in highway-env, and highway-env's pictures of it.

Tolerance of the agreement test: the JAX world integrates in float32, highway-env in float64,
over 15 decisions of 15 Euler steps. A position near 400 m has a float32 spacing of 3·10⁻⁵ m,
so 225 rounded additions drift by at most ~7·10⁻³ m (about 10⁻³ in practice); speeds (≤ 30 m/s,
spacing 2·10⁻⁶) and headings stay within 10⁻³ m/s and 10⁻⁴ rad. Anything beyond 10⁻² m is a
difference in the model, not in the arithmetic. Named differences (by design, see
``mindgap.envs.driving.world``): after a collision highway-env brakes and pushes the cars apart
while the JAX world ends the episode, so trajectories are compared up to the first collision,
which both must see at the same decision or highway-env one decision later.
"""

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest

highway_env = pytest.importorskip("highway_env", reason="highway-env is part of the test extra (mindgap[driving])")

from highway_env import utils  # noqa: E402
from highway_env.envs.common.abstract import AbstractEnv  # noqa: E402
from highway_env.envs.common.action import DiscreteMetaAction  # noqa: E402
from highway_env.road.lane import AbstractLane  # noqa: E402
from highway_env.vehicle.behavior import IDMVehicle  # noqa: E402
from highway_env.vehicle.controller import ControlledVehicle  # noqa: E402
from highway_env.vehicle.kinematics import Vehicle  # noqa: E402

from mindgap.envs.driving import advance, make_params, observe, reset  # noqa: E402
from mindgap.envs.driving import params as P  # noqa: E402
from mindgap.envs.driving.highway import ENV_ID, START_X, SleetHighwayEnv, register, save_animation  # noqa: E402
from mindgap.envs.driving.kinematics import will_collide  # noqa: E402
from mindgap.envs.driving.world import reward  # noqa: E402
from mindgap.envs.interface import EnvError  # noqa: E402
from mindgap.envs.resolve import resolve_env  # noqa: E402

POS_TOL, SPEED_TOL, HEADING_TOL = 1e-2, 1e-3, 1e-4


def test_the_constants_are_highway_envs():
    assert (P.LENGTH, P.WIDTH, P.MAX_SPEED, P.MIN_SPEED) == (
        Vehicle.LENGTH,
        Vehicle.WIDTH,
        Vehicle.MAX_SPEED,
        Vehicle.MIN_SPEED,
    )
    cv = ControlledVehicle
    assert (P.TAU_ACC, P.TAU_HEADING, P.TAU_LATERAL) == (cv.TAU_ACC, cv.TAU_HEADING, cv.TAU_LATERAL)
    assert (P.KP_A, P.KP_HEADING, P.KP_LATERAL, P.MAX_STEERING_ANGLE) == pytest.approx(
        (cv.KP_A, cv.KP_HEADING, cv.KP_LATERAL, cv.MAX_STEERING_ANGLE)
    )
    assert P.LANE_WIDTH == AbstractLane.DEFAULT_WIDTH
    cfg = AbstractEnv.default_config()
    assert (P.POLICY_FREQUENCY, P.SIMULATION_FREQUENCY) == (cfg["policy_frequency"], cfg["simulation_frequency"])
    assert P.ACTIONS == tuple(DiscreteMetaAction.ACTIONS_ALL[i] for i in range(5))
    # r_A's desired gap is IDM's (5 m beyond a car length, 1.5 s)
    rw = make_params().rewards
    assert (float(rw.standstill) + P.LENGTH, float(rw.headway)) == (IDMVehicle.DISTANCE_WANTED, IDMVehicle.TIME_WANTED)


L, I, R, F, S = range(5)  # noqa: E741 - the meta-actions' initials
SCRIPTS = {
    "brake to a stop behind the front car": [I, S, S, S, S, S, I, I, I, I, I, I, I, I, I],
    "brake, then change lane and pass": [I, I, L, I, S, S, I, F, F, I, I, R, R, S, I],
    "weave, turning back halfway": [R, F, I, S, F, L, I, L, R, I, F, F, I, L, I],
}


@jax.jit
def _advance(state, action, mu, onset, params):
    return advance(state, action, mu, onset, params)


def _both(actions, params, grips, onset, seed=0, **env_kwargs):
    """Drive both versions through ``actions`` with the same draws; per decision, (x, y, heading, speed) of the
    ego, the observation and the reward of each, and whether it crashed, up to the first collision."""
    s = reset(jax.random.key(seed), params)
    env = SleetHighwayEnv(sleet=float(params.sleet), traffic=params.n_traffic, **env_kwargs)
    options = {"grip": grips, "onset": onset, "traffic_dx": np.asarray(s.others_x[1:])}
    obs_hw, _ = env.reset(seed=seed, options=options)
    assert np.allclose(obs_hw, np.asarray(observe(s, params)), atol=1e-6)
    out = []
    for k, (a, mu) in enumerate(zip(actions, grips)):
        nxt = _advance(s, jnp.int32(a), jnp.float32(mu), jnp.asarray(k >= onset), params)
        r_jax = float(reward(observe(s, params), a, observe(nxt, params), params))
        obs_hw, r_hw, ended_hw, truncated_hw, _ = env.step(a)
        crashed_hw = env.vehicle.crashed
        # the horizon ends the task in both versions (world.py, "The horizon is terminal")
        assert ended_hw == (crashed_hw or k == len(actions) - 1) and not truncated_hw, k
        s = nxt
        jax_ego = np.array([float(s.x), float(s.y), float(s.heading), float(s.speed)])
        out.append((jax_ego, env.ego_state(), np.asarray(observe(s, params)), obs_hw, r_jax, r_hw))
        if bool(s.crashed) or crashed_hw:
            if not crashed_hw:  # highway-env marks the car crashed one integration step after its test fires
                env.step(I)
                crashed_hw = env.vehicle.crashed
            assert bool(s.crashed) and crashed_hw, f"only one version collided at decision {k}"
            out.pop()  # the collision's own step: positions differ by design
            break
    env.close()
    return out


def _check_agreement(rows):
    for k, (jax_ego, hw_ego, obs_jax, obs_hw, r_jax, r_hw) in enumerate(rows):
        err = np.abs(jax_ego - hw_ego)
        assert err[:2].max() < POS_TOL and err[2] < HEADING_TOL and err[3] < SPEED_TOL, (k, jax_ego, hw_ego)
        # the observations, scaled: every car's position and speed, the set-points, time, flags
        assert np.allclose(obs_jax, obs_hw, atol=POS_TOL / 100), (k, obs_jax - obs_hw)
        assert r_jax == pytest.approx(r_hw, abs=1e-4), k


@pytest.mark.parametrize("script", list(SCRIPTS))
def test_jax_and_highway_env_agree_on_a_dry_road(script):
    params = make_params(sleet=0.0)
    grips = np.random.default_rng(0).beta(95, 5, 15)  # the dry road's braking factors
    rows = _both(SCRIPTS[script], params, grips, onset=1)
    assert len(rows) == 15  # no collision in these scripts
    _check_agreement(rows)


def test_they_agree_on_random_drives_until_a_collision_and_see_it_at_once():
    rng = np.random.default_rng(1)
    params = make_params(sleet=0.0)
    lengths = []
    for _ in range(4):
        rows = _both(rng.integers(0, 5, 15), params, rng.beta(95, 5, 15), onset=int(rng.integers(1, 5)))
        _check_agreement(rows)
        lengths.append(len(rows))
    assert max(lengths) >= 5


def test_they_agree_with_traffic_and_on_sleet():
    params = make_params(sleet=1.0, traffic=2)
    grips = np.random.default_rng(2).beta(2.4, 3.6, 15)
    rows = _both(SCRIPTS["brake, then change lane and pass"], params, grips, onset=1, seed=3)
    assert len(rows) >= 5
    _check_agreement(rows)


def test_the_collision_test_is_highway_envs():
    rng = np.random.default_rng(0)
    n = 3000
    dx, dy = rng.uniform(-9, 9, n), rng.uniform(-3, 3, n)
    heading, speed, other_speed = rng.uniform(-0.5, 0.5, n), rng.uniform(0, 30, n), rng.uniform(0, 30, n)
    dt = P.DT
    expected = np.array(
        [
            utils.are_polygons_intersecting(
                Vehicle(None, [0.0, 0.0], h, v).polygon(),
                Vehicle(None, [x, y], 0.0, w).polygon(),
                Vehicle(None, [0.0, 0.0], h, v).velocity * dt,
                Vehicle(None, [x, y], 0.0, w).velocity * dt,
            )[1]
            for x, y, h, v, w in zip(dx, dy, heading, speed, other_speed)
        ]
    )
    f = jnp.float32
    got = np.asarray(jax.jit(will_collide)(f(0), f(0), f(heading), f(speed), f(dx), f(dy), f(other_speed)))
    assert 0.2 < expected.mean() < 0.8 and (got != expected).sum() <= 2  # float32 against float64 at the edges


def test_highway_env_draws_the_same_sleet():
    env = SleetHighwayEnv(sleet=1.0, gap=1000.0)  # nothing ahead: brake from 25 m/s, five decisions at a time
    grips = []
    for seed in range(40):
        env.reset(seed=seed)
        grips += [env.step(S)[4]["grip"] for _ in range(5)]
    env.close()
    assert np.mean(grips) == pytest.approx(0.40, abs=0.04) and np.std(grips) == pytest.approx(0.185, abs=0.04)


def _colours(frame):
    return np.unique(frame.reshape(-1, 3), axis=0)


@pytest.mark.parametrize("driver", [None, "dummy"])
def test_frames_show_the_road_and_both_cars(monkeypatch, driver):
    if driver:
        monkeypatch.setenv("SDL_VIDEODRIVER", driver)  # under which highway-env itself would draw nothing
    register()
    env = gymnasium.make(ENV_ID, render_mode="rgb_array", sleet=1.0)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (150, 600, 3) and frame.dtype == np.uint8
    assert len(_colours(frame)) > 3  # not one colour: road, lane marks, cars
    green = np.all(np.abs(frame.astype(int) - (50, 200, 0)) < 10, -1).sum()
    blue = np.all(np.abs(frame.astype(int) - (100, 200, 255)) < 10, -1).sum()
    assert green > 50 and blue > 50  # the ego (green) and the front car (blue) of Fig. 33


def test_an_episode_animates(tmp_path):
    from PIL import Image

    env = SleetHighwayEnv(render_mode="rgb_array", sleet=1.0)
    env.record()
    env.reset(seed=0, options={"onset": 1, "grip": [0.4] * 3})
    for a in (I, S, L):
        env.step(a)
    env.close()
    assert len(env.frames) == 1 + 3 * P.SUBSTEPS
    assert not np.array_equal(env.frames[0], env.frames[-1])
    path = save_animation(env.frames, tmp_path / "episode.gif")
    assert Image.open(path).n_frames == len(env.frames)


def test_it_is_a_gymnasium_env():
    register()
    env = gymnasium.make(ENV_ID, sleet=0.5, traffic=2)
    obs, _ = env.reset(seed=0)
    assert env.action_space == gymnasium.spaces.Discrete(5) and obs.shape == (17,) == env.observation_space.shape
    assert env.observation_space.contains(obs)
    obs, r, term, trunc, info = env.step(1)
    assert np.isfinite(r) and not term and {"grip", "braking"} <= set(info)
    env.close()
    with pytest.raises(ValueError, match=r"sleet must be in \[0, 1\]"):
        gymnasium.make(ENV_ID, sleet=3.0)
    # mindgap's host loop takes it by its gym: spec, and its continuous-action learners refuse it in one line
    with pytest.raises(EnvError, match="Discrete") as e:
        resolve_env(f"gym:{ENV_ID},sleet=0.5")
    assert len(str(e.value).splitlines()) == 1
    assert START_X > 0
