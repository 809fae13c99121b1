"""Replay buffer writes, relabelling only the reward column, segments that stop at episode ends."""

import jax.numpy as jnp
import numpy as np

from mindgap.feedback.replay import relabel, replay_add, replay_init, replay_sample
from mindgap.feedback.segments import sample_segments


def _filled(n=10, capacity=16, episode=4, terminal_at=()):
    buf = replay_init(capacity, 2, 2)
    for i in range(n):
        o = jnp.array([i, 0.0])
        buf = replay_add(buf, o, jnp.array([0.1 * i, 0.0]), o + 1, float(i), -1.0, i in terminal_at, i % episode)
    return buf


def test_add_and_ring():
    buf = _filled(n=20, capacity=16)
    assert int(buf.size) == 16 and int(buf.ptr) == 4
    assert float(buf.obs[0, 0]) == 16.0  # the oldest were overwritten
    b = replay_sample(buf, __import__("jax").random.key(0), 8)
    assert b.obs.shape == (8, 2) and set(np.asarray(b.reward).tolist()) == {-1.0}


def test_relabel_changes_exactly_the_reward_column():
    buf = _filled(n=10)
    new = relabel(buf, lambda p, o, a, o2: p * o[:, 0] + a[:, 0], 2.0, chunk=4)
    for field in ("obs", "act", "next_obs", "env_reward", "terminal", "ep_step", "ptr", "size"):
        np.testing.assert_array_equal(np.asarray(getattr(new, field)), np.asarray(getattr(buf, field)))
    expect = 2.0 * np.arange(10) + 0.1 * np.arange(10)
    np.testing.assert_allclose(np.asarray(new.reward[:10]), expect, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(new.reward[10:]), np.asarray(buf.reward[10:]))  # empty slots untouched


def test_segments_never_cross_episodes_or_terminals(key):
    buf = _filled(n=16, capacity=16, episode=5, terminal_at=(7,))
    seg = sample_segments(buf, key, 200, 4)
    obs0 = np.asarray(seg.obs[:, :, 0]).astype(int)
    mask = np.asarray(seg.mask)
    assert mask[:, 0].all()
    for row, m in zip(obs0, mask):
        kept = row[m]
        assert np.all(np.diff(kept) == 1)  # consecutive transitions
        assert len({i // 5 for i in kept}) == 1  # one episode
        assert 7 not in kept[:-1]  # a terminal step can only be last
