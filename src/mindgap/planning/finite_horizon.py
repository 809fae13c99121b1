"""Exact finite-horizon planning on a discretised terrain world, and what a policy earns there.

The design check (:mod:`~mindgap.design.design_check`) compares the policies that three
reward functions lead to: the person's r_H, what a learner that ignores the person's belief
learns (r_H + E_T[log T_H]) and what it learns from an unbiased person (r_H + E_T[log T]).
Each is planned exactly over the episode's horizon — backward induction on the sub-cell MDP
of :func:`~mindgap.planning.terrain.discretise` (time-dependent policies; with a fixed
horizon the last steps matter) — and then run forward on the same MDP from the start
distribution, which gives its expected true return and where its probability mass goes.

Written by hand: no planning library takes this sub-cell MDP with its terminal and trap rules.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..envs.terrain.dynamics import terrain_at
from ..envs.terrain.layout import GOAL, ICE, PIT, SAND
from .terrain import Discretised


class Outcome(NamedTuple):
    """What a policy earns from the start distribution, by forward propagation of the state distribution.

    Attributes:
        ret: expected true return (r_H) over the horizon.
        goal: probability of being in the goal at the last rewarded step (where episodes end:
            of having entered it by the end).
        pit: the same for pits.
        ice, sand: shares of the steps taken (live probability mass) spent on ice and on sand.
    """

    ret: float
    goal: float
    pit: float
    ice: float
    sand: float


def successors(d: Discretised) -> jax.Array:
    """[N, J+1] the state each landing column leads to (−1 for walls; the last column, "stay", the state itself)."""
    ids = jnp.arange(d.positions.shape[0])
    return jnp.concatenate([d.targets, ids[:, None]], -1)


@partial(jax.jit, static_argnames=("horizon",))
def backward(d: Discretised, rewards: jax.Array, horizon: int):
    """Optimal values and a time-dependent policy for ``rewards [N, K]`` over ``horizon`` steps.

    Terminal states (``d.terminal``) are worth 0 and stay put. Returns ``(v0 [N], policy [H, N])``
    with ``policy[t]`` the action ids at step t.
    """
    nxt = successors(d)

    def body(v, _):
        v_next = jnp.where(nxt >= 0, v[jnp.maximum(nxt, 0)], 0.0)
        q = rewards + jnp.einsum("nkj,nj->nk", d.probs, v_next)
        q = jnp.where(d.terminal[:, None], 0.0, q)
        return q.max(-1), q.argmax(-1).astype(jnp.int32)

    v0, policy = jax.lax.scan(body, jnp.zeros(d.positions.shape[0]), None, length=horizon)
    return v0, policy[::-1]


def start_distribution(d: Discretised, params) -> jax.Array:
    """[N] uniform over the sub-cells whose centres lie within ``start_jitter`` of a start cell's centre."""
    pos = np.asarray(d.positions)
    near = np.zeros(len(pos), bool)
    jitter = max(float(params.start_jitter), 0.5 / d.n)
    for r, c in np.asarray(params.starts):
        near |= np.all(np.abs(pos - np.array([c + 0.5, r + 0.5])) <= jitter + 1e-6, axis=-1)
    return jnp.asarray(near / near.sum(), jnp.float32)


@partial(jax.jit, static_argnames=("horizon",))
def _forward(d: Discretised, weights: jax.Array, rewards: jax.Array, start: jax.Array, horizon: int):
    nxt = successors(d)
    n, width = nxt.shape
    stay = jax.nn.one_hot(width - 1, width)
    probs = jnp.where(d.terminal[:, None, None], stay, d.probs)  # terminal states absorb
    rows = jnp.broadcast_to(jnp.arange(n)[:, None], nxt.shape)
    dest = jnp.where(nxt >= 0, nxt, rows)  # refused cells carry no mass anyway

    def body(dist, w_t):
        p = jnp.einsum("nk,nkj->nj", w_t, probs)
        r = jnp.sum(dist * jnp.einsum("nk,nk->n", w_t, rewards))
        live = jnp.where(d.terminal, 0.0, dist)
        new = jnp.zeros(n).at[dest.reshape(-1)].add((dist[:, None] * p).reshape(-1))
        return new, (r, live)

    final, (r, live) = jax.lax.scan(body, start, weights, length=horizon)
    # where episodes end, the goal's mass is what was absorbed by the end; with a fixed horizon,
    # what is there at the last rewarded step (the last action earns nothing)
    last = jnp.where(d.terminal, final, live[-1])
    return last, r.sum(), live


def forward(d: Discretised, params, policy, rewards: jax.Array) -> Outcome:
    """Run ``policy`` (``[H, N]`` action ids, or ``"uniform"`` over the actions) from the start distribution.

    ``rewards [N, K]``: what the return counts (the true r_H for a policy's true return).
    """
    horizon = int(params.horizon)
    n, k = rewards.shape
    if isinstance(policy, str):
        weights = jnp.full((horizon, n, k), 1.0 / k)
    else:
        weights = jax.nn.one_hot(jnp.asarray(policy), k)
    final, ret, live = _forward(d, weights, rewards, start_distribution(d, params), horizon)
    terr = np.asarray(jax.vmap(lambda p: terrain_at(params, p))(d.positions))
    final, live = np.asarray(final, np.float64), np.asarray(live, np.float64)
    steps = max(live.sum(), 1e-12)
    return Outcome(
        ret=float(ret),
        goal=float(final[terr == GOAL].sum()),
        pit=float(final[terr == PIT].sum()),
        ice=float(live[:, terr == ICE].sum() / steps),
        sand=float(live[:, terr == SAND].sum() / steps),
    )
