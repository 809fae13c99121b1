"""PrefBias inference: the preference likelihood by hand, the ELBO, fitting under jit/vmap, a planted belief."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from mindgap.algorithms.prefbias_inference import (
    PrefBiasConfig,
    PrefBiasState,
    bt_cross_entropy,
    fit,
    negative_elbo,
    prefbias_init,
    preference_prob,
    scores_fixed,
    with_dynamics,
)
from mindgap.data.prefs import PrefData
from mindgap.data.segments import AbsorbingSegments, Segments
from mindgap.envs.terrain import TerrainState, load_world, observe, step
from mindgap.envs.terrain.layout import FLOOR, ICE, SAND
from mindgap.models.bayes import init_gaussian
from mindgap.models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_sizes, train_dynamics
from mindgap.models.mlp import init_mlp
from mindgap.models.prefbias_nets import (
    RewardWeights,
    absorbing_value,
    reward_sizes,
)
from mindgap.models.reward_ensemble import REWARD_BOUND
from mindgap.planning.terrain_maps import belief_noise_map, table_noise_map
from mindgap.teachers.preference import TeacherConfig, answer

PLAIN = dict(absorbing=False, stay_head=False)
"""The plain model (Gaussian belief, no absorbing states) that most checks here are written for."""


def _np_mlp(params, x):
    for i, (w, b) in enumerate(params):
        x = x @ np.asarray(w, np.float64) + np.asarray(b, np.float64)
        if i < len(params) - 1:
            x = np.maximum(x, 0.0)
    return x


def _np_score(w, phi, norm, obs, act, nxt, mask, min_std, floor=-np.inf):
    """Σ_t [r(s_t, a_t) + max(log N(s_{t+1}; mean, std), floor)] over unmasked steps, in plain NumPy and SciPy."""
    obs, act, nxt = (np.asarray(x, np.float64) for x in (obs, act, nxt))
    in_mean, in_std, out_mean, out_std = (np.asarray(x, np.float64) for x in norm)
    x = np.concatenate([obs, act], -1)
    r = REWARD_BOUND * np.tanh(_np_mlp(w, x)[:, 0] / REWARD_BOUND)
    raw = _np_mlp(phi, (x - in_mean) / in_std)
    mean = obs + out_mean + out_std * raw[:, :2]
    std = out_std * (min_std + np.log1p(np.exp(raw[:, 2:])))
    log_f = np.maximum(stats.norm.logpdf(nxt, mean, std).sum(-1), floor)
    return float(np.sum((r + log_f)[np.asarray(mask)]))


def _tiny_problem(key):
    """Random small networks, a non-trivial normalisation and one pair of 2-step segments."""
    k_w, k_phi, k_seg = jax.random.split(key, 3)
    w = init_mlp(k_w, reward_sizes(2, 2, (5,)))
    phi = init_mlp(k_phi, dynamics_sizes(2, 2, (6,)))
    norm = Norm(
        jnp.array([0.1, -0.1, 0.0, 0.2]),
        jnp.array([0.5, 0.6, 0.7, 0.8]),
        jnp.array([0.01, 0.0]),
        jnp.array([0.05, 0.08]),
    )
    obs = jax.random.uniform(k_seg, (2, 1, 2, 2), minval=-1, maxval=1)  # [side, K=1, L=2, d]
    act = jax.random.uniform(jax.random.fold_in(k_seg, 1), (2, 1, 2, 2), minval=-1, maxval=1)
    nxt = obs + 0.05 * act + 0.03 * jax.random.normal(jax.random.fold_in(k_seg, 2), obs.shape)
    mask = jnp.array([[[True, True]], [[True, False]]])  # the second segment ends after one step
    seg_a, seg_b = (Segments(obs[i], act[i], nxt[i], mask[i]) for i in range(2))
    return w, phi, norm, seg_a, seg_b


def test_preference_likelihood_matches_hand_computation(key):
    """Eq. 3.4–3.5: p̂(a ≻ b) = σ(S_a − S_b), S = Σ_t r_w + log f_φ, against NumPy/SciPy."""
    w, phi, norm, seg_a, seg_b = _tiny_problem(key)
    cfg = PrefBiasConfig(reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,), min_std=0.02), **PLAIN)
    s_a = _np_score(w, phi, norm, seg_a.obs[0], seg_a.act[0], seg_a.next_obs[0], seg_a.mask[0], 0.02)
    s_b = _np_score(w, phi, norm, seg_b.obs[0], seg_b.act[0], seg_b.next_obs[0], seg_b.mask[0], 0.02)
    p = 1.0 / (1.0 + np.exp(-(s_a - s_b)))
    assert 1e-4 < p < 1 - 1e-4  # a pair the likelihood does not saturate on
    np.testing.assert_allclose(float(preference_prob(w, phi, norm, seg_a, seg_b, cfg)[0]), p, rtol=1e-4)
    np.testing.assert_allclose(float(preference_prob(w, phi, norm, seg_b, seg_a, cfg)[0]), 1 - p, rtol=1e-4)
    for y in (1.0, 0.0, 0.5):
        expect = -(y * np.log(p) + (1 - y) * np.log(1 - p))
        np.testing.assert_allclose(float(bt_cross_entropy(jnp.asarray(s_a - s_b), y)), expect, rtol=1e-4)


def test_a_floor_on_log_f_scores_each_step_as_the_person_does(key):
    """``log_f_floor``: S = Σ_t r_w + max(log f_φ, floor), the form of the simulated person's score."""
    w, phi, norm, seg_a, _ = _tiny_problem(key)
    args = (w, phi, norm, seg_a.obs[0], seg_a.act[0], seg_a.next_obs[0], seg_a.mask[0], 0.02)
    plain = PrefBiasConfig(reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,), min_std=0.02), **PLAIN)
    per_step = [_np_score(*args[:3], *(x[t : t + 1] for x in args[3:7]), 0.02) for t in range(2)]
    r = [_np_score(*args[:3], *(x[t : t + 1] for x in args[3:7]), 0.02, floor=1e6) - 1e6 for t in range(2)]
    log_f = np.subtract(per_step, r)
    floor = float(np.mean(log_f))  # between the two steps' log densities: it lifts the lower one only
    assert min(log_f) < floor < max(log_f)
    for f in (floor, float(max(log_f)) + 1.0):
        cfg = dataclasses.replace(plain, log_f_floor=f)
        got = float(scores_fixed(w, phi, norm, seg_a, cfg)[0])
        np.testing.assert_allclose(got, _np_score(*args, floor=f), rtol=1e-4)
        np.testing.assert_allclose(got, sum(r) + float(np.sum(np.maximum(log_f, f))), rtol=1e-4)
    assert float(scores_fixed(w, phi, norm, seg_a, plain)[0]) == pytest.approx(sum(per_step), rel=1e-4)
    with pytest.raises(ValueError, match="log_f_floor must be a finite number or None"):
        dataclasses.replace(plain, log_f_floor=float("-inf")).check()
    # recorded in a run's config only when set, so run folders from before the option still resume
    from mindgap.algorithms.prefbias import prefbias_config

    fast = prefbias_config("fast")
    assert "log_f_floor" not in fast.as_dict()["prefbias"]
    floored = dataclasses.replace(fast, prefbias=dataclasses.replace(fast.prefbias, log_f_floor=-20.0))
    assert floored.as_dict()["prefbias"]["log_f_floor"] == -20.0
    assert "scale_prior_std" not in fast.as_dict()["prefbias"]
    spread = dataclasses.replace(fast, prefbias=dataclasses.replace(fast.prefbias, scale_prior_std=1.0))
    assert spread.as_dict()["prefbias"]["scale_prior_std"] == 1.0


def test_stay_head_scores_a_stay_by_its_probability(key):
    """With a stay head a step with s' = s adds r + log p_stay to S(τ), a move r + log(1 − p_stay) + log N."""
    w, _, norm, seg_a, seg_b = _tiny_problem(key)
    phi = init_mlp(jax.random.fold_in(key, 7), dynamics_sizes(2, 2, (6,), stay=True))
    seg_a = seg_a._replace(next_obs=seg_a.next_obs.at[0, 1].set(seg_a.obs[0, 1]))  # its second step a stay
    cfg = PrefBiasConfig(
        reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,), min_std=0.02), stay_head=True, absorbing=False
    )

    def np_score(seg):
        obs, act, nxt = (np.asarray(x[0], np.float64) for x in (seg.obs, seg.act, seg.next_obs))
        in_mean, in_std, out_mean, out_std = (np.asarray(x, np.float64) for x in norm)
        x = np.concatenate([obs, act], -1)
        r = REWARD_BOUND * np.tanh(_np_mlp(w, x)[:, 0] / REWARD_BOUND)
        raw = _np_mlp(phi, (x - in_mean) / in_std)
        mean, std = obs + out_mean + out_std * raw[:, :2], out_std * (0.02 + np.log1p(np.exp(raw[:, 2:4])))
        p_stay = 1 / (1 + np.exp(-raw[:, 4]))
        stay = np.all(nxt == obs, -1)
        log_f = np.where(stay, np.log(p_stay), np.log1p(-p_stay) + stats.norm.logpdf(nxt, mean, std).sum(-1))
        return float(np.sum((r + log_f)[np.asarray(seg.mask[0])]))

    p = 1.0 / (1.0 + np.exp(-(np_score(seg_a) - np_score(seg_b))))
    assert 1e-4 < p < 1 - 1e-4
    np.testing.assert_allclose(float(preference_prob(w, phi, norm, seg_a, seg_b, cfg)[0]), p, rtol=1e-4)
    state = prefbias_init(key, 2, 2, dataclasses.replace(cfg, belief_prior="random"), DynamicsModel(phi, norm))
    assert state.belief.mean.net[-1][1].shape == (5,)  # a random prior of the same architecture
    np.testing.assert_array_equal(state.belief.mean.stay, 0.0)  # and a local stay disturbance of zeros


def test_units_state_a_move_s_density_in_the_world_s_units(key):
    """With units c per observation unit, f_φ scores a move by its density per world unit², as the person does.

    The belief network here outputs a constant Gaussian (zero weights), N(s + μ, σ²) in
    observation units: per cell² that is N(c·(s + μ), (c·σ)²), whose log density is
    Σ log c lower. A stay, a probability, is unit-free.
    """
    w, _, norm, seg_a, seg_b = _tiny_problem(key)
    phi = init_mlp(jax.random.fold_in(key, 7), dynamics_sizes(2, 2, (6,), stay=True))
    phi = jax.tree.map(jnp.zeros_like, phi[:-1]) + (
        (jnp.zeros_like(phi[-1][0]), jnp.array([0.2, -0.1, 0.3, -0.4, 0.5])),
    )
    seg = seg_a._replace(next_obs=seg_a.next_obs.at[0, 1].set(seg_a.obs[0, 1]))  # a move, then a stay
    cfg = PrefBiasConfig(
        reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,), min_std=0.02), stay_head=True, absorbing=False
    )
    units = jnp.array([5.0, 2.5])  # cells per observation unit (a 10 × 5-cell world on [−1, 1]²): Σ log = log 12.5
    state = prefbias_init(key, 2, 2, cfg, DynamicsModel(phi, norm), units=units)
    np.testing.assert_allclose(float(state.log_unit), np.log(12.5), rtol=1e-6)

    out_mean, out_std = np.asarray(norm.out_mean, np.float64), np.asarray(norm.out_std, np.float64)
    mean_obs = np.asarray(seg.obs[0, 0], np.float64) + out_mean + out_std * np.array([0.2, -0.1])
    std_obs = out_std * (0.02 + np.log1p(np.exp([0.3, -0.4])))
    c = np.asarray(units, np.float64)
    move_cells = stats.norm.logpdf(c * np.asarray(seg.next_obs[0, 0], np.float64), c * mean_obs, c * std_obs).sum()
    p_stay = 1 / (1 + np.exp(-0.5))
    x = np.concatenate([np.asarray(seg.obs[0], np.float64), np.asarray(seg.act[0], np.float64)], -1)
    r = REWARD_BOUND * np.tanh(_np_mlp(w, x)[:, 0] / REWARD_BOUND)
    expect = r.sum() + np.log1p(-p_stay) + move_cells + np.log(p_stay)
    got = scores_fixed(w, phi, norm, seg, cfg, state.log_unit)
    np.testing.assert_allclose(float(got[0]), expect, rtol=1e-5)
    # in observation units (log_unit 0) the move would be scored Σ log c = 2.53 nats higher
    np.testing.assert_allclose(float(scores_fixed(w, phi, norm, seg, cfg)[0] - got[0]), np.log(12.5), rtol=1e-4)


def test_one_preference_is_scored_under_one_draw_of_the_networks(key):
    """Eq. 3.3's likelihood is p(d | w, φ): both segments of a pair, all their steps, one (w, φ).

    Two identical segments then have S(a) − S(b) = 0 under every draw, so the cross-entropy
    is log 2 exactly however wide q is (a draw per transition would give them different scores).
    """
    w, phi, norm, seg_a, _ = _tiny_problem(key)
    cfg = PrefBiasConfig(reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,)), mc_samples=4, **PLAIN)
    state = PrefBiasState(init_gaussian(w, 0.5), init_gaussian(phi, 0.5), w, phi, norm, (), ())
    data = PrefData(seg_a, seg_a, jnp.array([1.0]), jnp.asarray(1, jnp.int32))
    nll = negative_elbo(state, data, key, dataclasses.replace(cfg, kl_scale=0.0))
    np.testing.assert_allclose(float(nll), np.log(2.0), rtol=1e-6)


def test_negative_elbo_is_cross_entropy_plus_kl_over_n(key):
    """Eq. 3.3 per pair with near-deterministic posteriors: CE of the mean networks + KL / N."""
    w, phi, norm, seg_a, seg_b = _tiny_problem(key)
    cfg = PrefBiasConfig(reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,)), kl_scale=2.0, **PLAIN)
    sigma, s_w, s_phi = 1e-6, cfg.reward_prior_std, cfg.belief_prior_std
    w_prior, phi_prior = jax.tree.map(lambda x: x + 0.03, w), jax.tree.map(lambda x: x - 0.05, phi)
    state = PrefBiasState(init_gaussian(w, sigma), init_gaussian(phi, sigma), w_prior, phi_prior, norm, (), ())
    data = PrefData(seg_a, seg_b, jnp.array([1.0]), jnp.asarray(1, jnp.int32))
    p = float(preference_prob(w, phi, norm, seg_a, seg_b, cfg)[0])

    def kl(n_params, shift, s):
        return n_params * (np.log(s / sigma) + (sigma**2 + shift**2) / (2 * s**2) - 0.5)

    n_w, n_phi = (sum(x.size for x in jax.tree.leaves(t)) for t in (w, phi))
    elbo = jax.jit(negative_elbo, static_argnames="cfg")
    ce_only = float(elbo(state, data, key, cfg=dataclasses.replace(cfg, kl_scale=0.0)))
    np.testing.assert_allclose(ce_only, -np.log(p), rtol=1e-4)
    kl_part = float(elbo(state, data, key, cfg=cfg)) - ce_only
    np.testing.assert_allclose(kl_part, 2.0 * (kl(n_w, 0.03, s_w) + kl(n_phi, 0.05, s_phi)), rtol=1e-4)


def _toy_data(key, pairs=48, length=3):
    """Segments where the person prefers the larger x (reward = x) and no step moves."""
    ks = jax.random.split(key, 4)

    def seg(k):
        obs = jax.random.uniform(k, (pairs, length, 2), minval=-1, maxval=1)
        act = jax.random.uniform(jax.random.fold_in(k, 1), (pairs, length, 2), minval=-1, maxval=1)
        return Segments(obs, act, obs, jnp.ones((pairs, length), bool))

    seg_a, seg_b = seg(ks[0]), seg(ks[1])
    label = (seg_a.obs[..., 0].sum(-1) > seg_b.obs[..., 0].sum(-1)).astype(jnp.float32)
    flat = jnp.concatenate([seg_a.obs, seg_a.act], -1).reshape(-1, 4)
    norm = Norm(flat.mean(0), flat.std(0), jnp.zeros(2), jnp.full(2, 0.05))
    return PrefData(seg_a, seg_b, label, jnp.asarray(pairs, jnp.int32)), norm


def test_fit_learns_a_planted_reward_under_jit_and_vmap_over_seeds(key):
    data, norm = _toy_data(key)
    dcfg = DynamicsConfig(hidden=(8,))
    cfg = PrefBiasConfig(reward_hidden=(16,), dynamics=dcfg, updates=150, batch_size=32, lr=3e-3, **PLAIN)
    # f_ψ predicts "no move" with a fixed scale everywhere: every step is equally likely under the
    # prior, so the preferences are the reward's to explain
    psi = init_mlp(jax.random.fold_in(key, 9), dynamics_sizes(2, 2, dcfg.hidden))
    dyn = DynamicsModel(psi[:-1] + ((psi[-1][0] * 0, psi[-1][1] * 0),), norm)

    def run(k):
        k_init, k_fit = jax.random.split(k)
        state = prefbias_init(k_init, 2, 2, cfg, dyn)
        before = jnp.mean(
            (preference_prob(state.reward.mean, state.belief.mean, norm, data.seg_a, data.seg_b, cfg) > 0.5)
            == (data.label > 0.5)
        )
        state, info = fit(state, data, k_fit, cfg)
        return state, info, before

    states, info, before = jax.jit(jax.vmap(run))(jax.random.split(jax.random.fold_in(key, 3), 2))
    acc = np.asarray(info.accuracy)
    assert np.all(acc > 0.85), acc
    assert np.all(acc > np.asarray(before) + 0.2)
    assert np.all(np.isfinite(np.asarray(info.loss)))
    # the seeds are independent runs, not copies
    assert float(jnp.abs(states.reward.mean[0][0][0] - states.reward.mean[0][0][1]).max()) > 1e-3
    # the priors did not move
    np.testing.assert_array_equal(states.belief_prior[0][0][0], dyn.params[0][0])


def test_priors_and_recentring(key):
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.ones(2))
    dcfg = DynamicsConfig(hidden=(8,))
    psi = DynamicsModel(init_mlp(key, dynamics_sizes(2, 2, dcfg.hidden)), norm)
    psi2 = DynamicsModel(jax.tree.map(lambda x: x + 1.0, psi.params), norm._replace(out_std=jnp.full(2, 2.0)))
    dyn_cfg = PrefBiasConfig(reward_hidden=(4,), dynamics=dcfg, belief_prior="dynamics", **PLAIN)
    rnd_cfg = PrefBiasConfig(reward_hidden=(4,), dynamics=dcfg, belief_prior="random", **PLAIN)
    s_dyn, s_rnd = prefbias_init(key, 2, 2, dyn_cfg, psi), prefbias_init(key, 2, 2, rnd_cfg, psi)
    same = jax.tree.map(lambda a, b: bool(jnp.all(a == b)), s_dyn.belief.mean, psi.params)
    assert all(jax.tree.leaves(same))  # q(φ) starts at ψ
    assert not bool(jnp.all(s_rnd.belief_prior[0][0] == psi.params[0][0]))
    moved = with_dynamics(s_dyn, psi2, dyn_cfg)
    np.testing.assert_array_equal(moved.belief_prior[0][0], psi2.params[0][0])
    np.testing.assert_array_equal(moved.belief.mean[0][0], s_dyn.belief.mean[0][0])  # the posterior stays
    assert float(moved.norm.out_std[0]) == 2.0
    kept = with_dynamics(s_rnd, psi2, rnd_cfg)
    np.testing.assert_array_equal(kept.belief_prior[0][0], s_rnd.belief_prior[0][0])
    with pytest.raises(ValueError, match="belief_prior"):
        PrefBiasConfig(belief_prior="uniform").check()
    with pytest.raises(ValueError, match="positive"):
        PrefBiasConfig(reward_prior_std=0.0).check()
    with pytest.raises(ValueError, match="absorbing must be True or False, got 'false'"):
        PrefBiasConfig(absorbing="false").check()  # a non-empty string is true: the switch would be on


# ---- a planted belief on nav1 ---------------------------------------------------------------

_NAV1 = load_world("nav1-v1")  # the dissertation's nav1, whose person believes the ice is noisy


def _nav1_segments(key, count: int, length: int) -> Segments:
    """Random-action segments of the true dynamics from uniform positions in floor, ice and sand cells."""
    params = _NAV1.params
    grid = np.asarray(params.grid)
    free = jnp.asarray(np.argwhere(np.isin(grid, [FLOOR, ICE, SAND])))
    k_cell, k_off, k_act, k_run = jax.random.split(key, 4)
    cells = free[jax.random.randint(k_cell, (count,), 0, free.shape[0])]
    pos = cells[:, ::-1].astype(jnp.float32) + jax.random.uniform(k_off, (count, 2), minval=0.05, maxval=0.95)
    acts = jax.random.uniform(k_act, (count, length, 2), minval=-1, maxval=1)

    def one(k, p, a):
        def body(s, xs):
            out = step(xs[0], s, xs[1], params)
            return out.state, (observe(s, params), observe(out.state, params), ~s.done)

        s0 = TerrainState(p, jnp.zeros((), jnp.int32), jnp.zeros((), bool))
        return jax.lax.scan(body, s0, (jax.random.split(k, length), a))[1]

    obs, nxt, mask = jax.vmap(one)(jax.random.split(k_run, count), pos, acts)
    return Segments(obs, acts, nxt, mask)


def _terrain_means(noise_map):
    grid = np.asarray(_NAV1.params.grid)
    m = np.asarray(noise_map)
    return {name: float(np.nanmean(m[grid == code])) for name, code in (("floor", FLOOR), ("ice", ICE), ("sand", SAND))}


@pytest.fixture(scope="module")
def planted_noisy_ice():
    """nav1-v1: a person who believes ice is noisy (σ 0.2 vs the truth's 0.05) teaches 400 pairs.

    Control: the same pairs labelled by a person whose belief is the truth. Both fits start
    from the prior centred on f_ψ, which knows ice is calm. Preferences only reveal how
    plausible the *observed* (true) steps look to the person, so the learned belief shows
    the bias as noise; it does not recover the believed mean (speed) as well.
    """
    from mindgap import rng

    key = rng.key(0)
    segs = jax.jit(_nav1_segments, static_argnums=(1, 2))
    length, pairs = 5, 400
    data = segs(jax.random.fold_in(key, 1), 800, length)
    dcfg = DynamicsConfig(hidden=(32, 32), max_epochs=40, batch_size=128)
    flat = [x.reshape(-1, x.shape[-1]) for x in (data.obs, data.act, data.next_obs)]
    psi, _ = jax.jit(train_dynamics, static_argnames="cfg")(
        jax.random.fold_in(key, 2), *flat, data.mask.reshape(-1), dcfg
    )

    seg_a, seg_b = segs(jax.random.fold_in(key, 3), pairs, length), segs(jax.random.fold_in(key, 4), pairs, length)
    ask = jax.jit(answer, static_argnames=("env", "cfg"))
    person = TeacherConfig(beta=1.0)
    env = _NAV1.env
    biased, _ = ask(jax.random.fold_in(key, 5), seg_a, seg_b, env, _NAV1.params, _NAV1.belief("human"), cfg=person)
    truthful, _ = ask(jax.random.fold_in(key, 5), seg_a, seg_b, env, _NAV1.params, _NAV1.params, cfg=person)
    cfg = PrefBiasConfig(reward_hidden=(32, 32), dynamics=dcfg, updates=400, **PLAIN)

    def run(label, k):
        k_init, k_fit = jax.random.split(k)
        state = prefbias_init(k_init, 2, 2, cfg, psi)
        state, info = fit(state, PrefData(seg_a, seg_b, label, jnp.asarray(pairs, jnp.int32)), k_fit, cfg)
        return belief_noise_map(state.belief.mean, state.norm, _NAV1.params, dcfg.min_std), info

    maps, info = jax.jit(jax.vmap(run))(jnp.stack([biased, truthful]), jax.random.split(jax.random.fold_in(key, 6), 2))
    prior_map = belief_noise_map(psi.params, psi.norm, _NAV1.params, dcfg.min_std)
    return maps, info, prior_map


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="the learner with s_φ = 0.01 on f_φ's network keeps the noisier ice (the first two checks hold) but "
    "fits this person's answers less well: training accuracy 0.67, held-out NLL 0.89 against the truthful "
    "control's 0.38 (nav1-v1's noise belief is not identified at this budget; docs/experiments/identifiability.md, "
    "'The belief posterior'); strict, so a fix shows",
)
def test_a_planted_noisy_ice_belief_shows_as_noisier_ice(planted_noisy_ice):
    """f_φ learns the ice noisier than the rest of the map, and noisier than with a truthful person."""
    maps, info, _ = planted_noisy_ice
    learned, control = _terrain_means(maps[0]), _terrain_means(maps[1])
    assert learned["ice"] > 1.05 * max(learned["floor"], learned["sand"]), learned
    assert learned["ice"] > 1.15 * control["ice"], (learned, control)
    assert float(info.accuracy[0]) > 0.7


@pytest.mark.slow
def test_a_planted_noisy_ice_belief_is_recovered_closer_than_the_prior(planted_noisy_ice):
    """The learned ice noise is nearer the person's than the prior's, and the map's RMS error below 0.7 of the prior's.

    It failed while p(φ) put s_φ = 0.1 on every weight: f_φ then widened its Gaussian past the belief (ice
    0.37 against the person's 0.2; docs/experiments/identifiability.md, "The belief posterior")."""
    maps, _, prior_map = planted_noisy_ice
    learned, prior = _terrain_means(maps[0]), _terrain_means(prior_map)
    believed_ice = float(_NAV1.beliefs["human"].noise[ICE])
    assert abs(learned["ice"] - believed_ice) < abs(prior["ice"] - believed_ice), (learned, prior)
    target = np.asarray(table_noise_map(_NAV1.belief("human")))

    def rms(m):
        return float(np.sqrt(np.nanmean((np.asarray(m) - target) ** 2)))

    assert rms(maps[0]) < 0.7 * rms(prior_map), (rms(maps[0]), rms(prior_map))


def test_absorbing_steps_count_r_abs_of_the_terminal_state(key):
    """With absorbing states S(τ) adds r_abs(s_T) per absorbed step, s_T where the last real step ended."""
    w, phi, norm, seg_a, seg_b = _tiny_problem(key)
    cfg = PrefBiasConfig(reward_hidden=(5,), dynamics=DynamicsConfig(hidden=(6,), min_std=0.02), **PLAIN)
    weights = RewardWeights(w, 0.05 * jax.random.normal(jax.random.fold_in(key, 7), (256,)))
    # b ended after its first step (a goal or a pit): its second step is absorbing
    seg_a = AbsorbingSegments(*seg_a[:4], jnp.zeros((1, 2), bool))
    seg_b = AbsorbingSegments(*seg_b[:4], jnp.array([[False, True]]))
    s_t = np.asarray(seg_b.next_obs[0, 0], np.float64)
    r_abs = float(absorbing_value(weights, jnp.asarray(s_t)[None])[0])
    assert abs(r_abs) > 0.05  # a head that matters
    s_a = _np_score(w, phi, norm, seg_a.obs[0], seg_a.act[0], seg_a.next_obs[0], seg_a.mask[0], 0.02)
    s_b = _np_score(w, phi, norm, seg_b.obs[0], seg_b.act[0], seg_b.next_obs[0], seg_b.mask[0], 0.02) + r_abs
    p = 1.0 / (1.0 + np.exp(-(s_a - s_b)))
    np.testing.assert_allclose(float(preference_prob(weights, phi, norm, seg_a, seg_b, cfg)[0]), p, rtol=1e-4)
    # the same segments without their absorbing steps: the head is not read
    plain = preference_prob(weights, phi, norm, Segments(*seg_a[:4]), Segments(*seg_b[:4]), cfg)
    p_plain = 1.0 / (1.0 + np.exp(-(s_a - s_b + r_abs)))
    np.testing.assert_allclose(float(plain[0]), p_plain, rtol=1e-4)


def test_fit_learns_which_terminal_state_is_worse(key):
    """Pairs that differ only in where they ended (left half: a pit, right half: a goal): r_abs learns the order."""
    pairs, length = 64, 4
    ks = jax.random.split(key, 4)

    def seg(k, side):
        obs = jax.random.uniform(k, (pairs, length, 2), minval=-0.2, maxval=0.2)
        end = jnp.stack(
            [
                side * jax.random.uniform(jax.random.fold_in(k, 1), (pairs,), minval=0.5, maxval=0.9),
                jax.random.uniform(jax.random.fold_in(k, 2), (pairs,), minval=-0.5, maxval=0.5),
            ],
            -1,
        )
        nxt = obs.at[:, 1].set(end)  # the second step ends the episode at `end`
        mask = jnp.arange(length) < 2
        mask = jnp.broadcast_to(mask, (pairs, length))
        act = jnp.zeros((pairs, length, 2))
        return AbsorbingSegments(obs, act, nxt, mask, ~mask)

    goal, pit = seg(ks[0], 1.0), seg(ks[1], -1.0)
    swap = jax.random.bernoulli(ks[2], 0.5, (pairs,))
    pick = lambda a, b: jax.tree.map(lambda x, y: jnp.where(swap.reshape(-1, *[1] * (x.ndim - 1)), y, x), a, b)  # noqa: E731
    seg_a, seg_b = pick(goal, pit), pick(pit, goal)
    label = (~swap).astype(jnp.float32)  # a is preferred when it is the goal segment
    data = PrefData(seg_a, seg_b, label, jnp.asarray(pairs, jnp.int32))
    dcfg = DynamicsConfig(hidden=(8,))
    cfg = PrefBiasConfig(
        reward_hidden=(8,), dynamics=dcfg, updates=150, batch_size=32, lr=3e-3, absorbing=True, stay_head=False,
        belief_prior_std=0.1,  # f_ψ here is a random network, far from the segments' moves: f_φ must be free to fit them
    )
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.full(2, 0.05))
    psi = init_mlp(jax.random.fold_in(key, 9), dynamics_sizes(2, 2, dcfg.hidden))
    state = prefbias_init(ks[3], 2, 2, cfg, DynamicsModel(psi, norm))
    state, info = jax.jit(fit, static_argnames="cfg")(state, data, jax.random.fold_in(key, 5), cfg)
    assert float(info.accuracy) > 0.9
    ends = jnp.array([[0.7, 0.0], [-0.7, 0.0]])
    r_goal, r_pit = np.asarray(absorbing_value(state.reward.mean, ends))
    assert r_goal > r_pit + 0.5, (r_goal, r_pit)


# ---- the belief's prior scales, the local stay disturbance, held-out answers ------------------


def test_belief_prior_scales_are_narrow_on_the_move_and_wide_on_the_stay(key):
    from jax.flatten_util import ravel_pytree

    from mindgap.algorithms.prefbias_inference import belief_prior_scales
    from mindgap.models.prefbias_nets import STAY_GAIN, BeliefWeights

    dcfg = DynamicsConfig(hidden=(6,))
    net = init_mlp(key, dynamics_sizes(2, 2, dcfg.hidden, stay=True))  # outputs: mean 2, scale 2, stay 1
    column = PrefBiasConfig(dynamics=dcfg, belief_prior_std=0.01, stay_prior_std=2.0, stay_local=False)
    scales = jax.tree.map(np.asarray, ravel_pytree(net)[1](belief_prior_scales(net, 2, column)))
    (w, b) = scales[-1]
    np.testing.assert_allclose(w[:, -1], 2.0)
    np.testing.assert_allclose(b[-1], 2.0)
    np.testing.assert_allclose(w[:, :-1], 0.01)
    np.testing.assert_allclose(scales[0][0], 0.01)
    one = dataclasses.replace(column, stay_prior_std=None)
    np.testing.assert_allclose(belief_prior_scales(net, 2, one), 0.01)
    local = BeliefWeights(net, jnp.zeros(7), jnp.zeros(7))
    flat = belief_prior_scales(local, 2, dataclasses.replace(column, stay_local=True, noise_local=True, noise_prior_std=0.5))
    np.testing.assert_allclose(flat[-14:-7], 2.0 / STAY_GAIN)  # the disturbances' weights, last; per unit of height
    np.testing.assert_allclose(flat[-7:], 0.5 / STAY_GAIN)
    np.testing.assert_allclose(flat[:-14], 0.01)  # the whole MLP, its stay column included
    rand = dataclasses.replace(column, belief_prior="random", random_prior_std=0.7)
    np.testing.assert_allclose(belief_prior_scales(net, 2, rand)[:-1], 0.7)
    # scale_prior_std: wide on the biases of the raw-scale columns (outputs 2, 3) only, with or without bumps
    spread = dataclasses.replace(column, scale_prior_std=1.5)
    (w, b) = jax.tree.map(np.asarray, ravel_pytree(net)[1](belief_prior_scales(net, 2, spread)))[-1]
    np.testing.assert_allclose(b, [0.01, 0.01, 1.5, 1.5, 2.0])
    np.testing.assert_allclose(w[:, :-1], 0.01)
    bumped = belief_prior_scales(local, 2, dataclasses.replace(spread, stay_local=True))
    (w, b) = jax.tree.map(np.asarray, ravel_pytree(local)[1](bumped)).net[-1]
    np.testing.assert_allclose(b, [0.01, 0.01, 1.5, 1.5, 0.01])
    np.testing.assert_allclose(belief_prior_scales(net, 2, dataclasses.replace(rand, scale_prior_std=1.5))[:-1], 0.7)
    with pytest.raises(ValueError, match="scale_prior_std must be positive or None"):
        dataclasses.replace(column, scale_prior_std=0.0).check()


def test_a_local_stay_disturbance_moves_the_stay_probability_near_its_bump_only(key):
    from mindgap.models.prefbias_nets import (
        STAY_GAIN,
        BeliefWeights,
        belief_log_prob,
        belief_predict,
        belief_stay_prob,
        stay_features,
    )
    from mindgap.models.reward_ensemble import rbf_count

    net = init_mlp(key, dynamics_sizes(2, 2, (6,), stay=True))
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.full(2, 0.1))
    m = rbf_count(2)
    obs = jnp.array([[-1.0, -1.0], [1.0, 1.0]])  # the first and the last bump's centres
    act, nxt = jnp.zeros((2, 2)), obs + 0.05
    zero = BeliefWeights(net, jnp.zeros(m), jnp.zeros(m))
    np.testing.assert_array_equal(
        belief_log_prob(zero, norm, obs, act, nxt, 0.01), belief_log_prob(net, norm, obs, act, nxt, 0.01)
    )
    np.testing.assert_allclose(stay_features(obs, m)[0, 0], STAY_GAIN)
    lifted = BeliefWeights(net, jnp.zeros(m).at[0].set(3.0 / STAY_GAIN), jnp.zeros(m))
    logit = lambda p: np.log(p) - np.log1p(-p)  # noqa: E731
    before, after = (np.asarray(belief_stay_prob(p, norm, obs, act)) for p in (zero, lifted))
    np.testing.assert_allclose(logit(after[0]) - logit(before[0]), 3.0, rtol=1e-4)
    np.testing.assert_allclose(after[1], before[1])
    noisier = BeliefWeights(net, jnp.zeros(m), jnp.zeros(m).at[0].set(2.0 / STAY_GAIN))
    std_before, std_after = (np.asarray(belief_predict(p, norm, obs, act, 0.01)[1]) for p in (zero, noisier))
    assert np.all(std_after[0] > std_before[0]) and np.allclose(std_after[1], std_before[1])


def test_held_out_answers_are_never_trained_on():
    from mindgap.algorithms.prefbias_inference import _train_index, held_out

    held = np.asarray(held_out(jnp.asarray(20), 24, 8))
    assert np.flatnonzero(held).tolist() == [7, 15]
    n_train = 20 - 2
    trained = np.asarray(_train_index(jnp.arange(n_train), 8))
    assert sorted(trained.tolist()) == [i for i in range(20) if i not in (7, 15)]
    assert not np.asarray(held_out(jnp.asarray(20), 24, 0)).any()
    with pytest.raises(ValueError, match="holdout_every"):
        PrefBiasConfig(holdout_every=1).check()
    with pytest.raises(ValueError, match="multiple of check_every"):
        PrefBiasConfig(updates=30, check_every=25).check()


def test_fit_keeps_the_posterior_that_predicts_the_held_out_answers_best(key):
    data, norm = _toy_data(key, pairs=64)
    dcfg = DynamicsConfig(hidden=(8,))
    cfg = PrefBiasConfig(reward_hidden=(16,), dynamics=dcfg, updates=100, check_every=20, holdout_every=4,
                         batch_size=32, lr=3e-3, **PLAIN)  # fmt: skip
    psi = init_mlp(jax.random.fold_in(key, 9), dynamics_sizes(2, 2, dcfg.hidden))
    dyn = DynamicsModel(psi[:-1] + ((psi[-1][0] * 0, psi[-1][1] * 0),), norm)
    state = prefbias_init(jax.random.fold_in(key, 1), 2, 2, cfg, dyn)
    held = np.arange(64) % 4 == 3

    def held_nll(s):
        p = np.clip(
            np.asarray(preference_prob(s.reward.mean, s.belief.mean, norm, data.seg_a, data.seg_b, cfg)), 1e-6, 1 - 1e-6
        )
        y = np.asarray(data.label)
        return float(np.mean(-(y * np.log(p) + (1 - y) * np.log1p(-p))[held]))

    new, info = jax.jit(fit, static_argnames="cfg")(state, data, jax.random.fold_in(key, 2), cfg=cfg)
    np.testing.assert_allclose(float(info.held_nll), held_nll(new), rtol=1e-4)
    assert held_nll(new) < held_nll(state) - 0.05  # it learned, judged on answers it never trained on
    _, plain = jax.jit(fit, static_argnames="cfg")(state, data, key, cfg=dataclasses.replace(cfg, holdout_every=0))
    assert np.isnan(float(plain.held_nll))


def test_each_fit_starts_afresh_at_the_priors_unless_told_to_warm_start(key):
    """Alg. 2, line 7: a fit to all answers so far; ``refit`` (the default) ignores where the last fit ended."""
    data, norm = _toy_data(key, pairs=32)
    dcfg = DynamicsConfig(hidden=(8,))
    cfg = PrefBiasConfig(reward_hidden=(8,), dynamics=dcfg, updates=50, check_every=25, batch_size=16, **PLAIN)
    psi = init_mlp(jax.random.fold_in(key, 9), dynamics_sizes(2, 2, dcfg.hidden))
    fresh = prefbias_init(jax.random.fold_in(key, 1), 2, 2, cfg, DynamicsModel(psi, norm))
    moved = fresh._replace(reward=fresh.reward._replace(mean=jax.tree.map(lambda x: x + 0.3, fresh.reward.mean)))
    fit_jit = jax.jit(fit, static_argnames="cfg")
    k = jax.random.fold_in(key, 2)
    a, _ = fit_jit(fresh, data, k, cfg=cfg)
    b, _ = fit_jit(moved, data, k, cfg=cfg)
    for x, y in zip(jax.tree.leaves((a.reward, a.belief)), jax.tree.leaves((b.reward, b.belief)), strict=True):
        np.testing.assert_array_equal(x, y)
    warm = dataclasses.replace(cfg, refit=False)
    c, _ = fit_jit(moved, data, k, cfg=warm)
    assert not np.allclose(np.asarray(c.reward.mean[0][0]), np.asarray(a.reward.mean[0][0]))
