"""Bradley–Terry loss, query samplers and reward training on hand-made segments."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.data.prefs import prefs_add, prefs_init
from mindgap.data.segments import AbsorbingSegments, Segments, with_absorbing
from mindgap.feedback.queries import query_scores
from mindgap.models.reward_ensemble import (
    RBF_GAIN,
    RBF_PER_AXIS,
    REWARD_BOUND,
    AbsorbingParams,
    RewardConfig,
    absorbing_features,
    absorbing_reward,
    bt_loss,
    ensemble_reward,
    member_absorbing_rewards,
    member_rewards,
    reward_init,
    segment_returns,
    train_reward,
)


def _bounded(x):
    return REWARD_BOUND * np.tanh(x / REWARD_BOUND)


def _seg(obs_x, mask=None):
    """Segments [K, L] whose observations are (x, 0) and actions 0."""
    x = jnp.asarray(obs_x, jnp.float32)
    obs = jnp.stack([x, jnp.zeros_like(x)], -1)
    m = jnp.ones(x.shape, bool) if mask is None else jnp.asarray(mask)
    return Segments(obs, jnp.zeros_like(obs), obs, m)


def test_bt_loss_matches_hand_computation():
    # one member whose reward is B·tanh(x/B): a zero hidden layer, identity-like path via the output bias
    w1, b1 = jnp.zeros((4, 1)).at[0, 0].set(1.0), jnp.zeros(1)
    w2, b2 = jnp.ones((1, 1)), jnp.zeros(1)
    params = jax.tree.map(lambda x: x[None], ((w1, b1), (w2, b2)))
    a = _seg([[0.5, 0.5]])  # relu(0.5) → B·tanh(0.5/B) per step
    b = _seg([[-0.5, 0.2]], mask=[[True, False]])  # relu(−0.5) = 0 → 0, second step masked
    ra, rb = 2 * _bounded(0.5), 0.0
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


def _bounded_x_member(absorb):
    """One member whose step reward is B·tanh(relu(x)/B), with a single absorbing state of reward B·tanh(absorb/B)."""
    w1, b1 = jnp.zeros((4, 1)).at[0, 0].set(1.0), jnp.zeros(1)
    w2, b2 = jnp.ones((1, 1)), jnp.zeros(1)
    head = jnp.array([[absorb]])  # one constant feature
    return AbsorbingParams(jax.tree.map(lambda x: x[None], ((w1, b1), (w2, b2))), head)


def test_segment_return_counts_absorbing_steps():
    """Σ mask·r(s, a) + Σ absorbed·r_abs, with r_abs = B·tanh(θ_abs/B) (Kostrikov et al. 2019)."""
    params = _bounded_x_member(0.7)
    plain = _seg([[0.5, 0.3, 9.0, 9.0]], mask=[[True, True, False, False]])
    seg = AbsorbingSegments(*plain[:4], jnp.array([[False, False, True, True]]))  # reached the goal after 2 steps
    expect = _bounded(0.5) + _bounded(0.3) + 2 * _bounded(0.7)
    np.testing.assert_allclose(float(segment_returns(params, seg)[0, 0]), expect, rtol=1e-6)
    np.testing.assert_allclose(  # a plain segment has no absorbing steps
        float(segment_returns(params, plain)[0, 0]), _bounded(0.5) + _bounded(0.3), rtol=1e-6
    )
    np.testing.assert_allclose(  # parameters without an absorbing state ignore them, as before
        float(segment_returns(params.net, seg)[0, 0]), _bounded(0.5) + _bounded(0.3), rtol=1e-6
    )
    s_t = jnp.array([[0.3, 0.0], [-5.0, 1.0]])
    np.testing.assert_allclose(np.asarray(absorbing_reward(params, s_t)), [_bounded(0.7)] * 2, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(absorbing_reward(params.net, s_t)), [0.0, 0.0])
    grid = jnp.array([[0.5, 0.0], [-1.0, 0.0]])
    np.testing.assert_array_equal(  # the step reward does not depend on the absorbing state
        np.asarray(ensemble_reward(params, grid, grid, grid)), np.asarray(ensemble_reward(params.net, grid, grid, grid))
    )


def test_each_terminal_state_has_its_own_absorbing_reward():
    """With a ``terminal`` head r_abs is a local function of the state s_T the last real step ended in."""
    phi = lambda o: np.asarray(absorbing_features(jnp.asarray(o, jnp.float32), RBF_PER_AXIS**2))  # noqa: E731
    centre = np.array([-1.0, -1.0])  # the first grid centre
    width = 2.0 / (RBF_PER_AXIS - 1)
    np.testing.assert_allclose(phi([centre + [width, 0.0]])[0, 0], RBF_GAIN * np.exp(-0.5), rtol=1e-5)
    assert phi([[0.3, -0.2]]).shape == (1, RBF_PER_AXIS**2)
    w = np.zeros((1, RBF_PER_AXIS**2), np.float32)
    w[0, 0] = 0.05
    params = _bounded_x_member(0.0)._replace(absorb=jnp.asarray(w))
    near, far = [-1.0, -0.95], [0.0, 0.0]
    nxt = jnp.asarray([[[0.1, 0.0], near, near, near], [[0.1, 0.0], [0.2, 0.0], far, far]], jnp.float32)
    obs = nxt.at[:, :, 0].set(0.2)
    mask = jnp.array([[True, True, False, False], [True, True, True, False]])
    seg = AbsorbingSegments(obs, jnp.zeros_like(obs), nxt, mask, ~mask)
    # segment 0 ended near the first centre (2 absorbing steps), segment 1 far from it (1 step)
    r_near = _bounded(0.05 * phi([near])[0, 0])
    assert r_near > 0.5 and abs(_bounded(0.05 * phi([far])[0, 0])) < 1e-6  # local: 0 where nothing was learned
    expect = [2 * _bounded(0.2) + 2 * r_near, 3 * _bounded(0.2)]
    np.testing.assert_allclose(np.asarray(segment_returns(params, seg)[0]), expect, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(absorbing_reward(params, nxt[:, 1])), [r_near, 0.0], rtol=1e-5, atol=1e-6)


def test_bt_loss_gradient_reaches_the_absorbing_reward():
    params = _bounded_x_member(0.2)
    a = AbsorbingSegments(*_seg([[0.5, 0.0, 0.0]], mask=[[True, False, False]])[:4], jnp.array([[False, True, True]]))
    b = AbsorbingSegments(*_seg([[0.1, 0.1, 0.1]])[:4], jnp.zeros((1, 3), bool))
    g = jax.grad(bt_loss)(params, a, b, jnp.array([1.0]), jnp.ones((1, 1)))
    # d loss / d θ_abs = −(1 − σ(R_a − R_b)) · 2 · (1 − tanh²(θ_abs/B)) for a preferred segment a
    ra, rb = _bounded(0.5) + 2 * _bounded(0.2), 3 * _bounded(0.1)
    expect = -(1 - 1 / (1 + np.exp(-(ra - rb)))) * 2 * (1 - np.tanh(0.2 / REWARD_BOUND) ** 2)
    got = float(g.absorb[0, 0])
    np.testing.assert_allclose(got, expect, rtol=1e-5)
    assert got < 0  # preferring the segment that ended raises r_abs


def test_reward_init_and_prefs_with_absorbing_state(key):
    cfg = RewardConfig(members=2, hidden=(8,))
    plain = reward_init(key, 2, 2, cfg)
    s_t = jax.random.normal(key, (5, 2))
    for kind, m in (("terminal", RBF_PER_AXIS**2), ("single", 1)):
        absorbing = reward_init(key, 2, 2, cfg, absorbing=kind)
        assert isinstance(absorbing.params, AbsorbingParams) and absorbing.params.absorb.shape == (2, m)
        np.testing.assert_array_equal(np.asarray(absorbing_reward(absorbing.params, s_t)), 0.0)  # r_abs starts at 0
        for x, y in zip(jax.tree.leaves(plain.params), jax.tree.leaves(absorbing.params.net)):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))  # same networks for the same key
    with pytest.raises(ValueError, match="absorbing"):
        reward_init(key, 2, 2, cfg, absorbing="many")
    store = prefs_init(4, 3, 2, 2, absorbing=True)
    seg = AbsorbingSegments(*_seg(jnp.ones((2, 3)))[:4], jnp.array([[False, False, True], [False, False, False]]))
    data = prefs_add(store, seg, with_absorbing(seg, False), jnp.array([1.0, 0.0]), jnp.ones(2, bool))
    np.testing.assert_array_equal(np.asarray(data.seg_a.absorbed[:2]), np.asarray(seg.absorbed))
    assert not np.asarray(data.seg_b.absorbed).any()  # plain segments: none
    old = prefs_add(prefs_init(4, 3, 2, 2), seg, seg, jnp.array([1.0, 0.0]), jnp.ones(2, bool))
    assert type(old.seg_a) is Segments  # a plain store stays plain (EPS, PrefBias)


def test_training_learns_that_reaching_the_end_is_good(key):
    """Segments that end early (then absorb) are always preferred: r_abs must exceed the step rewards."""
    cfg = RewardConfig(members=2, hidden=(16,), updates=300, batch_size=32)
    k_init, k_len, k_x, k_train = jax.random.split(key, 4)
    steps = jax.random.randint(k_len, (2, 64), 1, 6)  # real steps of each segment of 5
    xs = jax.random.uniform(k_x, (2, 64, 5), minval=-1, maxval=1)
    mask = jnp.arange(5)[None, None, :] < steps[..., None]
    a, b = (AbsorbingSegments(*_seg(xs[i], mask[i])[:4], ~mask[i] & (steps[i] < 5)[:, None]) for i in range(2))
    labels = jnp.where(steps[0] == steps[1], 0.5, (steps[0] < steps[1]).astype(jnp.float32))
    data = prefs_add(prefs_init(64, 5, 2, 2, absorbing=True), a, b, labels, jnp.ones(64, bool))
    state = reward_init(k_init, 2, 2, cfg, absorbing="single")
    state, _, acc = train_reward(state, data, k_train, cfg)
    assert float(acc) > 0.9
    grid = jnp.stack([jnp.linspace(-1, 1, 9), jnp.zeros(9)], -1)
    r_abs = float(absorbing_reward(state.params, grid[:1])[0])
    assert r_abs > float(ensemble_reward(state.params, grid, 0 * grid, grid).max())


def test_absorbing_reward_stays_zero_where_no_segment_ended(key):
    """Compact features: training on pits at one place leaves r_abs elsewhere exactly 0 (Adam included)."""
    cfg = RewardConfig(members=2, hidden=(8,), updates=200, batch_size=16)
    k_init, k_x = jax.random.split(key)
    xs = jax.random.uniform(k_x, (2, 32, 4), minval=-0.2, maxval=0.2)
    mask = jnp.broadcast_to(jnp.array([True, False, False, False]), (32, 4))
    pit = AbsorbingSegments(*_seg(xs[0] - 0.5, mask)[:4], ~mask)  # every one ends at x ≈ −0.5 and absorbs
    alive = AbsorbingSegments(*_seg(xs[1])[:4], jnp.zeros((32, 4), bool))
    data = prefs_add(prefs_init(32, 4, 2, 2, absorbing=True), pit, alive, jnp.zeros(32), jnp.ones(32, bool))
    state = reward_init(k_init, 2, 2, cfg, absorbing="terminal")
    state, _, acc = train_reward(state, data, key, cfg)
    assert float(acc) == 1.0
    at = jnp.array([[-0.5, 0.0], [0.5, 0.0], [0.5, -0.5]])
    r_abs = np.asarray(absorbing_reward(state.params, at))
    assert r_abs[0] < -0.5  # where the episodes ended: bad
    np.testing.assert_array_equal(r_abs[1:], 0.0)  # far from it: untouched
    phi = np.asarray(absorbing_features(at, RBF_PER_AXIS**2))
    assert np.all((phi[1:, None, :] == 0) | (phi[0][None, None, :] == 0))  # disjoint supports


def test_a_terminal_absorbing_head_is_refused_beyond_three_dimensions(key):
    """16^d radial features: 4096 at d = 3; a hopper's 11 dimensions would need 16^11, so say what to use instead."""
    cfg = RewardConfig(members=2, hidden=(4,))
    assert reward_init(key, 3, 1, cfg, absorbing="terminal").params.absorb.shape == (2, 16**3)
    with pytest.raises(ValueError, match="at most 3 observation dimensions.*this world has 11"):
        reward_init(key, 11, 3, cfg, absorbing="terminal")
    assert reward_init(key, 11, 3, cfg, absorbing="single").params.absorb.shape == (2, 1)


def _constant_output(layers, value):
    """The MLP (or stack of MLPs) with its last layer's weights zeroed and its bias set to ``value``."""
    w, b = layers[-1]
    return (*layers[:-1], (jnp.zeros_like(w), jnp.full_like(b, value)))


def test_pebble_and_prefbias_rewards_share_one_soft_bound(key):
    """Both learned rewards are B·tanh(x/B) with the same B, wide enough for scores of several nats a step."""
    from mindgap.models.mlp import init_mlp
    from mindgap.models.prefbias_nets import reward_sizes, reward_value

    state = reward_init(key, 2, 2, RewardConfig(members=2, hidden=(8,)), absorbing="terminal")
    obs, act = jnp.zeros((1, 2)), jnp.zeros((1, 2))
    r_w = init_mlp(key, reward_sizes(2, 2, (8,)))
    for raw in (-40.0, -2.5, 0.3, 2.5, 40.0):
        pebble = float(member_rewards(_constant_output(state.params.net, raw), obs, act)[0, 0])
        prefbias = float(reward_value(_constant_output(r_w, raw), obs, act)[0])
        assert pebble == pytest.approx(prefbias, rel=1e-6)
        assert pebble == pytest.approx(REWARD_BOUND * np.tanh(raw / REWARD_BOUND), rel=1e-5)
    assert REWARD_BOUND >= 5.0  # a biased person's score of 2.5 nats a step is representable, nearly unsquashed
    assert float(member_rewards(_constant_output(state.params.net, 2.5), obs, act)[0, 0]) > 2.4
    far = state.params._replace(absorb=jnp.full_like(state.params.absorb, 100.0))
    assert float(member_absorbing_rewards(far, jnp.zeros((1, 2))).max()) == pytest.approx(REWARD_BOUND, rel=1e-5)
