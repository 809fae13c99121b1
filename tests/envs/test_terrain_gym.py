"""The gymnasium adapter passes gymnasium's own checker and agrees with the functional API."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from mindgap.envs.terrain.gym_env import TerrainEnv


def test_passes_gymnasium_env_checker():
    check_env(TerrainEnv("d3"), skip_render_check=True)


def test_registered_ids_make_the_named_worlds():
    env = gym.make("mindgap/nav2-v0")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs) and info["t"] == 0
    env.close()


def test_an_episode_ends_in_the_goal_when_driven_there():
    env = TerrainEnv("d1")
    obs, info = env.reset(seed=0)
    total, done, steps = 0.0, False, 0
    while not done:  # down one row, right under the pit, up into the goal: d1's optimal route
        x, y = info["pos"]
        action = [1.0, 1.0] if y < 2.3 and x < 2.5 else [1.0, 0.0] if x < 4.7 else [0.3, -1.0]
        obs, r, term, trunc, info = env.step(action)
        total, done, steps = total + r, term or trunc, steps + 1
    assert term and not trunc and steps < 20
    assert total > 90  # +100 goal, −1 per step, progress ≈ the geodesic distance


def test_seeded_resets_repeat_and_render():
    env = TerrainEnv("nav1-v1", render_mode="rgb_array")
    a, _ = env.reset(seed=7)
    b, _ = env.reset(seed=7)
    np.testing.assert_array_equal(a, b)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (7 * 16, 14 * 16, 3)
    with pytest.raises(ValueError, match="render_mode"):
        TerrainEnv("nav1-v1", render_mode="human")


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        TerrainEnv("d1").step([0.0, 0.0])


def test_belief_world_steps_under_the_belief():
    env = TerrainEnv("d1", belief="human")
    assert float(env.params.dynamics.pit_noise) > 0 and float(env.world.params.dynamics.pit_noise) == 0
