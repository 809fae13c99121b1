"""Bayesian layers: closed-form KL against Monte Carlo, weight draws as consistent functions."""

import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats

from mindgap.models.bayes import (
    Gaussian,
    init_gaussian,
    kl_divergence,
    sample_params,
    softplus_inverse,
    stddev,
)
from mindgap.models.mlp import init_mlp, mlp


def _random_posterior(key, sizes, sigma_range=(0.05, 0.6)):
    k_mean, k_sigma = jax.random.split(key)
    mean = init_mlp(k_mean, sizes)
    leaves, tree = jax.tree.flatten(mean)
    keys = jax.random.split(k_sigma, len(leaves))
    sigmas = [
        jax.random.uniform(k, x.shape, minval=sigma_range[0], maxval=sigma_range[1]) for k, x in zip(keys, leaves)
    ]
    rho = jax.tree.unflatten(tree, [jnp.log(jnp.expm1(s)) for s in sigmas])
    return Gaussian(mean, rho)


def _flat(tree):
    return np.concatenate([np.asarray(x, np.float64).ravel() for x in jax.tree.leaves(tree)])


def test_softplus_parameterisation(key):
    post = init_gaussian(init_mlp(key, (3, 4, 2)), sigma=0.02)
    np.testing.assert_allclose(_flat(stddev(post)), 0.02, rtol=1e-5)
    assert abs(float(jax.nn.softplus(softplus_inverse(0.3))) - 0.3) < 1e-6


def test_kl_matches_monte_carlo(key):
    """KL[q ‖ p] in closed form against the mean of log q(θ) − log p(θ) over draws θ ~ q."""
    k_post, k_prior, k_mc = jax.random.split(key, 3)
    sizes = (3, 4, 2)
    post = _random_posterior(k_post, sizes)
    mu, sigma = _flat(post.mean), _flat(stddev(post))
    for prior_mean, prior_std in ((None, 0.5), (init_mlp(k_prior, sizes), 0.3)):
        m = 0.0 if prior_mean is None else _flat(prior_mean)
        closed = float(kl_divergence(post, prior_mean, prior_std))
        batch = jax.vmap(lambda k: sample_params(post, k))(jax.random.split(k_mc, 4000))
        draws = np.concatenate([np.asarray(x, np.float64).reshape(4000, -1) for x in jax.tree.leaves(batch)], 1)
        log_ratio = (stats.norm.logpdf(draws, mu, sigma) - stats.norm.logpdf(draws, m, prior_std)).sum(-1)
        se = log_ratio.std() / np.sqrt(len(log_ratio))
        assert abs(closed - log_ratio.mean()) < 4 * se, (closed, log_ratio.mean(), se)
        assert closed > 0


def test_kl_is_zero_at_the_prior_and_grows_away_from_it(key):
    mean = init_mlp(key, (2, 3, 1))
    at_prior = init_gaussian(mean, sigma=0.1)
    assert abs(float(kl_divergence(at_prior, mean, 0.1))) < 1e-4
    shifted = at_prior._replace(mean=jax.tree.map(lambda x: x + 0.1, mean))
    n = sum(x.size for x in jax.tree.leaves(mean))
    # each parameter shifted by one prior standard deviation adds exactly ½
    np.testing.assert_allclose(float(kl_divergence(shifted, mean, 0.1)), 0.5 * n, rtol=1e-4)
    assert float(kl_divergence(init_gaussian(mean, sigma=0.01), mean, 0.1)) > 1.0


def test_weight_draws_are_shared_across_rows(key):
    """One draw of all weights is one function: identical rows get identical outputs."""
    post = _random_posterior(key, (3, 4, 1))
    x = jnp.ones((5, 3))
    out = mlp(sample_params(post, jax.random.fold_in(key, 1)), x)
    assert float(jnp.ptp(out)) == 0.0
    other = mlp(sample_params(post, jax.random.fold_in(key, 2)), x)
    assert float(jnp.abs(other - out).max()) > 0.0  # another draw is another function
