"""Replay buffer writes, relabelling only the reward column, segments that stop at episode ends."""

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.data.replay import relabel, replay_add, replay_init, replay_sample
from mindgap.data.segments import sample_segments


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


def test_segments_from_the_start_begin_at_every_stored_episode_start_and_only_there(key):
    buf = _filled(n=20, capacity=16, episode=5)  # a wrapped ring: transitions 4 … 19 kept, starts 5, 10, 15
    seg = sample_segments(buf, key, 600, 3, from_start=True)
    first = np.asarray(seg.obs[:, 0, 0]).astype(int)
    assert set(first.tolist()) == {5, 10, 15}
    counts = np.bincount(first)[[5, 10, 15]]
    assert counts.min() > 600 / 3 - 4 * np.sqrt(600 * (1 / 3) * (2 / 3))  # uniform among the starts, 4 sd
    assert np.asarray(seg.mask).all()  # three steps fit in every episode
    # a buffer without any episode start falls back to starting anywhere
    mid = replay_init(8, 2, 2)
    for i in range(6):
        o = jnp.array([i, 0.0])
        mid = replay_add(mid, o, jnp.zeros(2), o + 1, 0.0, 0.0, False, i + 3)
    anywhere = np.asarray(sample_segments(mid, key, 200, 2, from_start=True).obs[:, 0, 0]).astype(int)
    assert set(anywhere.tolist()) <= set(range(6)) and len(set(anywhere.tolist())) > 1


def test_queries_from_the_start_are_picked_among_episode_starts(key):
    from mindgap.feedback.queries import select_queries

    buf = _filled(n=16, capacity=16, episode=4)

    def probs(seg_a, seg_b):  # a one-member "ensemble" that is least sure about the last pairs
        return jnp.linspace(0.0, 0.5, seg_a.obs.shape[0])[None, :]

    seg_a, seg_b = select_queries(key, buf, probs, 5, 3, "entropy", 4, from_start=True)
    for seg in (seg_a, seg_b):
        assert seg.obs.shape == (5, 3, 2)
        assert set(np.asarray(seg.obs[:, 0, 0]).astype(int).tolist()) <= {0, 4, 8, 12}


def _nstep_reference(buf, i, n, gamma):
    """Plain-Python n-step transition starting at slot i (written independently of the jitted code)."""
    buf = jax.tree.map(np.asarray, buf)
    cap, ptr = buf.obs.shape[0], int(buf.ptr)
    stored_after = (ptr - 1 - i) % cap
    r, last, m = 0.0, i, 0
    for k in range(n):
        j = (i + k) % cap
        if k > 0 and (stored_after < k or int(buf.ep_step[j]) != int(buf.ep_step[i]) + k or bool(buf.terminal[last])):
            break
        r += gamma**k * float(buf.reward[j])
        last, m = j, k + 1
    return r, float(buf.next_obs[last, 0]), float(buf.terminal[last]), gamma**m


def test_nstep_sums_stop_at_episode_ends_terminals_and_the_newest_entry():
    # 20 writes into 16 slots: episodes of 4 steps, one ending in a terminal state at write 9,
    # and the ring wrapped, so slot 3 (the newest) has nothing stored after it.
    buf = _filled(n=20, capacity=16, terminal_at=(9,))
    buf = buf._replace(reward=jnp.arange(16, dtype=jnp.float32) * 0.5 - 3.0)
    b = jax.tree.map(np.asarray, replay_sample(buf, jax.random.key(1), 512, n_step=3, gamma=0.9))
    slots = b.obs[:, 0].astype(int) % 16
    assert len(set(slots.tolist())) == 16  # every slot checked
    for s, r, nxt, term, disc in zip(slots, b.reward, b.next_obs[:, 0], b.terminal, b.discount):
        want = _nstep_reference(buf, int(s), 3, 0.9)
        np.testing.assert_allclose([float(r), float(nxt), float(term), float(disc)], want, rtol=1e-5)
    # the cases the test is about do occur: a full 3-step sum, a cut at a terminal, one at the newest entry
    discs = {int(s): float(d) for s, d in zip(slots, b.discount)}
    assert np.isclose(discs[0], 0.9**3) and np.isclose(discs[9 % 16], 0.9) and np.isclose(discs[3], 0.9)


def test_nstep_of_one_is_the_plain_sample():
    buf = _filled(n=10)
    k = jax.random.key(2)
    a, b = replay_sample(buf, k, 32), replay_sample(buf, k, 32, n_step=1)
    for x, y in zip(a[:5], b[:5]):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert a.discount is None
