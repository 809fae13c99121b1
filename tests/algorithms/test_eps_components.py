"""EPS's parts with known answers: H_T, the reshaped reward (Eq. 4.6), the explicability score (Eq. 4.4), policy shaping."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from mindgap.algorithms.eps_reward import (
    cost_offsets,
    entropy_mean_from_replay,
    environment_entropy,
    eps_absorbing,
    eps_reward,
    eps_reward_params,
    eps_sac_config,
    policy_entropy_max,
    raw_u,
    u_norm_from_replay,
    world_reward,
)
from mindgap.algorithms.explicability import explicability
from mindgap.algorithms.policy_shaping import ShapedPolicy, gaussian_product, shaped_dist, shaped_sample
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.data.replay import relabel, replay_add, replay_init
from mindgap.envs.terrain import load_world, observe, world_from_dict
from mindgap.envs.terrain.params import TerrainState
from mindgap.models.agent_dynamics import dynamics_entropy, gaussian_entropy
from mindgap.models.gaussian_dynamics import DynamicsModel, Norm
from mindgap.models.reward_ensemble import REWARD_BOUND, RewardConfig, reward_init
from mindgap.models.squashed import squashed_log_prob


def _bounded(x):
    """Every learned reward's soft bound, B·tanh(x/B)."""
    return REWARD_BOUND * np.tanh(np.asarray(x, np.float64) / REWARD_BOUND)


def linear_actor(gain, mean_bias, log_std):
    """A one-layer actor: pre-tanh mean ``gain ⊙ obs + mean_bias`` (per coordinate), constant ``log_std``."""
    w = jnp.zeros((2, 4)).at[0, 0].set(gain[0]).at[1, 1].set(gain[1])
    b = jnp.concatenate([jnp.asarray(mean_bias, jnp.float32), jnp.asarray(log_std, jnp.float32)])
    return ((w, b),)


def constant_dynamics(raw_scale, min_std):
    """T_A with std = min_std + softplus(raw_scale) everywhere (identity normalisation)."""
    w = jnp.zeros((4, 4))
    b = jnp.concatenate([jnp.zeros(2), jnp.asarray(raw_scale, jnp.float32)])
    return DynamicsModel(((w, b),), Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.ones(2)))


# ---------------------------------------------------------------- H_T (the Gaussian entropy term)


def test_gaussian_entropy_closed_form():
    std = np.array([[0.1, 2.0], [0.5, 0.5], [1e-3, 30.0]])
    for s in std:
        expect = stats.multivariate_normal(cov=np.diag(s**2)).entropy()
        np.testing.assert_allclose(float(gaussian_entropy(jnp.asarray(s))), expect, rtol=1e-5)
    x = np.random.default_rng(0).normal(size=(200_000, 2)) * std[0]
    mc = -stats.norm.logpdf(x, scale=std[0]).sum(-1).mean()
    np.testing.assert_allclose(float(gaussian_entropy(jnp.asarray(std[0]))), mc, atol=0.01)


def test_dynamics_entropy_reads_the_model_and_shifts_with_units():
    model = constant_dynamics([0.0, 1.0], min_std=0.01)
    std = 0.01 + np.log1p(np.exp([0.0, 1.0]))
    obs, act = jnp.zeros((5, 2)), jnp.ones((5, 2))
    h = dynamics_entropy(model, obs, act, 0.01)
    np.testing.assert_allclose(h, np.sum(0.5 * np.log(2 * np.pi * np.e) + np.log(std)), rtol=1e-5)
    scaled = dynamics_entropy(model, obs, act, 0.01, jnp.array([3.5, 2.0]))
    np.testing.assert_allclose(scaled - h, np.log(3.5) + np.log(2.0), rtol=1e-5)


# ---------------------------------------------------------------- the reshaped reward (Eq. 4.6)


def _linear_u(weight, bias):
    """A 2-member ensemble of one-layer u networks: member e gives B·tanh((weight[e] · obs_x + bias[e])/B)."""
    w = jnp.zeros((2, 4, 1)).at[:, 0, 0].set(jnp.asarray(weight, jnp.float32))
    return ((w, jnp.asarray(bias, jnp.float32)[:, None]),)


@pytest.fixture(scope="module")
def d1():
    return load_world("d1")


def _obs(world, xy):
    return observe(TerrainState(jnp.asarray(xy, jnp.float32), 0, False), world.params)


def test_reshaped_reward_on_hand_made_transitions(d1):
    # d1: the goal is the cell x ∈ [5, 6], y ∈ [1, 2]; Φ (geodesic distance to it) is 0.5 at (4.5, 1.5).
    s = [(4.5, 1.5), (2.0, 4.0)]
    s2 = [(5.2, 1.5), (2.0, 4.0)]  # into the goal from 0.5 cells (Φ: 0.5 → 0); a bump that stays put
    obs = jnp.stack([_obs(d1, p) for p in s])
    nxt = jnp.stack([_obs(d1, p) for p in s2])
    act = jnp.array([[1.0, 0.0], [0.0, -1.0]])
    rw = d1.params.rewards
    r_a = np.array([rw.step + rw.progress * 0.5 + rw.goal, rw.step], np.float64)

    u_params = _linear_u([1.0, 3.0], [0.0, 0.5])
    u_raw = np.mean([_bounded(np.asarray(obs[:, 0])), _bounded(3.0 * np.asarray(obs[:, 0]) + 0.5)], axis=0)
    u_mean, u_std, lam, min_std = 0.2, 0.5, 2.5, 0.01
    sigma_obs = min_std + np.log1p(np.exp(-1.0))  # T_A's std in observation units
    cells = np.array([7.0, 7.0]) / 2.0  # 7×7 map onto [−1, 1]²: 3.5 cells per observation unit
    h_t = np.sum(0.5 * np.log(2 * np.pi * np.e) + np.log(sigma_obs * cells))

    params = eps_reward_params(
        d1, u_params, constant_dynamics([-1.0, -1.0], min_std), lam, min_std=min_std, u_norm=(u_mean, u_std)
    )
    expect = r_a + lam * ((u_raw - u_mean) / u_std + h_t)
    reward_fn = jax.jit(eps_reward)
    np.testing.assert_allclose(reward_fn(params, obs, act, nxt), expect, rtol=1e-5)
    centred = dataclasses.replace(params, h_shift=jnp.float32(h_t))
    np.testing.assert_allclose(reward_fn(centred, obs, act, nxt), r_a + lam * (u_raw - u_mean) / u_std, rtol=1e-5)
    plain = dataclasses.replace(params, lam=jnp.float32(0.0))
    np.testing.assert_allclose(reward_fn(plain, obs, act, nxt), r_a, rtol=1e-6)


def test_h_t_is_weighted_as_u_h_is_and_a_cost_by_default(d1, key):
    """E log T_H (inside the standardised u_H) and H_T are halves of one −KL: both on u_H's scale, λ/s_H for H_T."""
    from mindgap.algorithms import engine, eps
    from mindgap.algorithms.eps_config import eps_config

    cfg = eps_config("fast")
    assert cfg.offset == "cost"  # the λ-term ≤ 0 on the buffer, as the −KL it stands for
    model, _, _ = eps._init(key, d1.env, cfg)
    model = model._replace(h_shift=jnp.float32(-2.0), u_norm=jnp.array([0.3, 0.8], jnp.float32))
    params = eps._reward_params(model, engine.WorldArgs(d1.params, d1.obs_units(), None), d1.env, cfg)
    assert float(params.h_weight) == pytest.approx(1.0 / cfg.nats_per_unit)
    obs = jnp.stack([_obs(d1, (2.5, 2.5)), _obs(d1, (4.5, 1.5))])
    act, nxt = jnp.zeros((2, 2)), obs
    r_a = world_reward(params, obs, act, nxt)
    u = (raw_u(params.u_params, obs, act, nxt) - 0.3) / 0.8
    h = environment_entropy(params, obs, act)  # H_T − h_shift, in cells
    expect = r_a + cfg.lam * (u + h / cfg.nats_per_unit)
    np.testing.assert_allclose(eps_reward(params, obs, act, nxt), expect, rtol=1e-5)
    # not λ·H_T, the weight before (which counted the entropy s_H = 7 times the belief's share)
    assert not np.allclose(eps_reward(params, obs, act, nxt), r_a + cfg.lam * (u + h), rtol=1e-3)


def test_a_person_who_judges_decisions_leaves_h_t_out(d1, key):
    """§4.3.1: "only the observable part needs to be considered". A person who judges decisions alone
    (``judged="decisions"``) makes the λ-term the policy's KL: no T_A is read, H_T counts 0, and the
    constants (``h_shift``) stay as they are."""
    from mindgap.algorithms import engine, eps
    from mindgap.algorithms.eps_config import eps_config

    obs = jnp.stack([_obs(d1, (2.5, 2.5)), _obs(d1, (4.5, 1.5))])
    act, nxt = jnp.zeros((2, 2)), obs
    w_args = engine.WorldArgs(d1.params, d1.obs_units(), None)
    for judged, has_t in (("transitions", True), ("decisions", False)):
        cfg = eps_config("fast", judged=judged)
        model, _, _ = eps._init(key, d1.env, cfg)
        model = model._replace(h_shift=jnp.float32(0.4), u_norm=jnp.array([0.3, 0.8], jnp.float32))
        params = eps._reward_params(model, w_args, d1.env, cfg)
        assert (params.dynamics is not None) == has_t
        u = (raw_u(params.u_params, obs, act, nxt) - 0.3) / 0.8
        h_t = environment_entropy(params, obs, act) + 0.4
        plain = world_reward(params, obs, act, nxt) + cfg.lam * (u - 0.4 / cfg.nats_per_unit)
        np.testing.assert_allclose(
            eps_reward(params, obs, act, nxt), plain + cfg.lam * h_t / cfg.nats_per_unit, rtol=1e-5
        )
        assert bool(jnp.all(h_t != 0)) == has_t
    with pytest.raises(ValueError, match="judged"):
        eps_config("fast", judged="outcomes").check()


def test_normalisation_statistics_come_from_the_filled_buffer(d1):
    buf = replay_init(16, 2, 2)
    xs = np.linspace(-0.9, 0.9, 10)
    for x in xs:
        buf = replay_add(buf, jnp.array([x, 0.0]), jnp.zeros(2), jnp.array([x, 0.0]), 0.0, 0.0, False, 0)
    u_params = _linear_u([1.0, 1.0], [0.0, 0.0])
    mean, std = u_norm_from_replay(u_params, buf)
    np.testing.assert_allclose([float(mean), float(std)], [_bounded(xs).mean(), _bounded(xs).std()], atol=1e-6)
    params = eps_reward_params(d1, u_params, constant_dynamics([0.0, 0.0], 0.01), 1.0, min_std=0.01)
    h = 2 * (0.5 * np.log(2 * np.pi * np.e) + np.log((0.01 + np.log(2)) * 3.5))
    np.testing.assert_allclose(float(entropy_mean_from_replay(params, buf)), h, rtol=1e-5)


def test_as_a_cost_the_lambda_term_never_pays_to_linger(d1):
    """Eq. 4.6's λ-term is −KL, ≤ 0. Centred over the buffer it is a bonus wherever the person's model
    rates a step above average: on d1, holding still beside the goal, where u_H is highest, then beats
    finishing (discounted, with the largest policy entropy SAC can add). As a cost it does not."""
    buf = replay_init(32, 2, 2)
    for x in np.linspace(1.5, 4.5, 10):  # the agent's buffer: steps along row 2, u_H rising with x
        o = _obs(d1, (x, 2.5))
        buf = replay_add(buf, o, jnp.zeros(2), o, 0.0, 0.0, False, 0)
    u_params = _linear_u([1.0, 3.0], [0.0, 0.5])
    lam, gamma, w = 2.5, 0.99, 1 / 7
    params = eps_reward_params(d1, u_params, constant_dynamics([-1.0, -1.0], 0.01), lam, min_std=0.01, h_weight=w)
    params = dataclasses.replace(params, **dict(zip(("u_mean", "u_std"), u_norm_from_replay(u_params, buf))))
    pi_max = policy_entropy_max(d1.env)
    assert pi_max == pytest.approx(2 * np.log(2))  # two squashed action dimensions
    linger = (_obs(d1, (4.5, 2.5)),) * 2, jnp.zeros(2)  # still, one cell below the cell left of the goal
    finish = (_obs(d1, (4.5, 1.5)), _obs(d1, (5.2, 1.5))), jnp.array([1.0, 0.0])  # into the goal, then absorbed

    def values(p):
        def r(step):
            (o, o2), a = step
            return float(eps_reward(p, o[None], a[None], o2[None])[0]) + lam * w * pi_max  # SAC's α H_π at most

        return r(linger) / (1 - gamma), r(finish)

    centred = dataclasses.replace(params, h_shift=entropy_mean_from_replay(params, buf))
    stay, end = values(centred)
    assert stay > end  # the centred term pays the agent to hold still instead of finishing
    u_mean, h_shift = cost_offsets(params, buf, pi_max)
    cost = dataclasses.replace(params, u_mean=u_mean, h_shift=h_shift)
    r_a = world_reward(cost, buf.obs[:10], buf.act[:10], buf.next_obs[:10])
    term = (eps_reward(cost, buf.obs[:10], buf.act[:10], buf.next_obs[:10]) - r_a) / lam + w * pi_max
    assert float(term.max()) == pytest.approx(0.0, abs=1e-5) and float(term.min()) < -0.5  # ≤ 0, 0 at the top
    stay, end = values(cost)
    assert stay < 0 < end  # as a cost, lingering costs what its steps cost


def test_with_absorbing_states_the_lambda_terms_constant_does_not_decide_when_to_end(d1, key):
    """Preferences fix u_H only up to a constant per step; without absorbing steps that constant
    decides whether an episode that ends sooner is worth more (the cost form pays to end, the
    centred one to linger). With them (``EPSConfig.absorbing``) an ended episode's λ-term goes on at
    its absorbing value, so moving u_H's or the entropies' constant moves every episode's discounted
    return alike: the difference between a one-step and a three-step episode stays where it was."""
    lam, gamma, w = 2.0, 0.9, 1 / 7
    u_params = reward_init(key, 2, 2, RewardConfig(members=2, hidden=(8,)), absorbing="single").params
    buf = replay_init(8, 2, 2)
    short = [((4.5, 1.5), (5.2, 1.5))]  # into the goal at once
    long = [((2.5, 1.5), (3.5, 1.5)), ((3.5, 1.5), (4.5, 1.5)), ((4.5, 1.5), (5.2, 1.5))]
    for episode in (short, long):
        for t, (a, b) in enumerate(episode):
            end = t == len(episode) - 1
            buf = replay_add(buf, _obs(d1, a), jnp.array([1.0, 0.0]), _obs(d1, b), 0.0, 0.0, end, t)
    params = eps_reward_params(d1, u_params, constant_dynamics([-1.0, -1.0], 0.01), lam, min_std=0.01, h_weight=w)

    def gap(p, absorbing):
        kw = dict(absorbing_fn=eps_absorbing, gamma=gamma) if absorbing else {}
        r = np.asarray(relabel(buf, eps_reward, p, **kw).reward, np.float64)
        return r[0] - (r[1] + gamma * r[2] + gamma**2 * r[3])

    moved = dataclasses.replace(params, u_mean=params.u_mean + 1.3, h_shift=params.h_shift + 0.7)
    assert gap(moved, True) == pytest.approx(gap(params, True), abs=1e-4)
    # the shift is −λ(1.3 + 0.7 w) a step: without absorbing steps the short episode escapes two of them
    escaped = lam * (1.3 + 0.7 * w) * (gamma + gamma**2)
    assert gap(moved, False) - gap(params, False) == pytest.approx(escaped, rel=1e-4)


def test_the_reshaped_reward_plugs_into_the_sac_loop(d1, key):
    cfg = SACConfig(hidden=(8,), batch_size=8, learning_starts=0)
    ls = jax.jit(loop_init, static_argnums=(1, 3, 4))(key, d1.env, d1.params, cfg, 64)
    params = eps_reward_params(
        d1,
        _linear_u([1.0, -2.0], [0.1, 0.0]),
        constant_dynamics([0.3, -0.2], 0.01),
        2.0,
        min_std=0.01,
        u_norm=(0.1, 0.7),
    )
    ls = run_chunk(ls, d1.env, d1.params, params, n_steps=20, cfg=cfg, phase="random", reward_fn=eps_reward)
    r = ls.replay
    n = int(r.size)
    reward_fn = jax.jit(eps_reward)
    np.testing.assert_allclose(r.reward[:n], reward_fn(params, r.obs[:n], r.act[:n], r.next_obs[:n]), rtol=1e-5)
    # the world's own reward is r_A: λ = 0 gives it back
    r_a = reward_fn(dataclasses.replace(params, lam=jnp.float32(0)), r.obs[:n], r.act[:n], r.next_obs[:n])
    np.testing.assert_allclose(r_a, r.env_reward[:n], atol=1e-4)


def test_policy_entropy_weight_is_sacs_alpha():
    assert eps_sac_config(SACConfig(), 2.5, 1.0).alpha == 2.5
    assert eps_sac_config(SACConfig(reward_scale=0.1), 2.5, 5.0).alpha == pytest.approx(0.05)
    assert eps_sac_config(SACConfig(), 0.0, 7.0).alpha == 0.0  # λ = 0: no entropy bonus at all
    # H_π's per-step constant is the λ-term's own (h_shift): never charged again by SAC
    assert eps_sac_config(SACConfig(survival_entropy="neutral"), 2.0, 7.0).survival_entropy == "paid"
    with pytest.raises(ValueError, match="non-negative"):
        eps_sac_config(SACConfig(), -1.0, 7.0)
    with pytest.raises(ValueError, match="positive"):
        eps_sac_config(SACConfig(), 2.0, 0.0)


# ---------------------------------------------------------------- the explicability score (Eq. 4.4)

EPISODES = 20_000
ROOM = """
#########
#......G#
#.......#
#.......#
#...S...#
#.......#
#.......#
#.......#
#########
"""


def _room(speed_a, noise_a, speed_h, noise_h, horizon):
    spec = {
        "layout": ROOM,
        "horizon": horizon,
        "start_jitter": 0.0,
        "dynamics": {"floor": {"speed": speed_a, "noise": noise_a}},
        "beliefs": {"person": {"floor": {"speed": speed_h, "noise": noise_h}}},
    }
    return world_from_dict(spec)


def _expect(f, dims, n=40):
    """E f(Z₁, …, Z_dims) over independent standard normals by Gauss–Hermite quadrature."""
    z, w = np.polynomial.hermite_e.hermegauss(n)
    w = w / np.sqrt(2 * np.pi)
    grids = np.meshgrid(*([z] * dims), indexing="ij")
    weights = np.prod(np.meshgrid(*([w] * dims), indexing="ij"), axis=0)
    return float(np.sum(weights * f(*grids)))


def test_explicability_matches_the_exact_kl_on_a_two_step_world(key):
    """Open room, two steps, no walls within reach: every density is Gaussian and the KL is an integral.

    Per coordinate i (the policies and the dynamics factorise over x and y):
    KL = KLπ(s₀) + E KL_T(a₀) + E KLπ(s₁) + E KL_T(a₁), each a Gaussian KL, the expectations
    over u₀ ~ π_θ(·|s₀), the noise of s₁ and u₁ ~ π_θ(·|s₁), by Gauss–Hermite quadrature.
    """
    v_a, sig_a, v_h, sig_h = 1.0, 0.05, 0.6, 0.2
    world = _room(v_a, sig_a, v_h, sig_h, horizon=2)
    k_th, c_th, ls_th = np.array([0.8, -0.5]), np.array([0.4, -0.2]), np.array([-0.7, -0.3])
    k_h, c_h, ls_h = np.array([0.2, 0.3]), np.array([-0.1, 0.5]), np.array([-0.2, -0.6])
    agent = linear_actor(k_th, c_th, ls_th)
    person = linear_actor(k_h, c_h, ls_h)

    def kl_gauss(m1, s1, m2, s2):
        return np.log(s2 / s1) + (s1**2 + (m1 - m2) ** 2) / (2 * s2**2) - 0.5

    def kl_t(a):
        return kl_gauss(0.5 * v_a * a, sig_a, 0.5 * v_h * a, sig_h)

    total = 0.0
    for i in range(2):
        x0 = 4.5

        def ob(x):
            return 2 * x / 9 - 1

        def m_th(x, i=i):
            return k_th[i] * ob(x) + c_th[i]

        def m_h(x, i=i):
            return k_h[i] * ob(x) + c_h[i]

        s_th, s_h = np.exp(ls_th[i]), np.exp(ls_h[i])

        def kl_pi(x, s_th=s_th, s_h=s_h, m_th=m_th, m_h=m_h):
            return kl_gauss(m_th(x), s_th, m_h(x), s_h)

        def x1(z0, e, m_th=m_th, s_th=s_th):
            return x0 + 0.5 * v_a * np.tanh(m_th(x0) + s_th * z0) + sig_a * e

        total += kl_pi(x0)
        total += _expect(lambda z0, m_th=m_th, s_th=s_th: kl_t(np.tanh(m_th(x0) + s_th * z0)), 1)
        total += _expect(lambda z0, e, kl_pi=kl_pi, x1=x1: kl_pi(x1(z0, e)), 2)
        total += _expect(
            lambda z0, e, z1, m_th=m_th, s_th=s_th, x1=x1: kl_t(np.tanh(m_th(x1(z0, e)) + s_th * z1)), 3, n=24
        )

    est = explicability(key, world, world.belief(), agent, person, episodes=EPISODES)
    assert abs(float(est.score) + total) < 4 * float(est.stderr), (float(est.score), -total, float(est.stderr))
    assert float(est.stderr) < 0.02 * total
    np.testing.assert_allclose(float(est.dynamics + est.policy), -float(est.score), rtol=1e-5)
    assert float(est.dynamics) > 0 and float(est.policy) > 0  # each part is itself a KL


def test_explicability_is_zero_when_the_agent_is_what_the_person_expects(key):
    world = _room(1.0, 0.05, 0.6, 0.2, horizon=2)  # the shapes of the test above: its compiled program
    actor = linear_actor(np.array([0.5, 0.5]), np.array([0.2, 0.0]), np.array([-1.0, -1.0]))
    est = explicability(key, world, world.params, actor, actor, episodes=EPISODES)
    np.testing.assert_array_equal(np.asarray(est.per_episode), 0.0)
    biased = explicability(key, world, world.belief(), actor, actor, episodes=EPISODES)  # the belief alone differs
    assert float(biased.score) < 0 and float(biased.policy) == 0.0


# ---------------------------------------------------------------- policy shaping


def test_product_of_known_gaussians():
    m1, s1, m2, s2 = 0.3, 0.5, -1.0, 0.8
    mean, log_std = gaussian_product(jnp.float32(m1), jnp.log(s1), jnp.float32(m2), jnp.log(s2))
    u = np.linspace(-6, 6, 200_001)
    prod = stats.norm.pdf(u, m1, s1) * stats.norm.pdf(u, m2, s2)
    prod /= np.trapezoid(prod, u)
    num_mean = np.trapezoid(u * prod, u)
    num_std = np.sqrt(np.trapezoid((u - num_mean) ** 2 * prod, u))
    np.testing.assert_allclose([float(mean), float(jnp.exp(log_std))], [num_mean, num_std], rtol=1e-4)
    np.testing.assert_allclose(prod, stats.norm.pdf(u, float(mean), float(jnp.exp(log_std))), atol=1e-4)
    # weights: π₁² π₂ has precision 2/σ₁² + 1/σ₂²
    wm, wls = gaussian_product(jnp.float32(m1), jnp.log(s1), jnp.float32(m2), jnp.log(s2), 2.0, 1.0)
    prec = 2 / s1**2 + 1 / s2**2
    np.testing.assert_allclose(
        [float(wm), float(jnp.exp(-2 * wls))], [(2 * m1 / s1**2 + m2 / s2**2) / prec, prec], rtol=1e-5
    )
    # two confident policies that disagree: a confident compromise (the D3 failure)
    cm, cls_ = gaussian_product(jnp.float32(-1.0), jnp.log(0.1), jnp.float32(1.0), jnp.log(0.1))
    np.testing.assert_allclose([float(cm), float(jnp.exp(cls_))], [0.0, 0.1 / np.sqrt(2)], atol=1e-6)


def test_shaped_policy_is_the_product_of_the_two_actors(key):
    env = linear_actor(np.array([0.5, 0.0]), np.array([1.0, -0.5]), np.array([-1.0, 0.0]))
    fb = linear_actor(np.array([0.0, 0.2]), np.array([-1.0, 0.5]), np.array([-0.5, -2.0]))
    policy = ShapedPolicy(env, fb)
    obs = jax.random.uniform(key, (16, 2), minval=-1, maxval=1)
    mean, log_std = shaped_dist(policy, obs)
    m_e, m_f = (
        0.5 * obs * jnp.array([1, 0]) + jnp.array([1.0, -0.5]),
        0.2 * obs * jnp.array([0, 1]) + jnp.array([-1.0, 0.5]),
    )
    p_e, p_f = jnp.exp(-2 * jnp.array([-1.0, 0.0])), jnp.exp(-2 * jnp.array([-0.5, -2.0]))
    np.testing.assert_allclose(mean, (p_e * m_e + p_f * m_f) / (p_e + p_f), rtol=1e-5)
    np.testing.assert_allclose(log_std, jnp.broadcast_to(-0.5 * jnp.log(p_e + p_f), log_std.shape), rtol=1e-5)
    act, logp = shaped_sample(policy, obs, jax.random.fold_in(key, 1))
    np.testing.assert_allclose(logp, squashed_log_prob(mean, log_std, act), rtol=1e-4, atol=1e-3)
