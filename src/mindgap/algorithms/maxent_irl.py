"""Maximum-entropy IRL (Ziebart et al. 2008), tabular, with the true dynamics.

The baseline of §2.3.1 that learns from *demonstrations of the person's own softmax
policy* (not ratings) and assumes the person's model of the robot is the true one.
Finite-horizon form of the original algorithm: a backward pass of soft value
iteration over the demonstrations' horizon gives a time-varying policy, a forward pass
gives expected state visitation from the demonstrations' start states, and the
gradient of the log-likelihood is empirical minus expected feature counts. A Gaussian
prior on ``w`` (MAP) matches the other learners; Adam.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..data.demos import Demonstrations
from ..envs.tabular import TabularMDP
from ._restarts import RestartRun, run_restarts


@dataclass(frozen=True)
class MaxEntConfig:
    """Hyperparameters of MaxEnt IRL."""

    max_iter: int = 1000
    """Iteration cap."""
    check_every: int = 50
    """Iterations between convergence tests."""
    tol: float = 1e-5
    """Converged when the mean log-likelihood per demonstration moves less than this."""
    learning_rate: float = 0.05
    """Adam step size."""
    reward_prior_std: float = 10.0
    """Gaussian prior on ``w``."""


@dataclass
class MaxEntResult:
    weights: np.ndarray
    run: RestartRun

    def curve(self):
        iters, snaps = self.run.trace(0)
        return iters, np.stack(snaps)


def finite_horizon_soft_policy(transitions, reward, horizon: int):
    """Time-varying MaxEnt policy ``π_t(a|s)`` ``[H, S, A]`` (backward pass, undiscounted)."""

    def back(v, _):
        q = reward[:, None] + transitions @ v
        v_new = jax.nn.logsumexp(q, axis=-1)
        return v_new, q - v_new[:, None]

    _, log_pi = jax.lax.scan(back, jnp.zeros(reward.shape), None, length=horizon)
    return log_pi[::-1]


@lru_cache(maxsize=8)
def _make_step(config: MaxEntConfig):
    opt = optax.adam(config.learning_rate)

    def step(state, _key, data):
        mdp, demos, emp, start = data
        w, opt_state = state
        horizon, n = demos.states.shape[1], demos.states.shape[0]
        t_true = mdp.transitions
        log_pi = finite_horizon_soft_policy(t_true, mdp.reward(w), horizon)
        pi = jnp.exp(log_pi)

        def fwd(d, pi_t):
            return jnp.einsum("s,sa,sat->t", d, pi_t, t_true), d

        _, visits = jax.lax.scan(fwd, start, pi)
        expected = (visits.sum(0)[:, None] * mdp.features).sum(0)
        grad = emp - expected - w / (config.reward_prior_std**2 * n)
        steps = jnp.arange(horizon)[None, :]
        loglik = (log_pi[steps, demos.states, demos.actions] * demos.mask).sum() / n
        updates, opt_state = opt.update(-grad, opt_state, w)
        return (optax.apply_updates(w, updates), opt_state), loglik

    return step, opt


def fit_maxent_irl(
    mdp: TabularMDP,
    demos: Demonstrations,
    config: MaxEntConfig = MaxEntConfig(),
    *,
    key,
    progress: bool = True,
) -> MaxEntResult:
    """Learn ``w`` from demonstrations by matching feature expectations (Ziebart 2008)."""
    n = demos.count
    emp = (mdp.features[demos.states] * demos.mask[..., None]).sum((0, 1)) / n
    start = jnp.zeros(mdp.n_states).at[demos.states[:, 0]].add(1.0 / n)
    step, opt = _make_step(config)
    data = (mdp, demos, emp, start)

    w0 = jnp.zeros((1, mdp.n_features))
    states = (w0, jax.vmap(opt.init)(w0))
    run = run_restarts(
        step,
        states,
        key,
        data,
        max_iter=config.max_iter,
        check_every=config.check_every,
        tol=config.tol,
        n_obs=1,
        snapshot=lambda s: s[0],
        desc="MaxEnt-IRL",
        progress=progress,
    )
    return MaxEntResult(np.asarray(run.states[0][0]), run)
