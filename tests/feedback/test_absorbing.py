"""Absorbing steps (Kostrikov et al. 2019): segments keep the steps after a terminal, the person ignores them."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.data.replay import replay_add, replay_init
from mindgap.data.segments import (
    AbsorbingSegments,
    Segments,
    absorbed_steps,
    sample_segments,
    with_absorbing,
)
from mindgap.envs.terrain import load_world, observe, step
from mindgap.envs.terrain.params import TerrainState
from mindgap.teachers.preference import TeacherConfig
from mindgap.teachers.preference import segment_scores as _segment_scores

segment_scores = jax.jit(_segment_scores, static_argnames=("env", "cfg"))

# slot:      0  1  2 | 3  4  5  6 | 7  8  9 (newest; 10.. empty)
EP_STEP = [0, 1, 2, 0, 1, 2, 3, 0, 1, 2]
TERMINAL = [False, False, True, False, False, False, False, False, False, True]
# slot 2 reaches the goal (terminal); slot 6 is the last step before the horizon (truncated,
# not terminal); slot 9, the newest stored transition, falls into a pit.


def _buffer(capacity=16):
    buf = replay_init(capacity, 2, 2)
    for i, (t, term) in enumerate(zip(EP_STEP, TERMINAL)):
        o = jnp.array([i, 0.0])
        buf = replay_add(buf, o, jnp.zeros(2), o + 1, 0.0, 0.0, term, t)
    return buf


def _reference(start, length, capacity=16, size=10):
    """mask and absorbed of the segment starting at slot ``start``, by hand."""
    mask, absorbed = [], []
    ended = truncated = False
    for k in range(length):
        j = (start + k) % capacity
        stored = j < size
        same_episode = stored and EP_STEP[j] == EP_STEP[start] + k
        real = not ended and not truncated and same_episode
        if not real and not ended:
            truncated = True
        mask.append(real)
        absorbed.append(ended)
        if real and TERMINAL[j]:
            ended = True
    return mask, absorbed


@pytest.mark.parametrize("length", [2, 4, 6])
def test_absorbed_steps_follow_terminals_only(length):
    buf = _buffer()
    key = jax.random.key(3)
    seg = sample_segments(buf, key, 300, length, absorbing=True)
    plain = sample_segments(buf, key, 300, length)
    assert isinstance(seg, AbsorbingSegments) and isinstance(plain, Segments)
    np.testing.assert_array_equal(np.asarray(seg.mask), np.asarray(plain.mask))  # masks as before
    for f in ("obs", "act", "next_obs"):
        np.testing.assert_array_equal(np.asarray(getattr(seg, f)), np.asarray(getattr(plain, f)))
    starts = np.asarray(seg.obs[:, 0, 0]).astype(int)
    assert set(starts) == set(range(10))  # every start was drawn
    for row, s in enumerate(starts):
        mask, absorbed = _reference(s, length)
        np.testing.assert_array_equal(np.asarray(seg.mask[row]), mask, err_msg=f"start {s}")
        np.testing.assert_array_equal(np.asarray(seg.absorbed[row]), absorbed, err_msg=f"start {s}")
    assert not np.any(np.asarray(seg.mask) & np.asarray(seg.absorbed))


def test_hand_picked_segments():
    buf = _buffer()
    seg = sample_segments(buf, jax.random.key(0), 300, 4, absorbing=True)
    starts = np.asarray(seg.obs[:, 0, 0]).astype(int)

    def row(s):
        i = int(np.flatnonzero(starts == s)[0])
        return np.asarray(seg.mask[i]).tolist(), np.asarray(seg.absorbed[i]).tolist()

    # the goal at slot 2: the two steps after it are absorbing
    assert row(1) == ([True, True, False, False], [False, False, True, True])
    # the horizon after slot 6: masked out, nothing absorbing
    assert row(5) == ([True, True, False, False], [False, False, False, False])
    # a pit at the newest transition: the empty slots after it are absorbing too
    assert row(8) == ([True, True, False, False], [False, False, True, True])
    # no end inside
    assert row(3) == ([True, True, True, True], [False, False, False, False])


def test_plain_segments_have_no_absorbing_steps():
    seg = Segments(jnp.zeros((2, 3, 2)), jnp.zeros((2, 3, 2)), jnp.zeros((2, 3, 2)), jnp.ones((2, 3), bool))
    assert not np.asarray(absorbed_steps(seg)).any() and absorbed_steps(seg).shape == (2, 3)
    both = with_absorbing(seg, True)
    assert isinstance(both, AbsorbingSegments) and not np.asarray(both.absorbed).any()
    back = with_absorbing(both._replace(absorbed=jnp.ones((2, 3), bool)), False)
    assert type(back) is Segments and back.env_reward is None


@pytest.fixture(scope="module")
def d1():
    return load_world("d1")


def _into_goal(world):
    """One segment of 5 steps: two real steps, the second entering the goal, then three absorbing steps.

    The absorbing steps hold a transition that would score highly if it counted (another
    entry into the goal), as the buffer would hold the next episode's steps there.
    Returns (segment, the world's own rewards of the two real steps).
    """
    s = TerrainState(jnp.array([4.2, 1.5], jnp.float32), jnp.zeros((), jnp.int32), jnp.zeros((), bool))
    a = jnp.array([1.0, 0.0])
    obs, act, nxt, rewards = [], [], [], []
    for t in range(2):
        out = jax.jit(step)(jax.random.key(t), s, a, world.params)
        obs.append(observe(s, world.params)), act.append(a), nxt.append(observe(out.state, world.params))
        rewards.append(float(out.reward))
        s = out.state
    assert bool(out.terminated) and rewards[-1] > 50  # the second step reached the goal
    obs, act, nxt = (jnp.stack(x + [x[-1]] * 3)[None] for x in (obs, act, nxt))
    mask = jnp.array([[True, True, False, False, False]])
    return AbsorbingSegments(obs, act, nxt, mask, ~mask), rewards


def test_the_person_scores_absorbing_steps_as_zero(d1):
    seg, rewards = _into_goal(d1)
    plain = with_absorbing(seg, False)
    for belief, cfg in ((None, TeacherConfig(use_belief=False)), (d1.belief(), TeacherConfig())):
        got = float(segment_scores(seg, d1.env, d1.params, belief, cfg)[0])
        assert got == float(segment_scores(plain, d1.env, d1.params, belief, cfg)[0])  # absorbed steps add nothing
        counted = with_absorbing(seg._replace(mask=jnp.ones_like(seg.mask)), False)
        assert float(segment_scores(counted, d1.env, d1.params, belief, cfg)[0]) > got + 100  # they would, if counted
    plain_cfg = TeacherConfig(use_belief=False)
    np.testing.assert_allclose(
        float(segment_scores(seg, d1.env, d1.params, None, plain_cfg)[0]), sum(rewards), rtol=1e-5
    )
    myopic = dataclasses.replace(plain_cfg, gamma=0.5)  # step t of L counts γ^(L−1−t); absorbed ones still 0
    expect = 0.5**4 * rewards[0] + 0.5**3 * rewards[1]
    np.testing.assert_allclose(float(segment_scores(seg, d1.env, d1.params, None, myopic)[0]), expect, rtol=1e-5)
