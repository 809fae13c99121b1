"""PrefBias's reward and belief networks: bounded reward, the engine's reward_fn signature, the belief map."""

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.data.replay import relabel, replay_add, replay_init
from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.layout import FLOOR, ICE, PIT, SAND, WALL
from mindgap.models.bayes import init_gaussian
from mindgap.models.gaussian_dynamics import Norm, dynamics_sizes
from mindgap.models.mlp import init_mlp
from mindgap.models.prefbias_nets import (
    absorbing_value,
    belief_predict,
    belief_weights_init,
    draw_per_pair,
    posterior_reward,
    reward_sizes,
    reward_value,
    reward_weights_init,
)
from mindgap.models.reward_ensemble import REWARD_BOUND
from mindgap.planning.terrain_maps import belief_noise_map, table_noise_map


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
    world = load_world("nav1-v1")
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
    nav1 = load_world("nav1-v1")
    belief = nav1.beliefs["human"]
    noise = np.asarray(table_noise_map(nav1.belief("human")))
    grid = np.asarray(nav1.params.grid)
    for code in (FLOOR, ICE, SAND):
        np.testing.assert_allclose(noise[grid == code], float(belief.noise[code]), rtol=1e-6)
    assert np.all(np.isnan(noise[grid == WALL]))
    # nav2's belief adds noise near the pit: the cell just above it is noisier than a far corner
    nav2 = load_world("nav2-v1")
    noise2 = np.asarray(table_noise_map(nav2.belief()))
    assert np.asarray(nav2.params.grid)[2, 5] == PIT
    assert noise2[1, 5] > 2 * noise2[6, 1]


def test_stay_maps_read_the_stay_head_and_the_table_s_exact_stay_probability(key):
    """nav1: the person thinks the icy corridor holds the robot most steps; f_φ's stay head is read per cell."""
    from mindgap.planning.terrain_maps import belief_stay_map, table_stay_map

    nav1 = load_world("nav1")
    grid = np.asarray(nav1.params.grid)
    walls = grid == WALL
    person, truth = np.asarray(table_stay_map(nav1.belief())), np.asarray(table_stay_map(nav1.params))
    assert np.all(np.isnan(person[walls])) and not np.any(np.isnan(person[~walls]))
    ice = grid == ICE
    # stuck, or else bumped against a wall: P(stay) = p_stuck + (1 − p_stuck)·P(bump), and the two
    # tables differ only in p_stuck (believed high, truly low), so P(bump) must come out the same
    assert ice.any()
    p_h, p_t = float(nav1.belief().dynamics.stuck[ICE]), float(nav1.params.dynamics.stuck[ICE])
    assert p_h > p_t > 0
    bump_person, bump_truth = (person[ice] - p_h) / (1 - p_h), (truth[ice] - p_t) / (1 - p_t)
    np.testing.assert_allclose(bump_person, bump_truth, atol=1e-5)
    assert np.all(bump_truth >= 0) and np.all(bump_truth < 0.5)
    # a network with a constant stay logit l predicts sigmoid(l) at every passable cell
    params = init_mlp(key, dynamics_sizes(2, 2, (8,), stay=True))
    w, b = params[-1]
    const = params[:-1] + ((w * 0, jnp.array([0.0, 0.0, 0.0, 0.0, 1.2])),)
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.ones(2))
    stay = np.asarray(belief_stay_map(const, norm, nav1.params))
    np.testing.assert_allclose(stay[~walls], 1 / (1 + np.exp(-1.2)), rtol=1e-5)
    assert np.all(np.isnan(stay[walls]))
    plain = init_mlp(key, dynamics_sizes(2, 2, (8,)))  # no stay head: nothing to read
    assert np.all(np.isnan(np.asarray(belief_stay_map(plain, norm, nav1.params))))


def _np_features(s_t):
    """Radial basis features of terminal states, by hand: 16 × 16 bumps on [−1, 1]², height 20, cut at 2 widths."""
    axis = np.linspace(-1.0, 1.0, 16)
    centres = np.stack(np.meshgrid(axis, axis, indexing="ij"), -1).reshape(-1, 2)
    width = 2.0 / 15
    sq = ((np.asarray(s_t, np.float64)[:, None, :] - centres) ** 2).sum(-1)
    return np.where(sq < (2 * width) ** 2, 20.0 * np.exp(-0.5 * sq / width**2), 0.0)


def test_absorbing_head_is_a_bounded_linear_function_of_terminal_features(key):
    k_w, k_a, k_s = jax.random.split(key, 3)
    weights = reward_weights_init(k_w, 2, 2, (8,), absorbing=True)
    assert weights.absorb.shape == (256,) and not np.any(np.asarray(weights.absorb))  # r_abs = 0 a priori
    np.testing.assert_array_equal(absorbing_value(weights, jnp.zeros((3, 2))), 0.0)
    weights = weights._replace(absorb=0.2 * jax.random.normal(k_a, (256,)))
    s_t = jax.random.uniform(k_s, (5, 2), minval=-1, maxval=1)
    raw = _np_features(s_t) @ np.asarray(weights.absorb, np.float64)
    expect = REWARD_BOUND * np.tanh(raw / REWARD_BOUND)
    np.testing.assert_allclose(absorbing_value(weights, s_t), expect, rtol=1e-4, atol=1e-5)
    # the step reward reads the MLP alone, as with plain MLP weights
    obs, act = s_t, jnp.ones((5, 2))
    np.testing.assert_array_equal(reward_value(weights, obs, act), reward_value(weights.net, obs, act))
    # without a head: the MLP's parameters alone, the same MLP, no absorbing reward
    off = reward_weights_init(k_w, 2, 2, (8,), absorbing=False)
    assert jax.tree.structure(off) == jax.tree.structure(weights.net)
    np.testing.assert_array_equal(reward_value(off, obs, act), reward_value(weights, obs, act))
    np.testing.assert_array_equal(absorbing_value(off, s_t), 0.0)


def test_a_single_absorbing_state_serves_worlds_of_any_size(key):
    import pytest

    from mindgap.algorithms.prefbias import PrefBiasLoopConfig
    from mindgap.algorithms.prefbias_inference import PrefBiasConfig

    with pytest.raises(ValueError, match="at most 3 observation dimensions"):
        reward_weights_init(key, 8, 2, (8,), absorbing=True)
    weights = reward_weights_init(key, 8, 2, (8,), absorbing=True, single=True)
    assert weights.absorb.shape == (1,)
    weights = weights._replace(absorb=jnp.array([3.0]))
    s_t = jax.random.uniform(key, (4, 8), minval=-1, maxval=1)
    np.testing.assert_allclose(absorbing_value(weights, s_t), REWARD_BOUND * np.tanh(3.0 / REWARD_BOUND), rtol=1e-6)
    # the run record names the choice only when it is not the default, so older run folders still resume
    plain = PrefBiasLoopConfig().as_dict()["prefbias"]
    single = PrefBiasLoopConfig(prefbias=PrefBiasConfig(absorbing_state="single")).as_dict()["prefbias"]
    assert "absorbing_state" not in plain and single["absorbing_state"] == "single"
    with pytest.raises(ValueError, match="absorbing_state must be one of"):
        PrefBiasConfig(absorbing_state="many").check()


def test_draw_per_pair_gives_each_pair_one_draw_of_all_weights(key):
    """One draw from q per pair: every weight (r_w's and r_abs's) has q's mean and spread across pairs."""
    k_w, k_m, k_draw = jax.random.split(key, 3)
    mean = reward_weights_init(k_w, 2, 2, (4,), absorbing=True)
    mean = mean._replace(absorb=0.01 * jax.random.normal(k_m, (256,)))
    post = init_gaussian(mean, 0.05)
    n = 4000
    draws = draw_per_pair(post, k_draw, n)
    assert jax.tree.structure(draws) == jax.tree.structure(mean)
    for d, m in zip(jax.tree.leaves(draws), jax.tree.leaves(mean), strict=True):
        d = np.asarray(d, np.float64)
        assert d.shape == (n, *m.shape)
        np.testing.assert_allclose(d.mean(0), m, atol=4.5 * 0.05 / np.sqrt(n))
        np.testing.assert_allclose(d.std(0), 0.05, rtol=0.1)
    # different pairs, different functions
    s_t = jnp.array([[0.1, -0.3]])
    values = jax.vmap(absorbing_value, in_axes=(0, None))(jax.tree.map(lambda x: x[:3], draws), s_t)[:, 0]
    assert len(set(np.asarray(values).tolist())) == 3


def test_a_world_of_many_dimensions_gets_a_belief_without_local_bumps(key):
    # the local stay disturbance needs radial features (at most 3 dimensions): a gym world of 8 has
    # none, and f_φ is the MLP alone rather than an error (reproduce gym's PrefBias jobs)
    net = init_mlp(key, [10, 8, 4])
    assert belief_weights_init(net, 8, local=False) is net
    local = belief_weights_init(init_mlp(key, [4, 8, 4]), 2, local=True)
    assert local.stay.shape == (16**2,) and local.noise.shape == (0,)  # 16 bumps an axis, no noise part
