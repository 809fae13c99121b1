"""Hopper and half-cheetah with hidden noise: the reliable env without it, noisier with it, the person's reward exact."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.envs.interface import EnvError
from mindgap.teachers.learned_belief import BeliefFitConfig, fit_learned_belief

RELIABLE = {
    "hopper": "gym:Hopper-v5,exclude_current_positions_from_observation=False",
    "cheetah": "gym:HalfCheetah-v5,exclude_current_positions_from_observation=False",
}
NOISY = {"hopper": "gym:mindgap/NoisyHopper-v0", "cheetah": "gym:mindgap/NoisyHalfCheetah-v0"}


def actions(n, dim, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (n, dim)).astype(np.float32)


@pytest.mark.parametrize("body, dim", [("hopper", 3), ("cheetah", 6)])
def test_without_noise_it_is_the_reliable_env_and_with_it_not(body, dim, gym_rollout):
    acts = actions(60, dim)
    _, calm, _ = gym_rollout(f"{NOISY[body]},share=0.0", acts, seed=1)
    _, plain, _ = gym_rollout(RELIABLE[body], acts, seed=1)
    np.testing.assert_array_equal(calm, plain)
    _, noisy, _ = gym_rollout(NOISY[body], acts, seed=1)
    n = min(len(noisy), len(plain))
    assert np.abs(noisy[:n] - plain[:n]).max() > 0.1


@pytest.mark.parametrize("body, dim", [("hopper", 3), ("cheetah", 6)])
def test_the_person_s_reward_is_gymnasium_s(body, dim, gym_rollout):
    world, obs, rewards = gym_rollout(RELIABLE[body], actions(80, dim, seed=2), seed=0)
    acts = actions(80, dim, seed=2)[: len(rewards)]
    ours = [float(world.env.reward(jnp.asarray(o), jnp.asarray(a), jnp.asarray(o2), world.params))
            for o, a, o2 in zip(obs[:-1], acts, obs[1:])]  # fmt: skip
    np.testing.assert_allclose(ours, rewards, rtol=1e-4, atol=1e-3)
    # the noise touches velocities, not positions: the noisy env's reward reads the same way
    noisy, obs, rewards = gym_rollout(NOISY[body], actions(80, dim, seed=2), seed=0)
    ours = [float(noisy.env.reward(jnp.asarray(o), jnp.asarray(a), jnp.asarray(o2), noisy.params))
            for o, a, o2 in zip(obs[:-1], acts, obs[1:])]  # fmt: skip
    np.testing.assert_allclose(ours, rewards[: len(ours)], rtol=1e-4, atol=1e-3)


def test_a_model_of_the_reliable_hopper_finds_the_noisy_one_less_predictable(tmp_path):
    cfg = BeliefFitConfig.fast()
    _, record = fit_learned_belief(
        gym_world_from_spec(RELIABLE["hopper"]),
        cfg,
        true_world=gym_world_from_spec(NOISY["hopper"]),
        cache_dir=tmp_path,
    )
    assert record["true_log_lik"] < record["held_out_log_lik"] - 1.0


def test_without_x_in_the_observation_there_is_no_reward_for_the_person():
    assert gym_world_from_spec("gym:Hopper-v5").env.reward is None
    assert gym_world_from_spec(NOISY["hopper"]).env.reward is not None


def test_bad_noise_is_one_line():
    with pytest.raises(EnvError, match=re.escape("share must be in [0, 1]")):
        gym_world_from_spec(f"{NOISY['hopper']},share=2.0")
