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


def side_actions(n, seed=0):
    a = np.random.default_rng(seed).uniform(-1, 1, (n, 2)).astype(np.float32)
    a[:, 0] = -1.0  # main engine off: the side engines alone move the lander sideways
    return a


def test_without_wind_it_is_the_vacuum_bit_for_bit(gym_rollout):
    acts = side_actions(80)
    for seed in range(3):
        _, calm, _ = gym_rollout("gym:mindgap/SolarWindLander-v0,gain=1.0,share=0.0", acts, seed)
        _, vacuum, _ = gym_rollout(VACUUM, acts, seed)
        np.testing.assert_array_equal(calm, vacuum)


def test_a_full_wind_drops_every_left_push(gym_rollout):
    left = np.tile(np.array([[-1.0, -1.0]], np.float32), (60, 1))
    idle = left.copy()
    idle[:, 1] = 0.0
    _, dropped, _ = gym_rollout("gym:mindgap/SolarWindLander-v0,gain=1.0,share=1.0", left, seed=4)
    _, coasting, _ = gym_rollout(VACUUM, idle, seed=4)
    _, pushed, _ = gym_rollout(VACUUM, left, seed=4)
    np.testing.assert_array_equal(dropped, coasting)
    assert pushed[-1, 0] < coasting[-1, 0] - 0.05  # in a vacuum the same pushes move it left


def test_right_pushes_are_reinforced(gym_rollout):
    right = np.tile(np.array([[-1.0, 1.0]], np.float32), (30, 1))
    _, strong, _ = gym_rollout("gym:mindgap/SolarWindLander-v0,gain=2.0,share=0.0", right, seed=2)
    _, plain, _ = gym_rollout(VACUUM, right, seed=2)
    assert strong[-1, 2] > plain[-1, 2] + 0.1  # more velocity to the right


def test_the_wind_drifts_the_lander_right_on_identical_actions(gym_rollout):
    acts = side_actions(60, seed=1)
    drift = [gym_rollout(WIND, acts, s)[1][-1, 0] - gym_rollout(VACUUM, acts, s)[1][-1, 0] for s in range(5)]
    assert min(drift) > 0.0 and np.mean(drift) > 0.02, drift


def test_the_person_s_reward_is_gymnasium_s_in_a_vacuum(gym_rollout):
    _, obs, rewards = gym_rollout(VACUUM, side_actions(100, seed=3), seed=0)
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
