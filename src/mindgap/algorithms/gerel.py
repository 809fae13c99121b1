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

Each sample's Q-values (the person's expected policy) come from value iteration on the
belief's successor form, ``K`` next states per ``(s, a)`` instead of ``S``, stopped once
MacQueen's bounds certify the accuracy of ``vi_iterations`` plain sweeps and
differentiated implicitly at the fixed point
(:mod:`mindgap.planning.sparse_value_iteration`); ``full`` beliefs keep the dense tensor.

GeReL⁻ is the same inference with the belief frozen to the true dynamics
(``freeze_belief=True``). Many local optima exist (a flipped reward with a permuted
belief explains ratings almost as well, SPEC §4), so every fit runs vmapped random
restarts and keeps the one with the highest ELBO.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..data.demos import RatedDemonstrations
from ..envs.tabular import TabularMDP
from ..models import dirichlet
from ..models.belief import BeliefSpace
from ._restarts import RestartRun, run_restarts
from .gerel_model import GeReLConfig as GeReLConfig
from .gerel_model import RatingData as RatingData
from .gerel_model import pathwise_elbo, score_gradient


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


@lru_cache(maxsize=32)
def make_step(cfg: GeReLConfig):
    """One iteration of Algorithm 1 for one restart: ``(state, key, data) -> (state, ELBO estimate)``.

    Pathwise: Adam on ``(μ, ℓ, log c)`` with ``α = c · softmax(ℓ)`` (the same family;
    the mean moves at the same pace at any concentration) and an annealed likelihood.
    Score: the paper's AdaGrad on ``(μ, α)`` with ``α`` projected to stay positive.
    """
    if cfg.estimator == "pathwise":
        opt = optax.adam(cfg.learning_rate)

        def split_alpha(alpha, mask):
            log_a = jnp.where(mask, jnp.log(alpha), 0.0)
            log_c = jax.nn.logsumexp(jnp.where(mask, log_a, -jnp.inf), axis=-1)
            return log_a - log_c[..., None], log_c

        def join_alpha(logits, log_c, mask):
            logits = jnp.where(mask, logits, -jnp.inf)
            return jnp.where(mask, jnp.exp(jax.nn.log_softmax(logits, axis=-1) + log_c[..., None]), 1.0)

        def neg_elbo(params, key, temperature, data):
            mu, logits, log_c = params
            alpha = join_alpha(logits, log_c, data.space.mask)
            return -pathwise_elbo(mu, alpha, key, data, cfg, temperature)

        def step(state: GeReLState, key, data):
            mask = data.space.mask
            params = (state.mu,) + split_alpha(state.alpha, mask)
            temperature = jnp.minimum(1.0, (state.t + 1.0) / max(cfg.anneal_iter, 1))
            loss, grads = jax.value_and_grad(neg_elbo)(params, key, temperature, data)
            updates, opt_state = opt.update(grads, state.opt, params)
            mu, logits, log_c = optax.apply_updates(params, updates)
            alpha = jnp.clip(join_alpha(logits, jnp.clip(log_c, -3.0, 12.0), mask), 1e-3, 1e5)
            return GeReLState(mu, alpha, opt_state, state.t + 1), -loss

        def init_opt(mu, alpha, mask):
            return opt.init((mu,) + split_alpha(alpha, mask))

    else:

        def step(state: GeReLState, key, data):
            elbo, grad_mu, grad_alpha = score_gradient(state.mu, state.alpha, key, data, cfg)
            acc_mu, acc_alpha = state.opt
            acc_mu = acc_mu + grad_mu**2
            acc_alpha = acc_alpha + grad_alpha**2
            mu = state.mu + cfg.adagrad_rate_mu * grad_mu / (jnp.sqrt(acc_mu) + 1e-8)
            alpha = state.alpha + cfg.adagrad_rate_alpha * grad_alpha / (jnp.sqrt(acc_alpha) + 1e-8)
            alpha = jnp.clip(alpha, 1e-3, 1e5)  # α stays positive (projected AdaGrad)
            return GeReLState(mu, alpha, (acc_mu, acc_alpha), state.t + 1), elbo

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
