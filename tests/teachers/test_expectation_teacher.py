"""The expectation teacher of EPS: its score, its answers, and the on-disk cache of π_H."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.algorithms import expected_policy as ep
from mindgap.algorithms.expected_policy import expectation_teacher
from mindgap.data.segments import Segments
from mindgap.envs.terrain import load_world, observe, position
from mindgap.envs.terrain.params import TerrainState
from mindgap.models.actor import sample_action
from mindgap.models.squashed import squashed_log_prob
from mindgap.teachers.expectation import ExpectationTeacher, answer, expected_log_prob, segment_scores
from mindgap.teachers.preference import TeacherConfig, labels_from_scores


def linear_actor(mean_bias, log_std, gain=0.0):
    """A one-layer actor: pre-tanh mean ``gain · obs + mean_bias``, constant ``log_std``."""
    w = jnp.zeros((2, 4)).at[0, 0].set(gain).at[1, 1].set(gain)
    b = jnp.concatenate([jnp.asarray(mean_bias, jnp.float32), jnp.full(2, log_std, jnp.float32)])
    return ((w, b),)


@pytest.fixture(scope="module")
def d1():
    return load_world("d1")


def _segment(world, positions, actions):
    """One segment from positions [L+1, 2] (x, y) and actions [L, 2]."""
    pos = jnp.asarray(positions, jnp.float32)
    obs = jax.vmap(lambda p: observe(TerrainState(p, 0, False), world.params))(pos)
    return Segments(
        obs[None, :-1], jnp.asarray(actions, jnp.float32)[None], obs[None, 1:], jnp.ones((1, len(actions)), bool)
    )


def test_squashed_density_matches_the_sampler_and_the_formula(key):
    actor = linear_actor([0.3, -2.0], -0.5, gain=0.7)
    obs = jax.random.uniform(key, (64, 2), minval=-1, maxval=1)
    act, logp = jax.jit(sample_action)(actor, obs, jax.random.fold_in(key, 1))
    mean = 0.7 * obs + jnp.array([0.3, -2.0])
    np.testing.assert_allclose(jax.jit(squashed_log_prob)(mean, jnp.full(2, -0.5), act), logp, rtol=1e-4, atol=1e-3)
    a = np.array([0.2, -0.9])
    u = np.arctanh(a)
    std = np.exp(-0.5)
    by_hand = np.sum(-0.5 * ((u - [0.3, -2.0]) / std) ** 2 - np.log(std * np.sqrt(2 * np.pi)) - np.log(1 - a**2))
    np.testing.assert_allclose(
        float(squashed_log_prob(jnp.array([0.3, -2.0]), jnp.full(2, -0.5), a)), by_hand, rtol=1e-5
    )
    assert np.isfinite(float(squashed_log_prob(jnp.zeros(2), jnp.zeros(2), jnp.ones(2))))  # saturated action


K = 100  # segments scored per call in every test below, so that they share one compiled program


def _tile(seg, n=K):
    return jax.tree.map(lambda x: jnp.repeat(x, n, 0), seg)


def _log_t_by_hand(s, a, s2):
    """log T_H of a move on d1's floor under the person's belief: N(s + a/2, σ²), σ = 0.05 + e^{−d(s)},
    d the distance to the pit cell x ∈ [3, 4], y ∈ [1, 2] (belief: pit_noise 1, pit_scale 1; stuck 0)."""
    gap = np.maximum(np.maximum(np.array([3.0, 1.0]) - s, 0.0), s - np.array([4.0, 2.0]))
    sigma = 0.05 + np.exp(-np.linalg.norm(gap))
    z = (s2 - (s + 0.5 * a)) / sigma
    return -np.log(2 * np.pi * sigma**2) - 0.5 * np.sum(z**2)


def _log_pi_by_hand(a, mean, log_std):
    u = np.arctanh(a)
    std = np.exp(log_std)
    return np.sum(-0.5 * ((u - mean) / std) ** 2 - np.log(std * np.sqrt(2 * np.pi)) - np.log(1 - a**2))


def test_score_is_the_sum_of_log_t_and_log_pi_under_the_mask(d1):
    teacher = ExpectationTeacher(d1.belief(), linear_actor([1.0, 0.0], -1.0), d1.env)
    actions = np.array([(0.8, 0.2), (0.9, 0.0), (0.95, -0.2)])
    positions = [np.array([1.5, 4.5])]
    for a, off in zip(actions, [(0.03, -0.02), (-0.01, 0.04), (0.0, 0.05)]):
        positions.append(positions[-1] + 0.5 * a + np.asarray(off))
    per_step = [
        max(_log_t_by_hand(positions[t], actions[t], positions[t + 1]), -20.0)
        + max(_log_pi_by_hand(actions[t], np.array([1.0, 0.0]), -1.0), -20.0)
        for t in range(3)
    ]
    seg = _segment(d1, positions, actions)
    short = seg._replace(mask=seg.mask.at[:, 2].set(False))  # the episode ended after two steps
    scores = segment_scores(
        _tile(jax.tree.map(lambda a, b: jnp.concatenate([a, b]), seg, short), K // 2), teacher, TeacherConfig()
    )
    np.testing.assert_allclose(scores[0], sum(per_step), rtol=1e-4)
    np.testing.assert_allclose(scores[K // 2], sum(per_step[:2]), rtol=1e-4)
    np.testing.assert_allclose(position(seg.obs[0, 0], d1.params), positions[0], rtol=1e-6)


def test_relative_scores_need_a_discrete_action_space(d1):
    """A continuous π_H has no most expected action to score against: one clear error."""
    teacher = ExpectationTeacher(d1.belief(), linear_actor([1.0, 0.0], -1.0), d1.env)
    seg = _segment(d1, [np.array([2.5, 3.5]), np.array([2.88, 3.5])], [np.array([0.76, 0.0])])
    with pytest.raises(ValueError, match="relative expectation scores need a discrete action space"):
        segment_scores(seg, teacher, TeacherConfig(relative=True))


def test_the_person_prefers_what_their_policy_would_do_and_the_knobs_apply(d1):
    teacher = ExpectationTeacher(d1.belief(), linear_actor([1.0, 0.0], -1.0), d1.env)  # expects pushes to the right
    start = np.array([2.5, 3.5])
    right, left = np.array([0.76, 0.0]), np.array([-0.76, 0.0])
    seg_r = _tile(_segment(d1, [start + 0.38 * t * right / 0.76 for t in range(4)], [right] * 3), K // 2)
    seg_l = _tile(
        _segment(d1, [start + 0.38 * t * left / 0.76 for t in range(4)], [left] * 3), K // 2
    )  # 0.5 · a a step
    labels, answered = answer(jax.random.key(0), seg_r, seg_l, teacher, TeacherConfig())
    assert labels.shape == (K // 2,) and np.all(np.asarray(labels) == 1.0) and bool(answered.all())
    # the knobs act on the scores as for the preference teacher (labels_from_scores is shared)
    both = segment_scores(jax.tree.map(lambda a, b: jnp.concatenate([a, b]), seg_r, seg_l), teacher, TeacherConfig())
    sr, sl = jnp.repeat(both[:1], K, 0), jnp.repeat(both[-1:], K, 0)
    assert float(sr[0] - sl[0]) > 10
    flipped, _ = labels_from_scores(jax.random.key(0), sr, sl, TeacherConfig(mistake=1.0))
    assert np.all(np.asarray(flipped) == 0.0)
    soft, _ = labels_from_scores(jax.random.key(1), jnp.tile(sr, 4), jnp.tile(sl, 4), TeacherConfig(beta=1e-3))
    assert 0.4 < float(np.mean(np.asarray(soft))) < 0.65  # β → 0: nearly a coin flip


def _fake_trainer(calls):
    def train(world, belief_params, cfg):
        calls.append(ep.cache_key(belief_params, cfg))
        actor = jax.tree.map(lambda x: x + len(calls), ep._actor_template(world.env, cfg))
        return actor, np.zeros(cfg.seeds)

    return train


def test_the_cache_trains_once_per_world_and_belief(d1, tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(ep, "train_expected_policy", _fake_trainer(calls))
    cfg = ep.ExpectedPolicyConfig.fast()
    first = ep.expected_policy(d1, d1.belief(), cfg, cache_dir=tmp_path)
    again = ep.expected_policy(d1, d1.belief(), cfg, cache_dir=tmp_path)
    assert len(calls) == 1  # the second call read the file
    jax.tree.map(np.testing.assert_array_equal, first, again)
    assert (tmp_path / "expected_policy" / f"{calls[0]}.npz").exists()
    teacher = expectation_teacher(d1, cache_dir=tmp_path, policy_cfg=cfg)  # the same person through the teacher
    assert len(calls) == 1
    jax.tree.map(np.testing.assert_array_equal, teacher.policy, first)
    ep.expected_policy(d1, d1.params, cfg, cache_dir=tmp_path)  # a person without bias: another key
    ep.expected_policy(d1, d1.belief(), dataclasses.replace(cfg, seed=1), cache_dir=tmp_path)  # another configuration
    other = load_world("d2")
    ep.expected_policy(other, other.belief(), cfg, cache_dir=tmp_path)  # another world
    assert len(calls) == 4 and len(set(calls)) == 4
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path))
    ep.expected_policy(d1, d1.belief(), cfg)  # $MINDGAP_CACHE is the default root
    assert len(calls) == 4


def test_default_trainer_runs_and_its_policy_is_stored(d1, tmp_path):
    cfg = ep.ExpectedPolicyConfig.fast()
    actor = ep.expected_policy(d1, d1.belief(), cfg, cache_dir=tmp_path)
    assert [w.shape for w, _ in actor] == [(2, 8), (8, 4)]  # obs → hidden → (mean, log std)
    assert all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree.leaves(actor))
    with np.load(next((tmp_path / "expected_policy").glob("*.npz"))) as f:
        assert f["extra_returns"].shape == (cfg.seeds,)
    again = ep.expected_policy(d1, d1.belief(), cfg, cache_dir=tmp_path)
    jax.tree.map(np.testing.assert_array_equal, actor, again)
    obs = jnp.zeros((3, 2))
    assert np.all(np.isfinite(np.asarray(expected_log_prob(actor, obs, jnp.full((3, 2), 0.5)))))
