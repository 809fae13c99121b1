"""The agent's Gaussian dynamics model f_ψ: head, density, fitting with a validation split."""

import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats

from mindgap.data.stays import is_stay
from mindgap.models.gaussian_dynamics import (
    DynamicsConfig,
    Norm,
    dynamics_init,
    dynamics_log_prob,
    fit_norm,
    gaussian_head,
    log_density,
    next_state_log_prob,
    normalise_input,
    predict,
    train_dynamics,
)
from mindgap.models.mlp import mlp


def test_head_and_density_by_hand():
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.array([0.1, -0.2]), jnp.array([0.5, 2.0]))
    obs = jnp.array([0.3, 0.4])
    raw = jnp.array([1.0, -1.0, 0.0, 2.0])
    mean, std = gaussian_head(raw, norm, obs, min_std=0.01)
    np.testing.assert_allclose(mean, [0.3 + 0.1 + 0.5, 0.4 - 0.2 - 2.0], rtol=1e-6)
    np.testing.assert_allclose(std, [0.5 * (0.01 + np.log(2)), 2.0 * (0.01 + np.log1p(np.exp(2)))], rtol=1e-6)
    nxt = jnp.array([1.0, -1.0])
    expect = stats.norm.logpdf(np.asarray(nxt), np.asarray(mean), np.asarray(std)).sum()
    np.testing.assert_allclose(float(log_density(mean, std, nxt)), expect, rtol=1e-5)


def _heteroscedastic(key, n):
    """s' = s + 0.1 a + ε with ε's scale 0.01 where x < 0 and 0.05 where x ≥ 0."""
    k_s, k_a, k_e = jax.random.split(key, 3)
    obs = jax.random.uniform(k_s, (n, 2), minval=-1, maxval=1)
    act = jax.random.uniform(k_a, (n, 2), minval=-1, maxval=1)
    scale = jnp.where(obs[:, :1] < 0, 0.01, 0.05)
    return obs, act, obs + 0.1 * act + scale * jax.random.normal(k_e, (n, 2))


def test_fit_learns_mean_and_noise_and_ignores_invalid_rows(key):
    obs, act, nxt = _heteroscedastic(key, 3000)
    valid = jnp.arange(3000) < 2500
    nxt = jnp.where(valid[:, None], nxt, 1e3)  # garbage in the unused rows must not matter
    cfg = DynamicsConfig(hidden=(32, 32), max_epochs=30, patience=4, lr=3e-3)
    model, info = jax.jit(train_dynamics, static_argnames="cfg")(jax.random.fold_in(key, 1), obs, act, nxt, valid, cfg)
    probe = jnp.array([[-0.5, 0.0], [0.5, 0.0]])
    a = jnp.array([[1.0, -1.0], [1.0, -1.0]])
    mean, std = predict(model, probe, a, cfg.min_std)
    np.testing.assert_allclose(mean, probe + 0.1 * a, atol=0.02)
    std = np.asarray(std).mean(-1)
    assert 0.005 < std[0] < 0.02 and 0.03 < std[1] < 0.07, std
    assert int(info.epochs) <= cfg.max_epochs and np.isfinite(float(info.val_nll))
    lp = dynamics_log_prob(model, obs[:2500], act[:2500], nxt[:2500], cfg.min_std)
    assert np.all(np.isfinite(np.asarray(lp)))
    norm = fit_norm(obs, act, nxt, valid)
    assert float(jnp.abs(norm.out_mean).max()) < 0.01  # computed on the valid rows only


def test_early_stopping_keeps_the_best_epoch(key):
    """With few rows and a large model, validation loss turns up; the fit stops and keeps the best epoch."""
    obs, act, nxt = _heteroscedastic(key, 60)
    valid = jnp.ones(60, bool)
    cfg = DynamicsConfig(hidden=(64, 64), max_epochs=200, patience=3, lr=1e-2, val_frac=0.3, steps_per_epoch=20)
    model, info = jax.jit(train_dynamics, static_argnames="cfg")(jax.random.fold_in(key, 2), obs, act, nxt, valid, cfg)
    assert int(info.epochs) < cfg.max_epochs
    # warm start from the returned model: its validation loss is the starting point, never worse
    _, again = jax.jit(train_dynamics, static_argnames="cfg")(
        jax.random.fold_in(key, 2), obs, act, nxt, valid, cfg, model
    )
    assert float(again.val_nll) <= float(info.val_nll) + 1e-5


def test_stay_head_mixture_by_hand():
    """With a fifth output the next state is p_stay · δ(s) + (1 − p_stay) · the Gaussian; without, the Gaussian."""
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.array([0.5, 2.0]))
    obs = jnp.array([[0.3, 0.4], [0.3, 0.4]])
    moved = jnp.array([[0.9, -0.1], [0.3, 0.4]])  # a move, then a stay
    raw4 = jnp.array([[1.0, -1.0, 0.0, 2.0]] * 2)
    raw5 = jnp.concatenate([raw4, jnp.full((2, 1), 0.7)], -1)
    gauss = log_density(*gaussian_head(raw4, norm, obs, 0.01), moved)
    np.testing.assert_allclose(next_state_log_prob(raw4, norm, obs, moved, 0.01), gauss, rtol=1e-6)
    # the stay logit does not leak into the scale head
    np.testing.assert_allclose(gaussian_head(raw5, norm, obs, 0.01)[1], gaussian_head(raw4, norm, obs, 0.01)[1])
    p_stay = 1 / (1 + np.exp(-0.7))
    np.testing.assert_allclose(
        next_state_log_prob(raw5, norm, obs, moved, 0.01),
        [np.log1p(-p_stay) + float(gauss[0]), np.log(p_stay)],
        rtol=1e-5,
    )


def test_stay_head_learns_the_stay_rate_and_keeps_the_noise_narrow(key):
    """Stays at 40% where x ≥ 0: the head learns that rate; the Gaussian keeps the moves' scale there,
    where a model without the head widens to cover the stays."""
    obs, act, moved = _heteroscedastic(key, 4000)
    stay = (obs[:, 0] >= 0) & (jax.random.uniform(jax.random.fold_in(key, 3), (4000,)) < 0.4)
    nxt = jnp.where(stay[:, None], obs, moved)
    valid = jnp.ones(4000, bool)
    cfg = DynamicsConfig(hidden=(32, 32), max_epochs=30, patience=4, lr=3e-3)
    train = jax.jit(train_dynamics, static_argnames="cfg")
    norm = fit_norm(obs, act, nxt, valid)
    probe, a = jnp.array([[-0.5, 0.0], [0.5, 0.0]]), jnp.array([[1.0, -1.0], [1.0, -1.0]])
    stds = {}
    for with_head in (False, True):
        init = dynamics_init(jax.random.fold_in(key, 4), 2, 2, cfg, norm, stay=with_head)
        model, _ = train(jax.random.fold_in(key, 5), obs, act, nxt, valid, cfg, init)
        stds[with_head] = np.asarray(predict(model, probe, a, cfg.min_std)[1]).mean(-1)
        if with_head:

            def p_stay(o, u):
                return np.asarray(jax.nn.sigmoid(mlp(model.params, normalise_input(norm, o, u))[:, -1]))

            p = p_stay(probe, a)
            assert p[0] < 0.05 and 0.3 < p[1] < 0.5, p
            lp = np.asarray(dynamics_log_prob(model, obs, act, nxt, cfg.min_std))
            stayed = np.asarray(stay)
            np.testing.assert_allclose(lp[stayed], np.log(p_stay(obs, act))[stayed], rtol=1e-5)
    assert 0.03 < stds[True][1] < 0.07, stds  # the moves' own noise
    # a plain Gaussian widens to cover the stays (here 0.1-cell steps: by about half)
    assert stds[False][1] > 1.3 * stds[True][1], stds


def test_a_stay_read_back_with_a_last_bit_difference_is_scored_as_a_stay():
    """Two observations of one state may differ in the last bit (the loop rounds ``observe`` in two
    places); the stay head scores such a step by p_stay, as an exact stay, and a real move (here
    10⁻⁴, far below any world's noise) by the Gaussian."""
    norm = Norm(jnp.zeros(4), jnp.ones(4), jnp.zeros(2), jnp.array([0.5, 2.0]))
    obs = jnp.array([[0.38133138, -0.4017267]] * 3)
    last_bit = obs.at[:, 1].set(jnp.nextafter(obs[:, 1], -jnp.inf))
    nxt = jnp.stack([obs[0], last_bit[1], obs[2] + 1e-4])
    assert np.asarray(last_bit[1] != obs[1]).any()
    raw = jnp.array([[1.0, -1.0, 0.0, 2.0, 0.7]] * 3)
    lp = np.asarray(next_state_log_prob(raw, norm, obs, nxt, 0.01))
    np.testing.assert_allclose(lp[:2], np.log(1 / (1 + np.exp(-0.7))), rtol=1e-6)
    gauss = float(log_density(*gaussian_head(raw[:, :4], norm, obs, 0.01), nxt)[2])
    np.testing.assert_allclose(lp[2], np.log1p(-1 / (1 + np.exp(-0.7))) + gauss, rtol=1e-5)


def test_is_stay_tolerates_rounding_only():
    x = jnp.array([[0.3, -12.5], [0.0, 1e-9], [7.0, 7.0]])
    assert np.asarray(is_stay(x, jnp.nextafter(x, jnp.inf))).all()
    assert not np.asarray(is_stay(x, x + jnp.array([0.0, 1e-4]))).any()  # 10⁻⁴: a move, at any scale here
