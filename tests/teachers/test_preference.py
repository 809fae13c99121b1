"""The preference teacher: scores, the log T_H term, and B-Pref's knobs."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.data.segments import Segments
from mindgap.envs.terrain import load_world, observe
from mindgap.envs.terrain.params import TerrainState
from mindgap.teachers.preference import TeacherConfig, answer, segment_scores


def _segments(world, starts, action, length=6, key=None):
    """Segments driven with a constant action from each start, stepped in the true world."""
    from mindgap.envs.terrain import step

    step = jax.jit(step)  # called eagerly, its control flow would compile again at every call
    key = jax.random.key(0) if key is None else key
    obs, acts, nxt = [], [], []
    for i, (x, y) in enumerate(starts):
        s = TerrainState(jnp.array([x, y], jnp.float32), jnp.zeros((), jnp.int32), jnp.zeros((), bool))
        o, a, n = [], [], []
        for t in range(length):
            out = step(jax.random.fold_in(key, i * 100 + t), s, jnp.asarray(action), world.params)
            o.append(observe(s, world.params))
            a.append(jnp.asarray(action))
            n.append(observe(out.state, world.params))
            s = out.state
        obs.append(jnp.stack(o)), acts.append(jnp.stack(a)), nxt.append(jnp.stack(n))
    return Segments(jnp.stack(obs), jnp.stack(acts), jnp.stack(nxt), jnp.ones((len(starts), length), bool))


@pytest.fixture(scope="module")
def nav1():
    """nav1 with a sparse reward (−1 per step, no progress or distance term), so scores are easy to state."""
    w = load_world("nav1")
    zero = jnp.zeros((), jnp.float32)
    rewards = w.params.rewards._replace(progress=zero, distance=zero)
    return dataclasses.replace(w, params=w.params._replace(rewards=rewards))


def test_biased_person_prefers_sand_the_plain_teacher_does_not_care(nav1):
    ice = _segments(nav1, [(11.5, 1.5)] * 8, [-1.0, 0.0], key=jax.random.key(1))
    sand = _segments(nav1, [(11.5, 4.5)] * 8, [-1.0, 0.0], key=jax.random.key(2))
    cfg = TeacherConfig()
    s_ice = segment_scores(ice, nav1.env, nav1.params, nav1.belief(), cfg)
    s_sand = segment_scores(sand, nav1.env, nav1.params, nav1.belief(), cfg)
    assert float(s_sand.mean()) > float(s_ice.mean()) + 2  # log T_H: real ice moves look unlikely to the person
    plain = TeacherConfig(use_belief=False, beta=None)  # deterministic: a tie is answered 0.5
    np.testing.assert_allclose(segment_scores(ice, nav1.env, nav1.params, None, plain), -6.0)  # r_H only: −1 per step
    labels, answered = answer(jax.random.key(0), ice, sand, nav1.env, nav1.params, None, plain)
    assert np.all(np.asarray(labels) == 0.5) and bool(answered.all())  # equal returns: a tie


def _pairs(nav1, n=400):
    """n pairs whose scores differ clearly: moving toward vs away from the goal on d1-like progress."""
    long_ = _segments(nav1, [(12.5, 3.5)], [-1.0, 0.0], length=3)
    short = long_._replace(mask=long_.mask.at[:, 1:].set(False))  # 1 step instead of 3: return −1 vs −3

    def rep(s):
        return jax.tree.map(lambda x: jnp.repeat(x, n, 0), s)

    return rep(short), rep(long_)


def test_mistake_rate_flips_about_that_share(nav1):
    a, b = _pairs(nav1)
    clean, _ = answer(jax.random.key(0), a, b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False, beta=None))
    assert np.all(np.asarray(clean) == 1.0)
    noisy, _ = answer(
        jax.random.key(3), a, b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False, beta=None, mistake=0.1)
    )
    flipped = float(np.mean(np.asarray(noisy) == 0.0))
    assert 0.07 < flipped < 0.13  # 400 answers: ±3 standard deviations around 0.1


def test_the_default_person_answers_by_bradley_terry_with_a_finite_beta(nav1):
    """Eq. 3.4 with β = 1 by default: a return gap of 2 is answered the right way about 88% of the time.

    Hard (β = ∞) labels would leave the score's scale, hence the belief, unidentified."""
    assert TeacherConfig().beta == 1.0
    a, b = _pairs(nav1)
    labels, _ = answer(jax.random.key(5), a, b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False))
    assert 0.82 < float(np.mean(np.asarray(labels))) < 0.94  # σ(2) ≈ 0.88; 400 answers


def test_rationality_equal_skip_and_myopia(nav1):
    a, b = _pairs(nav1)
    cfg = TeacherConfig(use_belief=False, beta=1.0)  # σ(1 · 2) ≈ 0.88 for a return gap of 2
    labels, _ = answer(jax.random.key(4), a, b, nav1.env, nav1.params, None, cfg)
    assert 0.82 < float(np.mean(np.asarray(labels))) < 0.94
    eq, _ = answer(jax.random.key(4), a, b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False, equal=0.9))
    assert np.all(np.asarray(eq) == 0.5)  # |−1 − (−3)| = 2 < 0.9 · 3
    _, answered = answer(
        jax.random.key(4), a, b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False, skip=0.5)
    )
    assert not bool(answered.any())  # max score −1 < 0.5 · 3 ... all skipped (negative returns)
    myopic = segment_scores(b, nav1.env, nav1.params, None, TeacherConfig(use_belief=False, gamma=0.5))
    np.testing.assert_allclose(np.asarray(myopic), -(0.25 + 0.5 + 1.0))
