"""PrefBias's query samplers on hand-made candidates and on a replay buffer."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from mindgap.algorithms.prefbias_inference import PrefBiasConfig, PrefBiasState
from mindgap.algorithms.prefbias_queries import (
    SAMPLERS,
    bernoulli_kl,
    candidate_scores,
    posterior_preferences,
    preference_disagreement,
    select_queries,
)
from mindgap.data.replay import Replay
from mindgap.data.segments import Segments, sample_segments, take
from mindgap.models.bayes import init_gaussian
from mindgap.models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_sizes
from mindgap.models.mlp import init_mlp
from mindgap.models.prefbias_nets import reward_sizes

OUT_STD, MIN_STD = 0.1, 0.01
CFG = PrefBiasConfig(
    reward_hidden=(4,), dynamics=DynamicsConfig(hidden=(4,), min_std=MIN_STD), absorbing=False, stay_head=False
)
NORM = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.full(2, OUT_STD))


def _constant_gaussian(key, std_raw: float):
    """Dynamics parameters that predict "no move" with scale OUT_STD · (MIN_STD + softplus(std_raw)) everywhere."""
    params = init_mlp(key, dynamics_sizes(2, 2, (4,)))
    w, _ = params[-1]
    return params[:-1] + ((w * 0, jnp.array([0.0, 0.0, std_raw, std_raw])),)


_scores = jax.jit(candidate_scores, static_argnames=("sampler", "cfg", "samples"))


def _models(key, reward_sigma=1e-6):
    k_w, k_psi = jax.random.split(key)
    w = init_mlp(k_w, reward_sizes(2, 2, (4,)))
    w = w[:-1] + ((w[-1][0], w[-1][1] * 0),)  # a reward that depends on (s, a): weight draws disagree
    psi = DynamicsModel(_constant_gaussian(k_psi, 0.0), NORM)  # scale ≈ 0.070
    phi = _constant_gaussian(k_psi, 2.0)  # the person: scale ≈ 0.214, so surprises matter less
    state = PrefBiasState(init_gaussian(w, reward_sigma), init_gaussian(phi, 1e-6), w, phi, NORM, (), ())
    return state, psi


def _candidates():
    """Three pairs of 2-step segments at one place: identical; exact vs 3σ_ψ off; exact vs σ_ψ/2 off."""
    obs = jnp.zeros((3, 2, 2))
    act = jnp.zeros((3, 2, 2))
    sigma_psi = OUT_STD * (MIN_STD + np.log(2))
    off = jnp.array([0.0, 3 * sigma_psi, 0.5 * sigma_psi])[:, None, None] * jnp.array([1.0, 0.0])
    mask = jnp.ones((3, 2), bool)
    seg_a = Segments(obs, act, obs, mask)
    seg_b = Segments(obs, act, obs + off, mask)
    return seg_a, seg_b, np.asarray(off[:, 0, 0])


def test_preference_disagreement_by_hand(key):
    state, psi = _models(key)
    seg_a, seg_b, off = _candidates()
    got = np.asarray(preference_disagreement(state, psi, seg_a, seg_b, CFG))

    def prob(std):  # the reward is the same for both segments (same s, a), so only the belief counts
        gap = 2 * (stats.norm.logpdf(0.0, 0.0, std) - stats.norm.logpdf(off, 0.0, std))
        return 1 / (1 + np.exp(-gap))

    p_agent = prob(OUT_STD * (MIN_STD + np.log1p(np.exp(0.0))))
    p_person = prob(OUT_STD * (MIN_STD + np.log1p(np.exp(2.0))))
    expect = p_agent * np.log(p_agent / p_person) + (1 - p_agent) * np.log((1 - p_agent) / (1 - p_person))
    np.testing.assert_allclose(got, expect, rtol=1e-3, atol=1e-7)
    assert got[0] == 0.0  # identical segments: both predict ½
    assert np.argmax(got) == 1 and got[1] > 10 * got[2]  # the 3σ surprise divides the two models most
    # the agent's model and the person's agreeing gives no disagreement at all
    same = state._replace(belief=init_gaussian(psi.params, 1e-6))
    np.testing.assert_allclose(np.asarray(preference_disagreement(same, psi, seg_a, seg_b, CFG)), 0.0, atol=1e-6)


def test_bernoulli_kl():
    np.testing.assert_allclose(bernoulli_kl(jnp.array(0.5), jnp.array(0.5)), 0.0, atol=1e-7)
    np.testing.assert_allclose(
        bernoulli_kl(jnp.array(0.9), jnp.array(0.5)), 0.9 * np.log(1.8) + 0.1 * np.log(0.2), rtol=1e-5
    )
    assert np.isfinite(float(bernoulli_kl(jnp.array(1.0), jnp.array(0.0))))


def test_disagreement_and_entropy_over_posterior_draws(key):
    seg_a, seg_b, _ = _candidates()
    # move the second segment of pair 1 and 2 elsewhere, so that the reward differs between sides
    seg_b = seg_b._replace(obs=seg_b.obs.at[1:].add(0.5), next_obs=seg_b.next_obs.at[1:].add(0.5))
    wide, psi = _models(key, reward_sigma=0.5)
    draws = jax.jit(posterior_preferences, static_argnames=("samples", "cfg"))
    probs = np.asarray(draws(wide, seg_a, seg_b, jax.random.fold_in(key, 1), samples=64, cfg=CFG))
    assert probs.shape == (64, 3)
    np.testing.assert_allclose(probs[:, 0], 0.5)  # one draw judges both sides of an identical pair
    dis = np.asarray(_scores(wide, psi, seg_a, seg_b, jax.random.fold_in(key, 1), "disagreement", CFG, 64))
    assert dis[0] == 0.0 and np.all(dis[1:] > 0.01)
    ent = np.asarray(_scores(wide, psi, seg_a, seg_b, jax.random.fold_in(key, 1), "entropy", CFG, 64))
    np.testing.assert_allclose(ent[0], np.log(2), rtol=1e-5)
    assert np.all(ent[1:] < ent[0])
    # a near-certain posterior: draws agree
    narrow, _ = _models(key, reward_sigma=1e-6)
    dis = np.asarray(_scores(narrow, psi, seg_a, seg_b, jax.random.fold_in(key, 1), "disagreement", CFG, 64))
    assert np.all(dis < 1e-4)
    with pytest.raises(ValueError, match="unknown sampler"):
        candidate_scores(narrow, psi, seg_a, seg_b, key, "greedy", CFG)


def _replay(key, n=60, episode=10):
    k_o, k_a = jax.random.split(key)
    obs = jax.random.uniform(k_o, (n, 2), minval=-1, maxval=1)
    act = jax.random.uniform(k_a, (n, 2), minval=-1, maxval=1)
    step = jnp.arange(n) % episode
    return Replay(
        obs, act, obs + 0.05 * act, jnp.zeros(n), jnp.zeros(n), step == episode - 1, step.astype(jnp.int32),
        jnp.asarray(0, jnp.int32), jnp.asarray(n, jnp.int32),
    )  # fmt: skip


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_select_queries_keeps_the_best_of_the_candidates(key, sampler):
    state, psi = _models(key, reward_sigma=0.3)
    buf = _replay(key)
    k, length, candidates = 4, 3, 3
    select = jax.jit(select_queries, static_argnames=("k", "length", "sampler", "cfg", "candidates", "samples"))
    q_key = jax.random.fold_in(key, 7)
    seg_a, seg_b = select(q_key, buf, state, psi, k=k, length=length, sampler=sampler, cfg=CFG, candidates=candidates)
    assert seg_a.obs.shape == (k, length, 2) and seg_b.mask.shape == (k, length)
    ka, kb, ks = jax.random.split(q_key, 3)
    m = k if sampler == "uniform" else k * candidates
    all_a, all_b = sample_segments(buf, ka, m, length), sample_segments(buf, kb, m, length)
    if sampler == "uniform":
        np.testing.assert_array_equal(seg_a.obs, all_a.obs)
        return
    scores = np.asarray(_scores(state, psi, all_a, all_b, ks, sampler, CFG))
    top = np.argsort(-scores)[:k]
    np.testing.assert_allclose(seg_a.obs, take(all_a, jnp.asarray(top)).obs)
    np.testing.assert_allclose(seg_b.obs, take(all_b, jnp.asarray(top)).obs)
    assert scores[top].min() >= np.delete(scores, top).max()


def test_select_queries_rejects_an_unknown_sampler(key):
    state, psi = _models(key)
    with pytest.raises(ValueError, match="unknown sampler"):
        select_queries(key, _replay(key), state, psi, 2, 3, "greedy", CFG)
