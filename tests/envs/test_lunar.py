"""The solar-wind lander: the wind drops left pushes and reinforces right ones; the vacuum is gymnasium's own."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.envs.interface import EnvError
from mindgap.envs.lunar import lander_reward

VACUUM = "gym:LunarLander-v3,continuous=True"
WIND = "gym:mindgap/SolarWindLander-v0,gain=2.0,share=0.5"


def rollout(spec, actions, seed):
    """Observations after each of ``actions`` (stops at the episode's end) and gymnasium's rewards."""
    world = gym_world_from_spec(spec)
    env, obs = world.make(seed)
    out, rewards = [obs], []
    try:
        for a in actions:
            o, r, term, trunc, _ = env.step(world.to_env(a))
            out.append(np.asarray(o, np.float32)), rewards.append(r)
            if term or trunc:
                break
    finally:
        env.close()
    return np.stack(out), np.asarray(rewards)


def side_actions(n, seed=0):
    a = np.random.default_rng(seed).uniform(-1, 1, (n, 2)).astype(np.float32)
    a[:, 0] = -1.0  # main engine off: the side engines alone move the lander sideways
    return a


def test_without_wind_it_is_the_vacuum_bit_for_bit():
    acts = side_actions(80)
    for seed in range(3):
        calm, _ = rollout("gym:mindgap/SolarWindLander-v0,gain=1.0,share=0.0", acts, seed)
        vacuum, _ = rollout(VACUUM, acts, seed)
        np.testing.assert_array_equal(calm, vacuum)


def test_a_full_wind_drops_every_left_push():
    left = np.tile(np.array([[-1.0, -1.0]], np.float32), (60, 1))
    idle = left.copy()
    idle[:, 1] = 0.0
    dropped, _ = rollout("gym:mindgap/SolarWindLander-v0,gain=1.0,share=1.0", left, seed=4)
    coasting, _ = rollout(VACUUM, idle, seed=4)
    pushed, _ = rollout(VACUUM, left, seed=4)
    np.testing.assert_array_equal(dropped, coasting)
    assert pushed[-1, 0] < coasting[-1, 0] - 0.05  # in a vacuum the same pushes move it left


def test_right_pushes_are_reinforced():
    right = np.tile(np.array([[-1.0, 1.0]], np.float32), (30, 1))
    strong, _ = rollout("gym:mindgap/SolarWindLander-v0,gain=2.0,share=0.0", right, seed=2)
    plain, _ = rollout(VACUUM, right, seed=2)
    assert strong[-1, 2] > plain[-1, 2] + 0.1  # more velocity to the right


def test_the_wind_drifts_the_lander_right_on_identical_actions():
    acts = side_actions(60, seed=1)
    drift = [rollout(WIND, acts, s)[0][-1, 0] - rollout(VACUUM, acts, s)[0][-1, 0] for s in range(5)]
    assert min(drift) > 0.0 and np.mean(drift) > 0.02, drift


def test_the_person_s_reward_is_gymnasium_s_in_a_vacuum():
    obs, rewards = rollout(VACUUM, side_actions(100, seed=3), seed=0)
    acts = side_actions(100, seed=3)[: len(rewards)]
    ours = np.asarray(
        [
            lander_reward(jnp.asarray(o), jnp.asarray(a), jnp.asarray(o2), None)
            for o, a, o2 in zip(obs[:-1], acts, obs[1:])
        ]
    )
    # gymnasium's first step has no previous potential, and the crash / rest bonuses are not
    # observable (module docstring): compare the steps in between
    np.testing.assert_allclose(ours[1:-1], rewards[1:-1], atol=1e-3)


@pytest.mark.parametrize(
    "kw, problem", [("share=1.5", "share must be in [0, 1]"), ("gain=0.5", "gain must be at least 1")]
)
def test_bad_wind_is_one_line(kw, problem):
    with pytest.raises(EnvError, match=re.escape(problem)):
        gym_world_from_spec(f"gym:mindgap/SolarWindLander-v0,{kw}")
