"""Bradley–Terry loss, query samplers and reward training on hand-made segments."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.feedback.queries import query_scores
from mindgap.feedback.segments import Segments
from mindgap.models.reward_ensemble import (
    RewardConfig,
    bt_loss,
    ensemble_reward,
    prefs_add,
    prefs_init,
    reward_init,
    segment_returns,
    train_reward,
)


def _seg(obs_x, mask=None):
    """Segments [K, L] whose observations are (x, 0) and actions 0."""
    x = jnp.asarray(obs_x, jnp.float32)
    obs = jnp.stack([x, jnp.zeros_like(x)], -1)
    m = jnp.ones(x.shape, bool) if mask is None else jnp.asarray(mask)
    return Segments(obs, jnp.zeros_like(obs), obs, m)


def test_bt_loss_matches_hand_computation():
    # one member whose reward is tanh(x): a zero hidden layer, identity-like path via the output bias
    w1, b1 = jnp.zeros((4, 1)).at[0, 0].set(1.0), jnp.zeros(1)
    w2, b2 = jnp.ones((1, 1)), jnp.zeros(1)
    params = jax.tree.map(lambda x: x[None], ((w1, b1), (w2, b2)))
    a = _seg([[0.5, 0.5]])  # relu(0.5) → tanh(0.5) per step
    b = _seg([[-0.5, 0.2]], mask=[[True, False]])  # relu(−0.5) = 0 → tanh(0) = 0, second step masked
    ra, rb = 2 * np.tanh(0.5), 0.0
    np.testing.assert_allclose(np.asarray(segment_returns(params, a))[0, 0], ra, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(segment_returns(params, b))[0, 0], rb, atol=1e-7)
    for y in (1.0, 0.0, 0.5):
        p = 1 / (1 + np.exp(-(ra - rb)))
        expect = -(y * np.log(p) + (1 - y) * np.log(1 - p))
        got = bt_loss(params, a, b, jnp.array([y]), jnp.ones((1, 1)))
        np.testing.assert_allclose(float(got), expect, rtol=1e-5)


def test_samplers_rank_hand_made_probabilities():
    probs = jnp.array([[0.5, 0.9, 0.1, 0.6], [0.5, 0.9, 0.9, 0.4], [0.5, 0.9, 0.5, 0.5]])  # [E=3, M=4]
    dis = np.asarray(query_scores(probs, "disagreement"))
    ent = np.asarray(query_scores(probs, "entropy"))
    assert np.argmax(dis) == 2 and dis[0] == 0 and dis[1] == 0  # members disagree most on pair 2
    assert np.argmax(ent) in (0, 3) and ent[1] < ent[0]  # mean 0.5 is most uncertain; 0.9 confident
    np.testing.assert_allclose(ent[0], np.log(2), rtol=1e-5)
    uni = np.asarray(query_scores(probs, "uniform"))
    assert list(np.argsort(-uni)) == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="unknown sampler"):
        query_scores(probs, "greedy")


def test_training_learns_a_preferred_region(key):
    """Segments further right are always preferred: the learned reward must increase with x."""
    cfg = RewardConfig(members=3, hidden=(16, 16), updates=300, batch_size=32)
    k_init, k_data, k_train = jax.random.split(key, 3)
    xs = jax.random.uniform(k_data, (2, 64, 5), minval=-1, maxval=1)
    a, b = _seg(xs[0]), _seg(xs[1])
    labels = (xs[0].sum(-1) > xs[1].sum(-1)).astype(jnp.float32)
    data = prefs_add(prefs_init(64, 5, 2, 2), a, b, labels, jnp.ones(64, bool))
    assert int(data.count) == 64
    state = reward_init(k_init, 2, 2, cfg)
    state, loss, acc = train_reward(state, data, k_train, cfg)
    assert float(acc) > 0.9
    grid = jnp.stack([jnp.linspace(-1, 1, 9), jnp.zeros(9)], -1)
    r = np.asarray(ensemble_reward(state.params, grid, jnp.zeros_like(grid), grid))
    assert np.corrcoef(r, np.linspace(-1, 1, 9))[0, 1] > 0.9


def test_prefs_add_drops_skipped_and_respects_capacity():
    data = prefs_init(3, 2, 2, 2)
    a = _seg(jnp.arange(8.0).reshape(4, 2))
    data = prefs_add(data, a, a, jnp.array([1.0, 0.0, 1.0, 0.5]), jnp.array([True, False, True, True]))
    assert int(data.count) == 3
    np.testing.assert_array_equal(np.asarray(data.seg_a.obs[:, 0, 0]), [0.0, 4.0, 6.0])  # pair 1 skipped
    np.testing.assert_array_equal(np.asarray(data.label), [1.0, 1.0, 0.5])
