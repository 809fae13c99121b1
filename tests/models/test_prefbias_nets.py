"""PrefBias's reward and belief networks: bounded reward, the engine's reward_fn signature, the belief map."""

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.layout import FLOOR, ICE, PIT, SAND, WALL
from mindgap.feedback.replay import relabel, replay_add, replay_init
from mindgap.models.gaussian_dynamics import Norm, dynamics_sizes
from mindgap.models.mlp import init_mlp
from mindgap.models.prefbias_nets import (
    REWARD_BOUND,
    belief_noise_map,
    belief_predict,
    posterior_reward,
    reward_sizes,
    reward_value,
    table_noise_map,
)


def test_reward_is_soft_bounded(key):
    params = init_mlp(key, reward_sizes(2, 2, (8,)))
    w, b = params[-1]
    big = params[:-1] + ((w, b + 1e4),)  # push the raw output far past the bound
    r = reward_value(big, jnp.zeros((3, 2)), jnp.zeros((3, 2)))
    assert np.all(np.asarray(r) <= REWARD_BOUND) and float(r.min()) > 0.99 * REWARD_BOUND
    small = params[:-1] + ((w * 0, b * 0 + 0.5),)
    np.testing.assert_allclose(reward_value(small, jnp.zeros(2), jnp.zeros(2)), 0.5, rtol=1e-3)  # ≈ linear near 0


def test_posterior_reward_relabels_a_replay_buffer(key):
    params = init_mlp(key, reward_sizes(2, 2, (8,)))
    buf = replay_init(16, 2, 2)
    rows = jax.random.normal(key, (5, 6))
    for i in range(5):
        buf = replay_add(buf, rows[i, :2], rows[i, 2:4], rows[i, 4:], 0.0, 0.0, False, i)
    buf = relabel(buf, posterior_reward, params, chunk=8)
    np.testing.assert_allclose(buf.reward[:5], reward_value(params, rows[:, :2], rows[:, 2:4]), rtol=1e-5)
    assert np.all(np.asarray(buf.reward[5:]) == 0)


def test_belief_noise_map_reads_cells_and_marks_walls(key):
    """A belief whose scale head is constant predicts the same noise everywhere, converted to cells."""
    world = load_world("nav1")
    params = init_mlp(key, dynamics_sizes(2, 2, (8,)))
    w, b = params[-1]
    const = params[:-1] + ((w * 0, jnp.array([0.0, 0.0, 0.5, -0.5])),)
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.array([0.02, 0.05]))
    noise = np.asarray(belief_noise_map(const, norm, world.params, min_std=0.01))
    h, wd = world.params.shape
    assert noise.shape == (h, wd)
    walls = np.asarray(world.params.grid) == WALL
    assert np.all(np.isnan(noise[walls])) and not np.any(np.isnan(noise[~walls]))
    sx, sy = 0.02 * (0.01 + np.log1p(np.exp(0.5))), 0.05 * (0.01 + np.log1p(np.exp(-0.5)))
    expect = 0.5 * (sx * wd / 2 + sy * h / 2)  # observation units → cells, averaged over the axes
    np.testing.assert_allclose(noise[~walls], expect, rtol=1e-5)
    # and a belief whose noise depends on the input is read at each cell's centre
    _, std = belief_predict(params, norm, jnp.array([2 * 1.5 / wd - 1, 2 * 1.5 / h - 1]), jnp.array([1.0, 0.0]), 0.01)
    one = np.asarray(belief_noise_map(params, norm, world.params, 0.01, actions=jnp.array([[1.0, 0.0]])))
    np.testing.assert_allclose(one[1, 1], 0.5 * (std[0] * wd / 2 + std[1] * h / 2), rtol=1e-5)


def test_table_noise_map_reads_the_belief_table():
    nav1 = load_world("nav1")
    belief = nav1.beliefs["human"]
    noise = np.asarray(table_noise_map(nav1.belief("human")))
    grid = np.asarray(nav1.params.grid)
    for code in (FLOOR, ICE, SAND):
        np.testing.assert_allclose(noise[grid == code], float(belief.noise[code]), rtol=1e-6)
    assert np.all(np.isnan(noise[grid == WALL]))
    # nav2's belief adds noise near the pit: the cell just above it is noisier than a far corner
    nav2 = load_world("nav2")
    noise2 = np.asarray(table_noise_map(nav2.belief()))
    assert np.asarray(nav2.params.grid)[2, 5] == PIT
    assert noise2[1, 5] > 2 * noise2[6, 1]
