"""GeReL's probabilistic model and its two ELBO gradient estimators (§2.2.2).

- :func:`believed_q_values`: the person's optimal Q-values under each sampled
  ``(w, Θ)`` — value iteration over the belief's successor form
  (:func:`mindgap.planning.sparse_q_values`), dense only for ``full`` beliefs.
- :func:`rating_log_likelihood`: ``log p(Γ | Z, w, Θ)`` for a batch of sampled models.
- :func:`pathwise_elbo`: a reparameterised ELBO estimate, differentiable in ``(μ, α)``.
- :func:`score_gradient`: the dissertation's score-function estimate of the ELBO's
  gradient (Eq. 2.4 and its ``α`` analogue) with control variates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..data.demos import RatedDemonstrations
from ..envs.tabular import TabularMDP
from ..models import dirichlet
from ..models.belief import BeliefSpace
from ..models.rating import censored_log_likelihood, mean_log_policy_from_counts
from ..planning import q_values, sparse_q_values
from ..planning.sparse_value_iteration import sparse_form
from ._restarts import RestartSchedule


@dataclass(frozen=True)
class GeReLConfig(RestartSchedule):
    """Hyperparameters of GeReL (Algorithm 1); the restart schedule's objective is the ELBO."""

    estimator: Literal["pathwise", "score"] = "pathwise"
    """ELBO gradient estimator: ``pathwise`` (reparameterised) or ``score`` (the paper's)."""
    n_samples: int = 8
    """Monte Carlo samples of ``(w, Θ)`` per iteration."""
    anneal_iter: int = 300
    """Pathwise only: the likelihood's weight rises linearly from 0 to 1 over these
    iterations (annealed VI), which lets restarts leave poor basins early."""
    learning_rate: float = 0.05
    """Adam step size on ``(μ, log α)`` (pathwise)."""
    adagrad_rate_mu: float = 0.5
    """AdaGrad base step for ``μ`` (score)."""
    adagrad_rate_alpha: float = 2.0
    """AdaGrad base step for ``α`` (score)."""
    reward_prior_std: float = 10.0
    """Prior ``p(w) = N(0, σ_p² I)``."""
    reward_posterior_std: float = 0.1
    """Fixed ``Σ = σ_q² I`` of ``q(w)``."""
    belief_prior: float = 1.0
    """Prior ``p(θ_i) = Dir(α_0 · 1)``: 1 is uniform over each factor's simplex."""
    init_reward_std: float = 2.0
    """Restart initialisation ``μ ~ N(0, s² I)``."""
    init_concentration: float = 5.0
    """Restart initialisation ``α = c · u``, ``u`` a random point of the simplex (plus 0.5)."""
    rating_noise: float = 0.5
    """``σ`` of the rating likelihood."""
    gamma_max: float = 10.0
    """Highest rating."""
    beta: float = 1.0
    """Rationality of the person's softmax policy."""
    vi_iterations: int = 100
    """Accuracy of value iteration: each evaluation is certified at least as accurate as
    this many plain sweeps and stops as soon as it is (never more sweeps)."""
    freeze_belief: bool = False
    """GeReL⁻: keep the belief at the true dynamics and learn only ``μ``."""

    def __post_init__(self):
        super().__post_init__()
        if self.estimator not in ("pathwise", "score"):
            raise ValueError(f"unknown estimator {self.estimator!r}: use 'pathwise' or 'score'")
        for name in ("n_samples", "vi_iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
        if self.n_samples < 2 and self.estimator == "score":
            raise ValueError("the score estimator's control variates need n_samples >= 2")


SPARSE_MAX_WIDTH = 16
"""Widest successor list (non-zeros per transition row) that value iteration keeps sparse."""


class RatingData(NamedTuple):
    """What a rating-based fit reads: the world, the belief space, step counts and ratings.

    ``true_form`` is the true dynamics as ``(probs, successors)`` ``[S, A, K]`` for
    GeReL⁻, or ``None`` when rows have more than :data:`SPARSE_MAX_WIDTH` non-zeros.
    """

    mdp: TabularMDP
    space: BeliefSpace
    counts: jnp.ndarray
    ratings: jnp.ndarray
    true_form: tuple[jnp.ndarray, jnp.ndarray] | None = None

    @classmethod
    def build(cls, mdp: TabularMDP, space: BeliefSpace, rated: RatedDemonstrations) -> RatingData:
        counts = rated.demos.step_counts(mdp.n_states, mdp.n_actions)
        probs, successors = sparse_form(np.asarray(mdp.transitions))
        true_form = (jnp.asarray(probs), jnp.asarray(successors)) if probs.shape[-1] <= SPARSE_MAX_WIDTH else None
        return cls(mdp, space, counts, jnp.asarray(rated.ratings, jnp.float32), true_form)


def believed_q_values(w, theta, data: RatingData, cfg: GeReLConfig) -> jnp.ndarray:
    """The person's optimal ``Q`` ``[B, S, A]`` under each sample ``(w_b, θ_b)`` (§2.2.1–2.2.2).

    ``θ`` ``[B, F, M]`` (``None`` for GeReL⁻, which plans in the true dynamics). Local
    beliefs (tied, per-(s,a), factored) run value iteration on their successor form; a
    ``full`` belief, whose rows have ``S`` successors, on the dense tensor.
    """
    mdp, space = data.mdp, data.space
    reward = mdp.reward(w)
    if theta is None:
        if data.true_form is None:
            return q_values(mdp.transitions, reward, mdp.discount, cfg.vi_iterations)
        return sparse_q_values(*data.true_form, reward, mdp.discount, cfg.vi_iterations)
    if space.kind == "full" or space.targets.shape[-1] > SPARSE_MAX_WIDTH:
        return q_values(space.to_transitions(theta), reward, mdp.discount, cfg.vi_iterations)
    probs, successors = space.successor_form(theta)
    return sparse_q_values(probs, successors, reward, mdp.discount, cfg.vi_iterations)


def rating_log_likelihood(w, theta, data: RatingData, cfg: GeReLConfig) -> jnp.ndarray:
    """``log p(Γ | Z, w, Θ)`` for ``w [B, K]`` and belief factors ``θ [B, F, M]`` (or ``None``), ``[B]``.

    The rating's mean is ``γ_max (Π_i π̃(a_i|s_i))^{1/n}`` with ``π̃ ∝ exp(β Q)`` (§2.2.2).
    """
    q = believed_q_values(w, theta, data, cfg)
    log_pi = jax.nn.log_softmax(cfg.beta * q, axis=-1)
    mean = cfg.gamma_max * jnp.exp(mean_log_policy_from_counts(log_pi, data.counts))
    ll = censored_log_likelihood(data.ratings, mean, cfg.rating_noise, cfg.gamma_max)
    return ll.sum(-1)


def _gauss_logpdf(x, mean, std):
    k = x.shape[-1]
    return -0.5 * (((x - mean) / std) ** 2).sum(-1) - k * jnp.log(std) - 0.5 * k * jnp.log(2 * jnp.pi)


def draw(key, mu, alpha, data: RatingData, cfg: GeReLConfig):
    """``n_samples`` draws ``w ~ q(w)`` ``[n, K]`` and ``log θ ~ q(Θ)`` ``[n, F, M]`` (``None`` for GeReL⁻)."""
    kw, kt = jax.random.split(key)
    sq = cfg.reward_posterior_std
    w = mu + sq * jax.random.normal(kw, (cfg.n_samples,) + mu.shape)
    if cfg.freeze_belief:
        return w, None
    return w, dirichlet.sample_log(kt, alpha, data.space.mask, (cfg.n_samples,))


def _theta(log_theta):
    return None if log_theta is None else jnp.exp(log_theta)


def pathwise_elbo(mu, alpha, key, data: RatingData, cfg: GeReLConfig, temperature=1.0):
    """ELBO estimate with reparameterised samples; prior and entropy terms in closed form.

    ``temperature`` scales the likelihood (annealed VI); 1 is the ELBO itself.
    """
    mask = data.space.mask
    sp, sq = cfg.reward_prior_std, cfg.reward_posterior_std
    w, log_theta = draw(key, mu, alpha, data, cfg)
    k = mu.shape[-1]
    elbo = temperature * rating_log_likelihood(w, _theta(log_theta), data, cfg).mean()
    elbo += -0.5 * ((mu**2).sum() + k * sq**2) / sp**2 - k * jnp.log(sp) - 0.5 * k * jnp.log(2 * jnp.pi)
    elbo += k * (0.5 * jnp.log(2 * jnp.pi * jnp.e) + jnp.log(sq))
    if not cfg.freeze_belief:
        alpha0 = jnp.full(mask.shape, cfg.belief_prior)
        elbo += dirichlet.cross_entropy_term(alpha, alpha0, mask).sum()
        elbo += dirichlet.entropy(alpha, mask).sum()
    return elbo


def control_variate_mean(f, g):
    """``mean(f − a g)`` with ``a = cov(f, g) / var(g)`` per coordinate (§2.2.2)."""
    fc = f - f.mean(0)
    gc = g - g.mean(0)
    a = (fc * gc).mean(0) / jnp.maximum((gc * gc).mean(0), 1e-12)
    return (f - a * g).mean(0)


def score_gradient(mu, alpha, key, data: RatingData, cfg: GeReLConfig):
    """Score-function ELBO gradient (Eq. 2.4 and the ``α_i`` analogue) with control variates.

    ``f = ∇ log q · (log p(Γ|Z, w, Θ) + log p(·) − log q(·))`` per factor, ``g = ∇ log q``.

    Returns:
        ``(ELBO estimate, ∇_μ [K], ∇_α [F, M])``.
    """
    mask = data.space.mask
    sp, sq = cfg.reward_prior_std, cfg.reward_posterior_std
    w, log_theta = draw(key, mu, alpha, data, cfg)
    ll = rating_log_likelihood(w, _theta(log_theta), data, cfg)  # [S]
    log_pw = _gauss_logpdf(w, 0.0, sp)
    log_qw = _gauss_logpdf(w, mu, sq)
    g_mu = (w - mu) / sq**2
    grad_mu = control_variate_mean(g_mu * (ll + log_pw - log_qw)[:, None], g_mu)
    elbo_s = ll + log_pw - log_qw
    if cfg.freeze_belief:
        return elbo_s.mean(), grad_mu, jnp.zeros_like(alpha)
    alpha0 = jnp.full(mask.shape, cfg.belief_prior)
    log_pt = dirichlet.log_prob(log_theta, alpha0, mask)  # [S, F]
    log_qt = dirichlet.log_prob(log_theta, alpha, mask)
    g_a = dirichlet.score(log_theta, alpha, mask)  # [S, F, M]
    f_a = g_a * (ll[:, None] + log_pt - log_qt)[..., None]
    grad_alpha = jnp.where(mask, control_variate_mean(f_a, g_a), 0.0)
    return (elbo_s + (log_pt - log_qt).sum(-1)).mean(), grad_mu, grad_alpha
