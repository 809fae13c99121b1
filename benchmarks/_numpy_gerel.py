"""A straightforward NumPy GeReL iteration (score-function estimator), the reference for speed.

Per Monte Carlo sample, in a Python loop: draw ``w`` and ``Θ``, build the transition
tensor, run value iteration, score the demonstrations, and form the score-function
terms; then control variates and one AdaGrad step — Algorithm 1 as written.
"""

from __future__ import annotations

import numpy as np
from scipy.special import digamma, gammaln, log_ndtr


def expand(theta, factor, targets, mask, n_states):
    n_s, n_a, n_m = targets.shape
    t = np.zeros((n_s, n_a, n_states))
    for s in range(n_s):
        for a in range(n_a):
            f = factor[s, a]
            for m in range(n_m):
                if mask[f, m]:
                    t[s, a, targets[s, a, m]] += theta[f, m]
    return t


def value_iteration(t, r, gamma, n_iter):
    v = np.zeros(len(r))
    for _ in range(n_iter):
        v = (r[:, None] + gamma * t @ v).max(1)
    return r[:, None] + gamma * t @ v


def log_dirichlet(theta, alpha):
    return ((alpha - 1) * np.log(theta)).sum(-1) - (gammaln(alpha).sum(-1) - gammaln(alpha.sum(-1)))


def iteration(
    state, rng, data, n_samples=64, sq=0.1, sp=10.0, gamma_max=10.0, noise=0.5, vi_iter=100, rate_mu=0.5, rate_alpha=2.0
):
    mu, alpha, acc_mu, acc_alpha = state
    feats, gamma, factor, targets, mask, states, actions, ratings = data
    n_f = alpha.shape[0]
    f_mu, g_mu, f_a, g_a = [], [], [], []
    for _ in range(n_samples):
        w = mu + sq * rng.normal(size=mu.shape)
        theta = np.stack([rng.dirichlet(alpha[f]) for f in range(n_f)])
        theta = np.maximum(theta, 1e-300)
        t = expand(theta, factor, targets, mask, feats.shape[0])
        q = value_iteration(t, feats @ w, gamma, vi_iter)
        log_pi = q - np.log(np.exp(q - q.max(1, keepdims=True)).sum(1, keepdims=True)) - q.max(1, keepdims=True)
        mean = gamma_max * np.exp(log_pi[states, actions].mean(1))
        z = (ratings - mean) / noise
        ll = np.where(
            ratings <= 0,
            log_ndtr(z),
            np.where(ratings >= gamma_max, log_ndtr(-z), -0.5 * z**2 - np.log(noise) - 0.5 * np.log(2 * np.pi)),
        ).sum()
        log_pw = -0.5 * (w**2).sum() / sp**2
        log_qw = -0.5 * ((w - mu) ** 2).sum() / sq**2
        g = (w - mu) / sq**2
        g_mu.append(g)
        f_mu.append(g * (ll + log_pw - log_qw))
        score = digamma(alpha.sum(-1, keepdims=True)) - digamma(alpha) + np.log(theta)
        h = ll + log_dirichlet(theta, np.ones_like(alpha)) - log_dirichlet(theta, alpha)
        g_a.append(score)
        f_a.append(score * h[:, None])

    def cv(f, g):
        f, g = np.array(f), np.array(g)
        a = ((f - f.mean(0)) * (g - g.mean(0))).mean(0) / np.maximum(g.var(0), 1e-12)
        return (f - a * g).mean(0)

    grad_mu, grad_alpha = cv(f_mu, g_mu), cv(f_a, g_a)
    acc_mu, acc_alpha = acc_mu + grad_mu**2, acc_alpha + grad_alpha**2
    mu = mu + rate_mu * grad_mu / (np.sqrt(acc_mu) + 1e-8)
    alpha = np.clip(alpha + rate_alpha * grad_alpha / (np.sqrt(acc_alpha) + 1e-8), 1e-3, 1e5)
    return mu, alpha, acc_mu, acc_alpha
