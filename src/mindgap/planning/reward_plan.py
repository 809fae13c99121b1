"""Planning on any reward table of a discretised terrain world: its optimum and a policy's value.

:func:`~mindgap.planning.terrain.plan` plans on the world's own reward with terminal states
worth 0. A learned reward r̂ needs two things more: its own table ``rewards [N, K]`` and a value
for the terminal sub-cells — a learner with absorbing states values the state after a terminal
transition at ``r_abs / (1 − γ)`` (Kostrikov et al. 2019; :func:`~mindgap.data.replay.terminal_bonus`),
one without at 0. With both, value iteration gives r̂'s own optimum under the true dynamics,
the policy an ideal optimiser of r̂ would follow, and policy evaluation gives what r̂ says of
any other plan (:mod:`~mindgap.experiments.reward_optimum` reads a run's learned reward so).

Written by hand: no planning library takes this sub-cell MDP with its terminal rule.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .finite_horizon import successors
from .terrain import Discretised, Plan


def _backup(d: Discretised, rewards, terminal_values, discount, v):
    nxt = successors(d)
    v_next = jnp.where(nxt >= 0, v[jnp.maximum(nxt, 0)], 0.0)  # [N, J+1]
    return rewards + discount * jnp.einsum("nkj,nj->nk", d.probs, v_next)


@jax.jit
def _optimum(d: Discretised, rewards, terminal_values, discount, tol):
    def cond(c):
        _, delta, i = c
        return (delta > tol) & (i < 20000)

    def body(c):
        v, _, i = c
        v_new = jnp.where(d.terminal, terminal_values, _backup(d, rewards, terminal_values, discount, v).max(-1))
        return v_new, jnp.max(jnp.abs(v_new - v)), i + 1

    v0 = jnp.where(d.terminal, terminal_values, 0.0)
    v, _, iters = jax.lax.while_loop(cond, body, (v0, jnp.inf, 0))
    q = _backup(d, rewards, terminal_values, discount, v)
    return jnp.where(d.terminal[:, None], terminal_values[:, None], q), iters


def plan_rewards(d: Discretised, rewards, terminal_values=None, discount: float = 0.99, tol: float = 1e-4) -> Plan:
    """The optimal plan of ``rewards [N, K]`` on ``d``'s dynamics, terminal sub-cells worth ``terminal_values [N]``.

    Infinite-horizon discounted value iteration (the objective of SAC with ``discount``);
    a terminal sub-cell's every action is worth its terminal value. Without ``terminal_values``
    terminal sub-cells are worth 0, and on the world's own
    ``d.rewards`` the plan is :func:`~mindgap.planning.terrain.plan`'s.
    """
    tv = jnp.zeros(d.positions.shape[0]) if terminal_values is None else jnp.asarray(terminal_values, jnp.float32)
    q, iters = _optimum(d, jnp.asarray(rewards, jnp.float32), tv, discount, tol)
    return Plan(d, q, jnp.argmax(q, -1), int(iters))


@jax.jit
def _evaluate(d: Discretised, rewards, terminal_values, policy, discount, tol):
    ids = jnp.arange(d.positions.shape[0])

    def cond(c):
        _, delta, i = c
        return (delta > tol) & (i < 20000)

    def body(c):
        v, _, i = c
        q = _backup(d, rewards, terminal_values, discount, v)
        v_new = jnp.where(d.terminal, terminal_values, q[ids, policy])
        return v_new, jnp.max(jnp.abs(v_new - v)), i + 1

    v, _, _ = jax.lax.while_loop(cond, body, (jnp.where(d.terminal, terminal_values, 0.0), jnp.inf, 0))
    return v


def policy_values(
    d: Discretised, rewards, policy, terminal_values=None, discount: float = 0.99, tol: float = 1e-4
) -> jax.Array:
    """[N] the discounted value of following ``policy [N]`` (action ids) under ``rewards [N, K]`` on ``d``'s dynamics."""
    tv = jnp.zeros(d.positions.shape[0]) if terminal_values is None else jnp.asarray(terminal_values, jnp.float32)
    return _evaluate(d, jnp.asarray(rewards, jnp.float32), tv, jnp.asarray(policy), discount, tol)


def state_id(d: Discretised, pos) -> int:
    """The sub-cell state id of a continuous position (−1 in a wall)."""
    sub = jnp.floor(jnp.asarray(pos)[::-1] * d.n).astype(jnp.int32)
    return int(d.index[sub[0], sub[1]])
