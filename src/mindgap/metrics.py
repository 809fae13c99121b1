"""Evaluation metrics of Table 1 (§2.3.1).

- ``d(R) = ‖R̂ − R_H‖₂`` over states;
- ``d(Θ)`` = mean over ``(s, a)`` of ``‖θ̂_sa − θ_sa‖₂`` (full next-state vectors);
- ``d(π)`` = mean over states of ``KL(π_H ‖ π̂)``, both the softmax policy of value
  iteration (rationality ``β``) under the respective reward and belief.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .envs.tabular import TabularMDP
from .planning import q_values


def d_reward(mdp: TabularMDP, w_hat, w_true) -> float:
    """d(R): the L2 distance between the learned and true state rewards."""
    return float(jnp.linalg.norm(mdp.reward(w_hat) - mdp.reward(w_true)))


def d_belief(t_hat, t_true) -> float:
    """d(Θ): the mean over (s, a) of the L2 distance between next-state distributions, [S, A, S] each."""
    return float(jnp.linalg.norm(t_hat - t_true, axis=-1).mean())


@jax.jit
def _policy_kl(mdp: TabularMDP, w_hat, t_hat, w_true, t_true, beta):
    logp = jax.nn.log_softmax(beta * q_values(t_true, mdp.reward(w_true), mdp.discount), -1)
    logq = jax.nn.log_softmax(beta * q_values(t_hat, mdp.reward(w_hat), mdp.discount), -1)
    return (jnp.exp(logp) * (logp - logq)).sum(-1).mean()


def d_policy(mdp: TabularMDP, w_hat, t_hat, w_true, t_true, beta: float = 1.0) -> float:
    """d(π): the mean over states of KL(π_H ‖ π̂) between the true and learned softmax policies."""
    return float(_policy_kl(mdp, jnp.asarray(w_hat), jnp.asarray(t_hat), w_true, t_true, beta))


def reward_correlation(mdp: TabularMDP, w_hat, w_true) -> float:
    """Pearson correlation of learned and true state rewards (sign of what was learned)."""
    a = np.asarray(mdp.reward(w_hat))
    b = np.asarray(mdp.reward(w_true))
    if a.std() == 0 or b.std() == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def all_metrics(mdp: TabularMDP, w_hat, t_hat, w_true, t_true, beta: float = 1.0) -> dict:
    """Table 1's metrics of a learned reward and belief against the person's true ones.

    Args:
        mdp: the task (its features, discount and true dynamics).
        w_hat: [k] learned reward weights.
        t_hat: [S, A, S] learned belief.
        w_true: [k] the person's reward weights.
        t_true: [S, A, S] the person's belief.
        beta: rationality of the softmax policies compared by d(π).

    Returns:
        ``d_R``, ``d_Theta``, ``d_pi`` (the module docstring defines them) and ``corr_R``, the
        correlation of the learned and true state rewards (its sign tells the basin).
    """
    return {
        "d_R": d_reward(mdp, w_hat, w_true),
        "d_Theta": d_belief(t_hat, t_true),
        "d_pi": d_policy(mdp, w_hat, t_hat, w_true, t_true, beta),
        "corr_R": reward_correlation(mdp, w_hat, w_true),
    }
