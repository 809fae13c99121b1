import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import polygamma
from jax.scipy.stats import dirichlet as jdir

from mindgap import rng
from mindgap.models import dirichlet


def test_loggamma_samples_have_gamma_moments():
    a = jnp.asarray([0.05, 0.5, 1.0, 5.0, 100.0])
    x = np.exp(np.asarray(dirichlet.loggamma(rng.key(0), jnp.broadcast_to(a, (100_000, 5))), np.float64))
    np.testing.assert_allclose(x.mean(0), a, rtol=0.03)
    np.testing.assert_allclose(x.var(0), a, rtol=0.06)


def test_loggamma_gradient_is_unbiased():
    # d/dα E[log x] = ψ'(α) for x ~ Gamma(α)
    a = jnp.asarray([0.05, 0.5, 1.0, 5.0, 100.0])
    g = jax.grad(lambda a: dirichlet.loggamma(rng.key(1), jnp.broadcast_to(a, (100_000, 5))).mean(0).sum())(a)
    np.testing.assert_allclose(g, polygamma(1, a), rtol=0.03)


def test_log_prob_matches_scipy_and_masks():
    alpha = jnp.asarray([[2.0, 3.0, 0.5], [1.0, 4.0, 9.0]])
    mask = jnp.ones_like(alpha, bool)
    log_theta = dirichlet.sample_log(rng.key(2), alpha, mask)
    theta = jnp.exp(log_theta)
    for i in range(2):
        np.testing.assert_allclose(
            dirichlet.log_prob(log_theta[i], alpha[i], mask[i]), jdir.logpdf(theta[i], alpha[i]), rtol=1e-4
        )
    # a masked component behaves as if absent
    m = jnp.asarray([True, True, False])
    lt = dirichlet.sample_log(rng.key(3), alpha[0], m)
    assert float(jnp.exp(lt[2])) == 0.0
    np.testing.assert_allclose(
        dirichlet.log_prob(lt, alpha[0], m), jdir.logpdf(jnp.exp(lt[:2]), alpha[0, :2]), rtol=1e-4
    )


def test_entropy_and_score_match_monte_carlo():
    alpha = jnp.asarray([2.0, 3.0, 0.7])
    mask = jnp.ones(3, bool)
    lt = dirichlet.sample_log(rng.key(4), alpha, mask, (200_000,))
    mc_entropy = -float(dirichlet.log_prob(lt, alpha, mask).mean())
    assert abs(float(dirichlet.entropy(alpha, mask)) - mc_entropy) < 0.02
    # the score has mean zero
    np.testing.assert_allclose(dirichlet.score(lt, alpha, mask).mean(0), 0.0, atol=0.02)
    np.testing.assert_allclose(jnp.exp(lt).mean(0), dirichlet.mean(alpha, mask), atol=0.005)
