"""SAC's update against a naive per-sample reference on a tiny batch."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from mindgap.algorithms.sac import SACConfig, sac_init, sac_losses, sac_update
from mindgap.data.batch import Batch
from mindgap.models.actor import sample_action


def _net(params, x):
    """Naive MLP on one input vector."""
    for i, (w, b) in enumerate(params):
        x = x @ w + b
        if i < len(params) - 1:
            x = jnp.maximum(x, 0.0)
    return x


def _naive_action(actor, o, eps):
    out = _net(actor, o)
    mean, log_std = out[:2], jnp.clip(out[2:], -20.0, 2.0)
    u = mean + jnp.exp(log_std) * eps
    logp = 0.0
    for j in range(2):
        logp += -0.5 * eps[j] ** 2 - log_std[j] - 0.5 * np.log(2 * np.pi) - jnp.log(1 - jnp.tanh(u[j]) ** 2)
    return jnp.tanh(u), logp


def _critic_i(critic, i):
    return jax.tree.map(lambda x: x[i], critic)


def naive_update(state, batch, key, cfg):
    """The SAC update written out sample by sample (no vectorisation, plain formulas)."""
    k_next, k_pi = jax.random.split(key)
    n = batch.obs.shape[0]
    eps_next = jax.random.normal(k_next, (n, 2))
    eps_pi = jax.random.normal(k_pi, (n, 2))
    p = state.params
    alpha = jnp.exp(p.log_alpha)
    ys = []
    for b in range(n):
        a2, lp2 = _naive_action(p.actor, batch.next_obs[b], eps_next[b])
        x2 = jnp.concatenate([batch.next_obs[b], a2])
        qmin = jnp.minimum(_net(_critic_i(p.target, 0), x2)[0], _net(_critic_i(p.target, 1), x2)[0])
        gamma = cfg.gamma if batch.discount is None else batch.discount[b]
        ys.append(batch.reward[b] + gamma * (1 - batch.terminal[b]) * (qmin - alpha * lp2))

    def critic_loss(critic):
        total = 0.0
        for i in range(2):
            total += (
                sum(
                    (_net(_critic_i(critic, i), jnp.concatenate([batch.obs[b], batch.act[b]]))[0] - ys[b]) ** 2
                    for b in range(n)
                )
                / n
            )
        return total

    opt = optax.adam(cfg.lr)
    g = jax.grad(critic_loss)(p.critic)
    upd, _ = opt.update(g, state.critic_opt, p.critic)
    critic = optax.apply_updates(p.critic, upd)

    def actor_loss(actor):
        total, lps = 0.0, []
        for b in range(n):
            a, lp = _naive_action(actor, batch.obs[b], eps_pi[b])
            x = jnp.concatenate([batch.obs[b], a])
            q = jnp.minimum(_net(_critic_i(critic, 0), x)[0], _net(_critic_i(critic, 1), x)[0])
            total += alpha * lp - q
            lps.append(lp)
        return total / n, jnp.stack(lps)

    (la, lps), ga = jax.value_and_grad(actor_loss, has_aux=True)(p.actor)
    upd, _ = opt.update(ga, state.actor_opt, p.actor)
    actor = optax.apply_updates(p.actor, upd)
    # α: gradient of −log α (mean log π + target entropy) w.r.t. log α, then Adam
    g_alpha = -(jnp.mean(lps) - 2.0)
    upd, _ = opt.update(g_alpha, state.alpha_opt, p.log_alpha)
    log_alpha = optax.apply_updates(p.log_alpha, upd)
    target = jax.tree.map(lambda t, c: (1 - cfg.tau) * t + cfg.tau * c, p.target, critic)
    return actor, critic, target, log_alpha, la


@pytest.fixture
def setup(key):
    cfg = SACConfig(hidden=(8, 8), batch_size=4, lr=1e-2)
    k_init, k_data, k_upd = jax.random.split(key, 3)
    state = sac_init(k_init, 2, 2, cfg)
    ks = jax.random.split(k_data, 5)
    batch = Batch(
        obs=jax.random.normal(ks[0], (4, 2)),
        act=jax.random.uniform(ks[1], (4, 2), minval=-0.9, maxval=0.9),
        reward=jax.random.normal(ks[2], (4,)),
        next_obs=jax.random.normal(ks[3], (4, 2)),
        terminal=jnp.array([0.0, 1.0, 0.0, 0.0]),
    )
    return cfg, state, batch, k_upd


def test_update_matches_naive_reference(setup):
    cfg, state, batch, key = setup
    new, metrics = jax.jit(sac_update, static_argnums=3)(state, batch, key, cfg)
    actor, critic, target, log_alpha, la = naive_update(state, batch, key, cfg)

    def close(a, b):
        return jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, rtol=2e-4, atol=2e-5), a, b)

    close(new.params.critic, critic)
    close(new.params.actor, actor)
    close(new.params.target, target)
    np.testing.assert_allclose(new.params.log_alpha, log_alpha, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(metrics["actor_loss"], la, rtol=1e-4, atol=1e-5)
    assert int(new.updates) == 1


def test_update_with_multistep_discounts_matches_naive_reference(setup):
    cfg, state, batch, key = setup
    batch = batch._replace(discount=jnp.array([0.99**3, 0.99, 0.99**2, 0.5]))
    new, _ = jax.jit(sac_update, static_argnums=3)(state, batch, key, cfg)
    _, critic, *_ = naive_update(state, batch, key, cfg)
    jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, rtol=2e-4, atol=2e-5), new.params.critic, critic)
    # the discounts are what the targets use (Adam's first step hides the scale of a gradient)
    y = sac_losses(state.params, batch, key, cfg)[2]
    y_plain = sac_losses(state.params, batch._replace(discount=None), key, cfg)[2]
    np.testing.assert_array_equal(np.asarray(y[1]), np.asarray(y_plain[1]))  # terminal: no bootstrap either way
    assert not np.isclose(float(y[3]), float(y_plain[3]))


def test_config_rejects_empty_updates():
    for bad in (dict(utd=0), dict(batch_size=0), dict(n_step=0)):
        with pytest.raises(ValueError, match="at least 1"):
            SACConfig(**bad)


def test_fixed_alpha_stays_fixed(setup):
    _, state, batch, key = setup
    cfg = SACConfig(hidden=(8, 8), batch_size=4, alpha=0.2)
    state = sac_init(jax.random.split(key)[0], 2, 2, cfg)
    new, m = sac_update(state, batch, key, cfg)
    assert float(m["alpha"]) == pytest.approx(0.2)


def test_alpha_extra_adds_to_the_tuned_alpha_which_keeps_tuning(setup):
    cfg, state, batch, key = setup
    extra = dataclasses.replace(cfg, alpha_extra=0.3)
    plus = state.params._replace(log_alpha=jnp.log(jnp.exp(state.params.log_alpha) + 0.3))
    y_extra, y_plus = sac_losses(state.params, batch, key, extra)[2], sac_losses(plus, batch, key, cfg)[2]
    np.testing.assert_allclose(y_extra, y_plus, rtol=1e-5)  # the critic's target sees α_tuned + 0.3
    new, m = sac_update(state, batch, key, extra)
    _, m_plain = sac_update(state, batch, key, cfg)
    assert float(new.params.log_alpha) != float(state.params.log_alpha)  # the tuned part still moves
    assert float(m["alpha"]) == pytest.approx(float(jnp.exp(new.params.log_alpha)) + 0.3)
    assert float(m["actor_loss"]) != pytest.approx(float(m_plain["actor_loss"]))  # the actor pays the larger α
    with pytest.raises(ValueError, match="alpha_extra must be non-negative"):
        SACConfig(alpha_extra=-0.1)


def test_actions_are_squashed_and_log_probs_match_density(key):
    cfg = SACConfig(hidden=(8, 8))
    actor = sac_init(key, 2, 2, cfg).params.actor
    obs = jnp.zeros((20000, 2))
    a, logp = sample_action(actor, obs, key)
    assert float(jnp.abs(a).max()) < 1.0
    # Monte Carlo: E[-log π] is the entropy; compare against a histogram estimate of the density
    hist, xe, ye = np.histogram2d(np.asarray(a[:, 0]), np.asarray(a[:, 1]), bins=20, range=[[-1, 1], [-1, 1]])
    dens = hist / hist.sum() / (0.1 * 0.1)
    ix = np.clip(((np.asarray(a) + 1) / 0.1).astype(int), 0, 19)
    est = np.log(np.maximum(dens[ix[:, 0], ix[:, 1]], 1e-9))
    assert float(np.mean(est)) == pytest.approx(float(jnp.mean(logp)), abs=0.15)
