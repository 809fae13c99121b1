"""The MJX hopper and cheetah: the world interface, the same simulation as gymnasium's, the noise and its density.

Tolerances of the comparisons with gymnasium. MuJoCo's C engine (gymnasium) runs in float64;
run in float64 too (``jax.enable_x64``), MJX on the same model file and options repeats its
first step to 1e-15, and the contact dynamics amplify such differences about tenfold every
five steps (1e-10 after 20 cheetah steps, 1e-6 after 50, measured), so 25 steps agree within
1e-8. In float32, the worlds' default, a step's rounding (1e-7 relative) grows the same
way: 1e-4 after 5 steps measured, so the check there is 1e-3 over 5 steps. The hopper of the
quick tests runs the ``euler`` options (it compiles in a quarter of the time of RK4); its
gymnasium env is given the same options, so the comparison is still code path against code path.
"""

import re

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.scipy.stats import norm

from mindgap.data.fingerprint import fingerprint
from mindgap.envs import mjx_model
from mindgap.envs.interface import EnvError
from mindgap.envs.mjx_locomotion import BODIES, MjxState, MjxWorld, mjx_world
from mindgap.envs.resolve import check_world, resolve_env

QUICK = {"cheetah": "fast", "hopper": "euler"}  # the solver options of the quick tests (module docstring)


def actions(n, dim, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (n, dim)).astype(np.float32)


def gymnasium_rollout(body, solver, acts, seed):
    """gymnasium's env of ``body`` with the world's solver options, reset with ``seed`` and stepped with ``acts``
    until it terminates: (its state after reset as an MjxState, observations [T+1, d], rewards [T], terminated [T])."""
    env = gymnasium.make(BODIES[body].gym_id, exclude_current_positions_from_observation=False).unwrapped
    mine = mjx_model.load_model(body, solver)
    opt = env.model.opt
    opt.iterations, opt.ls_iterations, opt.integrator = mine.opt.iterations, mine.opt.ls_iterations, mine.opt.integrator
    obs = [env.reset(seed=seed)[0]]
    d = env.data
    f = jnp.zeros(()).dtype
    state = MjxState(*(jnp.asarray(x.copy(), f) for x in (d.qpos, d.qvel, d.qacc_warmstart)), jnp.zeros((), jnp.int32))
    rewards, ends = [], []
    for a in acts:
        o, r, term, _, _ = env.step(a)
        obs.append(o), rewards.append(r), ends.append(term)
        if term:
            break
    env.close()
    return state, np.stack(obs), np.asarray(rewards), np.asarray(ends)


def mjx_rollout(world, state, acts):
    """The world's observations [T+1, d], step rewards [T] and terminations [T] from ``state`` on ``acts`` (jitted)."""
    env, p = world.env, world.params

    def body(s, a):
        out = env.step(jax.random.key(0), s, a, p)
        return out.state, (env.observe(out.state, p), out.reward, out.terminated)

    _, (obs, rew, term) = jax.jit(lambda s, acts: jax.lax.scan(body, s, acts))(state, jnp.asarray(acts))
    return np.concatenate([np.asarray(env.observe(state, p))[None], np.asarray(obs)]), np.asarray(rew), np.asarray(term)


@pytest.mark.parametrize("body, obs_dim, act_dim", [("hopper", 12, 3), ("cheetah", 18, 6)])
def test_the_worlds_follow_the_interface(body, obs_dim, act_dim):
    world = resolve_env(f"mjx:{body},share=0.1")
    check_world(world, world.name)  # spaces, shapes, the step's structure (traced, not run)
    assert isinstance(world, MjxWorld) and world.name == f"mjx:{body},share=0.1"
    assert world.env.observation_space.dim == obs_dim and world.env.action_space.shape == (act_dim,)
    assert (world.env.action_space.low, world.env.action_space.high) == (-1.0, 1.0)
    assert world.env.reward is not None and world.env.log_prob is not None  # a person can score it exactly
    assert float(world.params["share"]) == pytest.approx(0.1) and float(world.belief("reliable")["share"]) == 0.0
    assert world.horizon == 1000 and resolve_env(f"mjx:{body},horizon=50").horizon == 50


@pytest.mark.parametrize("body", ["cheetah", "hopper"])
def test_in_float64_it_is_gymnasium_s_trajectory_and_reward(body):
    with jax.enable_x64(True):
        world = mjx_world(body, share=0.0, solver=QUICK[body])
        acts = actions(25, world.env.action_space.dim, seed=3)
        for seed in (0, 1):
            state, g_obs, g_rew, g_end = gymnasium_rollout(body, QUICK[body], acts, seed)
            obs, rew, end = mjx_rollout(world, state, acts[: len(g_rew)])
            np.testing.assert_allclose(obs, g_obs, rtol=0, atol=1e-8)
            np.testing.assert_allclose(rew, g_rew, rtol=1e-6, atol=1e-6)  # the reward's weights are float32
            np.testing.assert_array_equal(end, g_end)
            person = jax.vmap(world.env.reward, (0, 0, 0, None))(obs[:-1], acts[: len(rew)], obs[1:], world.params)
            np.testing.assert_allclose(person, g_rew, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("body", ["cheetah", "hopper"])
def test_in_float32_it_stays_within_rounding_of_gymnasium(body):
    world = mjx_world(body, share=0.0, solver=QUICK[body])
    acts = actions(5, world.env.action_space.dim, seed=4)
    state, g_obs, g_rew, _ = gymnasium_rollout(body, QUICK[body], acts, seed=2)
    obs, rew, _ = mjx_rollout(world, state, acts[: len(g_rew)])
    assert obs.dtype == np.float32
    np.testing.assert_allclose(obs, g_obs, rtol=0, atol=1e-3)
    np.testing.assert_allclose(rew, g_rew, rtol=1e-3, atol=1e-3)


@pytest.fixture(scope="module")
def one_step_many_keys():
    """The cheetah's first step from one reset state, with 2000 keys, with and without the noise."""
    world = mjx_world("cheetah")
    env, p = world.env, world.params
    state = env.reset(jax.random.key(1), p)
    act = jnp.asarray(actions(1, 6, seed=5)[0])
    keys = jax.random.split(jax.random.key(2), 2000)
    step = jax.jit(jax.vmap(lambda k, q: env.step(k, state, act, q).state, (0, None)))
    noisy, calm = step(keys, p), step(keys, world.belief("reliable"))
    return world, state, act, noisy, calm


def test_the_noise_perturbs_a_share_of_steps_velocities_by_the_stated_scale(one_step_many_keys):
    world, _, _, noisy, calm = one_step_many_keys
    np.testing.assert_array_equal(noisy.qpos, calm.qpos)  # positions: never
    np.testing.assert_array_equal(calm.qvel, np.broadcast_to(calm.qvel[0], calm.qvel.shape))  # no noise: one outcome
    gap = np.asarray(noisy.qvel - calm.qvel)
    hit = np.any(gap != 0, axis=1)
    assert abs(hit.mean() - 0.2) < 0.04  # 2000 draws: 4.5 binomial standard deviations
    eps = gap[hit].ravel()  # ~3,600 draws of N(0, 0.5²)
    assert abs(eps.mean()) < 0.03 and abs(eps.std() - 0.5) < 0.03


def test_log_prob_is_the_atom_or_the_gaussian(one_step_many_keys):
    world, state, act, noisy, calm = one_step_many_keys
    env, p, reliable = world.env, world.params, world.belief("reliable")
    obs = env.observe(state, p)
    nxt = jax.vmap(env.observe, (0, None))(noisy, p)
    hit = np.any(np.asarray(noisy.qvel != calm.qvel), axis=1)
    score = jax.jit(jax.vmap(env.log_prob, (None, None, 0, None)))
    true_lp, belief_lp = np.asarray(score(obs, act, nxt, p)), np.asarray(score(obs, act, nxt, reliable))
    np.testing.assert_allclose(true_lp[~hit], np.log(0.8), rtol=1e-6)
    gauss = np.log(0.2) + norm.logpdf(noisy.qvel[hit] - calm.qvel[hit], 0.0, 0.5).sum(-1)
    np.testing.assert_allclose(true_lp[hit], gauss, rtol=1e-4, atol=1e-3)
    # the reliable person: what happened as the physics says is sure, any perturbed step impossible
    assert np.all(belief_lp[~hit] == 0.0) and np.all(np.isneginf(belief_lp[hit]))
    moved = np.asarray(nxt[0]).copy()
    moved[0] += 0.01  # a position the noise never moves
    assert np.isneginf(float(env.log_prob(obs, act, jnp.asarray(moved), p)))


def test_seeds_vmap_into_one_program_and_each_is_its_own_run():
    world = mjx_world("cheetah", horizon=8)
    env, p = world.env, world.params

    def run(key):
        k0, k1 = jax.random.split(key)
        acts = jax.random.uniform(k1, (8, 6), minval=-1.0, maxval=1.0)

        def body(s, xs):
            k, a = xs
            out = env.step(k, s, a, p)
            return out.state, (env.observe(out.state, p), out.truncated)

        return jax.lax.scan(body, env.reset(k0, p), (jax.random.split(k1, 8), acts))[1]

    keys = jax.random.split(jax.random.key(3), 3)
    seeds = jax.jit(jax.vmap(run))
    obs, trunc = seeds(keys)
    assert obs.shape == (3, 8, 18) and np.all(np.isfinite(obs))
    assert trunc[:, -1].all() and not trunc[:, :-1].any()  # the horizon ends every episode at step 8
    assert np.abs(obs[0] - obs[1]).max() > 1e-2  # seeds start and go their own ways
    # a seed's run does not depend on its neighbours: the same keys in another order, the same runs
    again, _ = seeds(keys[jnp.array([2, 0, 1])])
    np.testing.assert_array_equal(again, obs[jnp.array([2, 0, 1])])


def test_the_solver_options_are_part_of_the_world_s_identity():
    fast, gym = mjx_world("cheetah"), mjx_world("cheetah", solver="gym")
    assert fast.name == "mjx:cheetah" and gym.name == "mjx:cheetah,solver=gym"
    assert fingerprint(fast.fingerprint_tree()) != fingerprint(gym.fingerprint_tree())
    assert fingerprint(fast.fingerprint_tree()) == fingerprint(mjx_world("cheetah").fingerprint_tree())
    assert mjx_model.load_model("cheetah", "fast").opt.iterations == 4
    assert mjx_model.load_model("cheetah", "gym").opt.iterations == 100  # the model file's (MuJoCo's default)


@pytest.mark.parametrize(
    "spec, problem",
    [
        ("mjx:dog", "expected mjx:BODY with BODY one of hopper, cheetah"),
        ("mjx:hopper,share=2.0", "share must be in [0, 1]"),
        ("mjx:hopper,scale=0.001", "scale must be 0 or at least 0.01"),
        ("mjx:cheetah,solver=rk9", "no solver options 'rk9'"),
        ("mjx:cheetah,horizon=0", "horizon must be a positive integer"),
        ("mjx:cheetah,gravity=3", "unknown argument(s) gravity"),
    ],
)
def test_bad_specs_are_one_line(spec, problem):
    with pytest.raises(EnvError, match=re.escape(problem)):
        resolve_env(spec)


def test_without_mjx_the_error_names_the_extra(monkeypatch):
    import sys

    import mujoco

    monkeypatch.delattr(mujoco, "mjx", raising=False)
    monkeypatch.setitem(sys.modules, "mujoco.mjx", None)  # an import of it now fails
    with pytest.raises(EnvError, match=re.escape("pip install 'mindgap[gym]'")):
        mjx_model.mjx()


@pytest.mark.slow
@pytest.mark.parametrize("body", ["cheetah", "hopper"])
def test_gymnasium_s_own_options_simulate_the_same_trajectory(body):
    """With ``solver="gym"`` against gymnasium's env as it is (RK4 and 100 iterations for the hopper):
    25–45 s each on two busy CPU cores, most of it compiling."""
    with jax.enable_x64(True):
        world = mjx_world(body, share=0.0, solver="gym")
        acts = actions(25, world.env.action_space.dim, seed=6)
        state, g_obs, g_rew, g_end = gymnasium_rollout(body, "gym", acts, seed=0)
        obs, rew, end = mjx_rollout(world, state, acts[: len(g_rew)])
        np.testing.assert_allclose(obs, g_obs, rtol=0, atol=1e-8)
        np.testing.assert_allclose(rew, g_rew, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(end, g_end)


@pytest.mark.slow
def test_the_default_hopper_is_gymnasium_s_trajectory_in_float64():
    """The default ``fast`` options with RK4: about 40 s on two busy CPU cores, most of it compiling."""
    with jax.enable_x64(True):
        world = mjx_world("hopper", share=0.0)
        acts = actions(25, 3, seed=7)
        state, g_obs, g_rew, g_end = gymnasium_rollout("hopper", "fast", acts, seed=1)
        obs, _, end = mjx_rollout(world, state, acts[: len(g_rew)])
        np.testing.assert_allclose(obs, g_obs, rtol=0, atol=1e-8)
        np.testing.assert_array_equal(end, g_end)


@pytest.mark.slow
def test_prefbias_runs_on_the_mjx_cheetah_with_the_reliable_person(tmp_path):
    """The whole PbRL loop jitted on an MJX world, the person scoring with its exact log_prob: about 4.5 min on
    two busy CPU cores, most of it compiling."""
    import json

    from mindgap.cli import main

    out = tmp_path / "prefbias"
    argv = ["prefbias", "--env", "mjx:cheetah,horizon=50", "--fast", "--absorbing-state", "single", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["queries"] == 30 and np.isfinite(summary["final_return_mean"])
