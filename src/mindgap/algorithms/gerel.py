"""GeReL: joint variational inference of reward and believed dynamics from ratings (ch. 2).

Model (§2.2): ``w ~ N(0, σ_p² I)``, ``θ_i ~ Dir(α_0)`` for each belief factor, the
person's softmax policy ``π̃`` of value iteration under ``(w · φ, T(θ))``, and each
rating ``~ N(γ_max · (Π π̃(a_i|s_i))^{1/n}, σ²)`` censored to ``[0, γ_max]``.
Variational family ``q(w) = N(μ, σ_q² I)`` (``σ_q`` fixed, as in the dissertation) and
``q(θ_i) = Dir(α_i)``.

Two gradient estimators of the ELBO:

- ``"score"`` — the dissertation's Algorithm 1: score-function (black-box) gradients,
  Eq. 2.4 for ``μ`` and its analogue for each ``α_i``, control variates with the score
  as ``g`` and ``a = cov(f, g) / var(g)`` per coordinate, AdaGrad step sizes, ``α``
  projected back to positive values.
- ``"pathwise"`` — the same ELBO with reparameterised samples (``w = μ + σ_q ε``;
  Dirichlet via implicit reparameterisation of JAX's Gamma sampler), closed-form
  entropies and prior terms, Adam on ``(μ, log α)``. The default: it reaches the
  Table 1 targets in far fewer iterations (``benchmarks/estimators.py``).

GeReL⁻ is the same inference with the belief frozen to the true dynamics
(``freeze_belief=True``). Many local optima exist (a flipped reward with a permuted
belief explains ratings almost as well, SPEC §4), so every fit runs vmapped random
restarts and keeps the one with the highest ELBO.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..envs.tabular import TabularMDP
from ..feedback.demos import RatedDemonstrations
from ..models import dirichlet
from ..models.belief import BeliefSpace
from ..models.rating import censored_log_likelihood, mean_log_policy_from_counts
from ..planning import q_values
from ._restarts import RestartRun, run_restarts


@dataclass(frozen=True)
class GeReLConfig:
    """Hyperparameters of GeReL (Algorithm 1)."""

    estimator: Literal["pathwise", "score"] = "pathwise"
    """ELBO gradient estimator: ``pathwise`` (reparameterised) or ``score`` (the paper's)."""
    n_samples: int = 8
    """Monte Carlo samples of ``(w, Θ)`` per iteration."""
    max_iter: int = 1500
    """Iteration cap (MaxIter)."""
    check_every: int = 50
    """Iterations between convergence tests (and learning-curve points)."""
    tol: float = 1e-4
    """Converged when the ELBO's chunk mean moves less than this per rating."""
    restarts: int = 32
    """Random restarts run side by side; the highest ELBO wins."""
    keep: int = 4
    """Restarts that go on after screening (the rest stop at ``screen_iter``)."""
    screen_iter: int = 300
    """Iterations before screening restarts by ELBO."""
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
    """Value-iteration sweeps per evaluation."""
    freeze_belief: bool = False
    """GeReL⁻: keep the belief at the true dynamics and learn only ``μ``."""

    def __post_init__(self):
        if self.estimator not in ("pathwise", "score"):
            raise ValueError(f"unknown estimator {self.estimator!r}: use 'pathwise' or 'score'")
        for name in ("n_samples", "max_iter", "check_every", "restarts", "keep", "vi_iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
        if self.n_samples < 2 and self.estimator == "score":
            raise ValueError("the score estimator's control variates need n_samples >= 2")


class GeReLState(NamedTuple):
    """Variational parameters ``(μ [K], α [F, M])``, optimiser state and step count of one restart."""

    mu: jnp.ndarray
    alpha: jnp.ndarray
    opt: tuple
    t: jnp.ndarray


@dataclass
class GeReLResult:
    """A fitted posterior.

    Attributes:
        mu: ``[K]`` posterior mean of the reward weights.
        alpha: ``[F, M]`` Dirichlet parameters of the belief factors.
        transitions: ``[S, A, S]`` believed dynamics under ``E[θ]`` (the truth for GeReL⁻).
        space: the belief parameterisation.
        elbo: ``[R']`` final ELBO estimate per surviving restart; ``best`` indexes the chosen one.
        run: the optimisation record (history of ``μ``, ``α`` and ELBO per chunk).
    """

    mu: np.ndarray
    alpha: np.ndarray
    transitions: np.ndarray
    space: BeliefSpace
    elbo: np.ndarray
    best: int
    run: RestartRun
    config: GeReLConfig

    def curve(self, restart_id: int | None = None):
        """``(iterations, μ [C, K], T [C, S, A, S])`` along the optimisation of one restart."""
        rid = int(self.run.ids[self.best]) if restart_id is None else restart_id
        iters, snaps = self.run.trace(rid)
        mus = np.stack([m for m, _ in snaps])
        if self.config.freeze_belief:
            ts = np.broadcast_to(self.transitions, (len(iters),) + self.transitions.shape)
        else:
            ts = np.asarray(jax.vmap(self.space.mean_transitions)(jnp.stack([a for _, a in snaps])))
        return iters, mus, ts

    def restart_estimates(self):
        """``{restart id: (μ, T)}`` at the end of every restart (at screening for dropped ones)."""
        out = {}
        finals = {int(i): (self.run.states.mu[j], self.run.states.alpha[j]) for j, i in enumerate(self.run.ids)}
        finals.update({i: snap for i, (snap, _) in self.run.dropped.items()})
        for i, (mu, alpha) in sorted(finals.items()):
            t = self.transitions if self.config.freeze_belief else self.space.mean_transitions(jnp.asarray(alpha))
            out[i] = (np.asarray(mu), np.asarray(t))
        return out


class RatingData(NamedTuple):
    """What a rating-based fit reads: the world, the belief space, step counts and ratings."""

    mdp: TabularMDP
    space: BeliefSpace
    counts: jnp.ndarray
    ratings: jnp.ndarray

    @classmethod
    def build(cls, mdp: TabularMDP, space: BeliefSpace, rated: RatedDemonstrations) -> RatingData:
        counts = rated.demos.step_counts(mdp.n_states, mdp.n_actions)
        return cls(mdp, space, counts, jnp.asarray(rated.ratings, jnp.float32))


def rating_log_likelihood(w, transitions, data: RatingData, cfg: GeReLConfig) -> jnp.ndarray:
    """``log p(Γ | Z, w, Θ)`` for ``w [B, K]`` and transitions ``[B, S, A, S]``, ``[B]``."""
    mdp = data.mdp
    q = q_values(transitions, mdp.reward(w), mdp.discount, cfg.vi_iterations)
    log_pi = jax.nn.log_softmax(cfg.beta * q, axis=-1)
    mean = cfg.gamma_max * jnp.exp(mean_log_policy_from_counts(log_pi, data.counts))
    ll = censored_log_likelihood(data.ratings, mean, cfg.rating_noise, cfg.gamma_max)
    return ll.sum(-1)


def _gauss_logpdf(x, mean, std):
    k = x.shape[-1]
    return -0.5 * (((x - mean) / std) ** 2).sum(-1) - k * jnp.log(std) - 0.5 * k * jnp.log(2 * jnp.pi)


@lru_cache(maxsize=32)
def make_step(cfg: GeReLConfig):
    """One iteration of Algorithm 1 for one restart: ``(state, key, data) -> (state, ELBO estimate)``."""
    sp, sq = cfg.reward_prior_std, cfg.reward_posterior_std
    frozen = cfg.freeze_belief
    n_s = cfg.n_samples

    def draw(key, mu, alpha, data):
        mdp, space, mask = data.mdp, data.space, data.space.mask
        kw, kt = jax.random.split(key)
        w = mu + sq * jax.random.normal(kw, (n_s,) + mu.shape)
        if frozen:
            return w, None, mdp.transitions
        log_theta = dirichlet.sample_log(kt, alpha, mask, (n_s,))
        return w, log_theta, space.to_transitions(jnp.exp(log_theta))

    if cfg.estimator == "pathwise":
        opt = optax.adam(cfg.learning_rate)

        def split_alpha(alpha, mask):
            """``α = c · softmax(ℓ)``: Adam moves the mean at the same pace at any concentration."""
            log_a = jnp.where(mask, jnp.log(alpha), 0.0)
            log_c = jax.nn.logsumexp(jnp.where(mask, log_a, -jnp.inf), axis=-1)
            return log_a - log_c[..., None], log_c

        def join_alpha(logits, log_c, mask):
            logits = jnp.where(mask, logits, -jnp.inf)
            return jnp.exp(jax.nn.log_softmax(logits, axis=-1) + log_c[..., None])

        def neg_elbo(params, key, temperature, data):
            mask = data.space.mask
            alpha0 = jnp.full(mask.shape, cfg.belief_prior)
            mu, logits, log_c = params
            alpha = jnp.where(mask, join_alpha(logits, log_c, mask), 1.0)
            w, _, transitions = draw(key, mu, alpha, data)
            k = mu.shape[-1]
            elbo = temperature * rating_log_likelihood(w, transitions, data, cfg).mean()
            elbo += -0.5 * ((mu**2).sum() + k * sq**2) / sp**2 - k * jnp.log(sp) - 0.5 * k * jnp.log(2 * jnp.pi)
            elbo += k * (0.5 * jnp.log(2 * jnp.pi * jnp.e) + jnp.log(sq))
            if not frozen:
                elbo += dirichlet.cross_entropy_term(alpha, alpha0, mask).sum()
                elbo += dirichlet.entropy(alpha, mask).sum()
            return -elbo

        def step(state: GeReLState, key, data):
            mask = data.space.mask
            params = (state.mu,) + split_alpha(state.alpha, mask)
            temperature = jnp.minimum(1.0, (state.t + 1.0) / max(cfg.anneal_iter, 1))
            loss, grads = jax.value_and_grad(neg_elbo)(params, key, temperature, data)
            updates, opt_state = opt.update(grads, state.opt, params)
            mu, logits, log_c = optax.apply_updates(params, updates)
            alpha = jnp.where(mask, join_alpha(logits, jnp.clip(log_c, -3.0, 12.0), mask), 1.0)
            alpha = jnp.clip(alpha, 1e-3, 1e5)
            return GeReLState(mu, alpha, opt_state, state.t + 1), -loss

        def init_opt(mu, alpha, mask):
            return opt.init((mu,) + split_alpha(alpha, mask))

    else:

        def control_variate_mean(f, g):
            """``mean(f − a g)`` with ``a = cov(f, g) / var(g)`` per coordinate (§2.2.2)."""
            fc = f - f.mean(0)
            gc = g - g.mean(0)
            a = (fc * gc).mean(0) / jnp.maximum((gc * gc).mean(0), 1e-12)
            return (f - a * g).mean(0)

        def step(state: GeReLState, key, data):
            mask = data.space.mask
            alpha0 = jnp.full(mask.shape, cfg.belief_prior)
            mu, alpha = state.mu, state.alpha
            w, log_theta, transitions = draw(key, mu, alpha, data)
            ll = rating_log_likelihood(w, transitions, data, cfg)  # [n_s]
            log_pw = _gauss_logpdf(w, 0.0, sp)
            log_qw = _gauss_logpdf(w, mu, sq)
            g_mu = (w - mu) / sq**2
            grad_mu = control_variate_mean(g_mu * (ll + log_pw - log_qw)[:, None], g_mu)
            elbo_s = ll + log_pw - log_qw
            if frozen:
                grad_alpha = jnp.zeros_like(alpha)
            else:
                log_pt = dirichlet.log_prob(log_theta, alpha0, mask)  # [n_s, F]
                log_qt = dirichlet.log_prob(log_theta, alpha, mask)
                g_a = dirichlet.score(log_theta, alpha, mask)  # [n_s, F, M]
                f_a = g_a * (ll[:, None] + log_pt - log_qt)[..., None]
                grad_alpha = jnp.where(mask, control_variate_mean(f_a, g_a), 0.0)
                elbo_s = elbo_s + (log_pt - log_qt).sum(-1)
            acc_mu, acc_alpha = state.opt
            acc_mu = acc_mu + grad_mu**2
            acc_alpha = acc_alpha + grad_alpha**2
            mu = mu + cfg.adagrad_rate_mu * grad_mu / (jnp.sqrt(acc_mu) + 1e-8)
            alpha = alpha + cfg.adagrad_rate_alpha * grad_alpha / (jnp.sqrt(acc_alpha) + 1e-8)
            alpha = jnp.clip(alpha, 1e-3, 1e5)  # α stays positive (projected AdaGrad)
            return GeReLState(mu, alpha, (acc_mu, acc_alpha), state.t + 1), elbo_s.mean()

        def init_opt(mu, alpha, mask):
            return (jnp.zeros_like(mu), jnp.zeros_like(alpha))

    return step, init_opt


def init_states(key, n_features: int, space: BeliefSpace, cfg: GeReLConfig, init_opt) -> GeReLState:
    """Random restarts: ``μ ~ N(0, s²)``, ``α = 0.5 + c · u`` with ``u ~ Dir(1)`` per factor."""
    k_mu, k_a = jax.random.split(key)
    r = cfg.restarts
    mu = cfg.init_reward_std * jax.random.normal(k_mu, (r, n_features))
    u = jnp.exp(dirichlet.sample_log(k_a, jnp.ones(space.mask.shape), space.mask, (r,)))
    alpha = jnp.where(space.mask, 0.5 + cfg.init_concentration * u, 1.0)
    opt = jax.vmap(init_opt, in_axes=(0, 0, None))(mu, alpha, space.mask)
    return GeReLState(mu, alpha, opt, jnp.zeros(r, jnp.int32))


def fit_gerel(
    mdp: TabularMDP,
    rated: RatedDemonstrations,
    space: BeliefSpace,
    config: GeReLConfig = GeReLConfig(),
    *,
    key,
    progress: bool = True,
) -> GeReLResult:
    """Fit ``q(w) q(Θ)`` to ratings (Algorithm 1) and keep the best restart.

    Args:
        mdp: the world; its transitions are the truth (used by GeReL⁻).
        rated: demonstrations and their ratings.
        space: how the belief is parameterised (tied, per-(s,a), full).
        config: hyperparameters; ``freeze_belief=True`` gives GeReL⁻.
        key: PRNG key (restart initialisation and Monte Carlo samples).
        progress: show a progress bar.
    """
    ratings = np.asarray(rated.ratings)
    if ratings.ndim != 1 or len(ratings) != rated.demos.count:
        raise ValueError("need exactly one rating per demonstration")
    if np.any((ratings < 0) | (ratings > config.gamma_max)) or not np.isfinite(ratings).all():
        raise ValueError(f"ratings must lie in [0, {config.gamma_max}]")
    step, init_opt = make_step(config)
    data = RatingData.build(mdp, space, rated)
    k_init, k_run = jax.random.split(key)
    states = init_states(k_init, mdp.n_features, space, config, init_opt)
    name = "GeReL-" if config.freeze_belief else f"GeReL[{config.estimator}, {space.kind}]"
    run = run_restarts(
        step,
        states,
        k_run,
        data,
        max_iter=config.max_iter,
        check_every=config.check_every,
        tol=config.tol,
        n_obs=rated.demos.count,
        snapshot=lambda s: (s.mu, s.alpha),
        desc=name,
        progress=progress,
        keep=config.keep,
        screen_iter=config.screen_iter,
    )
    best = run.best
    mu = np.asarray(run.states.mu[best])
    alpha = np.asarray(run.states.alpha[best])
    if config.freeze_belief:
        transitions = np.asarray(mdp.transitions)
    else:
        transitions = np.asarray(space.mean_transitions(jnp.asarray(alpha)))
    return GeReLResult(mu, alpha, transitions, space, run.objective, best, run, config)
