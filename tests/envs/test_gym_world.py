"""gymnasium worlds: the exact reward registry against gymnasium's own rewards, and bad specs."""

import gymnasium
import jax
import numpy as np
import pytest

from mindgap.envs.gym_world import GymWorld
from mindgap.envs.interface import EnvError
from mindgap.envs.resolve import resolve_env


def _transitions(world, n, rng, set_state=None):
    env, obs = world.make(seed=0)
    out = []
    for _ in range(n):
        if set_state is not None:
            env.unwrapped.state = set_state(rng)
            obs = np.asarray(env.unwrapped._get_obs() if hasattr(env.unwrapped, "_get_obs") else env.unwrapped.state)
        act = rng.uniform(-1, 1, world.env.action_space.shape).astype(np.float32)
        nxt, r, term, trunc, _ = env.step(world.to_env(act))
        out.append((np.asarray(obs, np.float32), act, np.asarray(nxt, np.float32), r, term))
        obs = nxt
        if term or trunc:
            obs, _ = env.reset()
    return out


def _check(world, transitions):
    reward = jax.jit(world.env.reward)
    for obs, act, nxt, r, _ in transitions:
        assert float(reward(obs, act, nxt, world.params)) == pytest.approx(r, rel=1e-4, abs=1e-4)


def test_pendulum_reward_is_gymnasiums():
    world = resolve_env("gym:Pendulum-v1,g=9.81")
    assert isinstance(world, GymWorld) and world.horizon == 200
    assert world.env.observation_space.shape == (3,) and world.env.action_space.low == -1.0
    np.testing.assert_allclose(world.to_env(np.array([-1.0, 0.0, 1.0])[:, None]).ravel(), [-2.0, 0.0, 2.0])
    rng = np.random.default_rng(0)
    _check(world, _transitions(world, 300, rng))
    # any angle and speed, wrapped angles included
    _check(world, _transitions(world, 200, rng, lambda g: np.array([g.uniform(-10, 10), g.uniform(-8, 8)])))


def test_mountain_car_reward_is_gymnasiums_including_the_goal():
    world = resolve_env("gym:MountainCarContinuous-v0")
    assert world.horizon == 999
    rng = np.random.default_rng(1)
    near_goal = _transitions(world, 300, rng, lambda g: np.array([g.uniform(0.3, 0.6), g.uniform(-0.07, 0.07)]))
    assert any(t[4] for t in near_goal) and not all(t[4] for t in near_goal)
    _check(world, near_goal)
    _check(world, _transitions(world, 200, rng))
    slow = resolve_env("gym:MountainCarContinuous-v0,goal_velocity=0.05")
    _check(slow, _transitions(slow, 300, rng, lambda g: np.array([g.uniform(0.3, 0.6), g.uniform(-0.07, 0.07)])))


def test_bad_gym_specs_are_one_line():
    cases = {
        "gym:NoSuchEnv-v0": "gym:NoSuchEnv-v0",
        "gym:CartPole-v1": "flat Box action space",
        "gym:": "expected gym:ID",
        "gym:Pendulum-v1,g": "expected key=value",
        "gym:Pendulum-v1,max_episode_steps=0": "max_episode_steps must be a positive integer",
        "gym:Pendulum-v1,colour=red": "Pendulum-v1",
    }
    for spec, words in cases.items():
        with pytest.raises(EnvError) as e:
            resolve_env(spec)
        assert words in str(e.value) and "\n" not in str(e.value), spec
    assert resolve_env("gym:Pendulum-v1,max_episode_steps=50").horizon == 50
    assert gymnasium.make("Pendulum-v1").spec.max_episode_steps == 200
