"""The SERD variant (Herman et al. 2016, as adapted in §2.3.1).

Point estimates of the reward weights ``w`` and of belief logits ``ℓ`` (``θ = softmax(ℓ)``
per factor, over the same belief space as GeReL) that maximise the rating likelihood of
GeReL's rating model, with the person's policy given by *soft* value iteration
(``π = exp(Q_soft − V_soft)``). Gradients flow through soft value iteration (implicitly,
see :mod:`mindgap.planning.value_iteration`); Adam; the same restart screening as GeReL.
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
from ..models.rating import censored_log_likelihood, mean_log_policy_from_counts
from ..planning import soft_q_values
from ._restarts import RestartRun, RestartSchedule, run_restarts
from .gerel_model import RatingData


@dataclass(frozen=True)
class SERDConfig(RestartSchedule):
    """Hyperparameters of the SERD variant; the restart schedule's objective is the MAP objective."""

    learning_rate: float = 0.05
    """Adam step size."""
    reward_prior_std: float = 10.0
    """Gaussian prior on ``w`` (MAP)."""
    init_reward_std: float = 2.0
    """Restart initialisation of ``w``."""
    rating_noise: float = 0.5
    """``σ`` of the rating likelihood."""
    gamma_max: float = 10.0
    """Highest rating."""
    vi_iterations: int = 100
    """Soft value-iteration sweeps."""


class SERDState(NamedTuple):
    w: jnp.ndarray
    logits: jnp.ndarray
    opt: tuple


@dataclass
class SERDResult:
    """Point estimates: ``weights [K]``, ``logits [F, M]``, ``transitions [S, A, S]``."""

    weights: np.ndarray
    logits: np.ndarray
    transitions: np.ndarray
    space: BeliefSpace
    objective: np.ndarray
    best: int
    run: RestartRun

    def curve(self):
        """``(iterations, w [C, K], T [C, S, A, S])`` of the chosen restart."""
        iters, snaps = self.run.trace(int(self.run.ids[self.best]))
        ws = np.stack([w for w, _ in snaps])
        ts = np.asarray(
            jax.vmap(lambda lg: self.space.to_transitions(_theta(lg, self.space.mask)))(
                jnp.stack([lg for _, lg in snaps])
            )
        )
        return iters, ws, ts


def _theta(logits, mask):
    return jax.nn.softmax(jnp.where(mask, logits, -jnp.inf), axis=-1)


@lru_cache(maxsize=16)
def _make_step(config: SERDConfig):
    opt = optax.adam(config.learning_rate)

    def objective(params, data: RatingData):
        w, logits = params
        mdp, mask = data.mdp, data.space.mask
        t = data.space.to_transitions(_theta(logits, mask))
        q = soft_q_values(t, mdp.reward(w), mdp.discount, config.vi_iterations)
        mean = config.gamma_max * jnp.exp(mean_log_policy_from_counts(jax.nn.log_softmax(q, -1), data.counts))
        ll = censored_log_likelihood(data.ratings, mean, config.rating_noise, config.gamma_max).sum()
        return ll - 0.5 * (w**2).sum() / config.reward_prior_std**2

    def step(state: SERDState, _key, data: RatingData):
        params = (state.w, state.logits)
        value, grads = jax.value_and_grad(objective)(params, data)
        grads = jax.tree_util.tree_map(jnp.negative, grads)
        updates, opt_state = opt.update(grads, state.opt, params)
        w, logits = optax.apply_updates(params, updates)
        return SERDState(w, jnp.where(data.space.mask, logits, 0.0), opt_state), value

    return step, opt


def fit_serd(
    mdp: TabularMDP,
    rated: RatedDemonstrations,
    space: BeliefSpace,
    config: SERDConfig = SERDConfig(),
    *,
    key,
    progress: bool = True,
) -> SERDResult:
    """Maximise the rating likelihood under a soft-optimal person over ``(w, θ)``."""
    mask = space.mask
    step, opt = _make_step(config)
    data = RatingData.build(mdp, space, rated)

    k_w, k_t, k_run = jax.random.split(key, 3)
    r = config.restarts
    w0 = config.init_reward_std * jax.random.normal(k_w, (r, mdp.n_features))
    logits0 = jnp.where(mask, dirichlet.sample_log(k_t, jnp.ones(mask.shape), mask, (r,)), 0.0)
    states = SERDState(w0, logits0, jax.vmap(lambda w, lg: opt.init((w, lg)))(w0, logits0))
    run = run_restarts(
        step,
        states,
        k_run,
        data,
        max_iter=config.max_iter,
        check_every=config.check_every,
        tol=config.tol,
        n_obs=rated.demos.count,
        snapshot=lambda s: (s.w, s.logits),
        desc=f"SERD[{space.kind}]",
        progress=progress,
        keep=config.keep,
        screen_iter=config.screen_iter,
    )
    best = run.best
    logits = np.asarray(run.states.logits[best])
    transitions = np.asarray(space.to_transitions(_theta(jnp.asarray(logits), mask)))
    return SERDResult(np.asarray(run.states.w[best]), logits, transitions, space, run.objective, best, run)
