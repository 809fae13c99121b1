"""The planning check of terrain worlds: discretise, value-iterate, roll the plan out.

A world is cut into n×n sub-cells per cell and a fixed set of actions (16 directions on
the boundary of [−1, 1]²). The transition probabilities between sub-cells are the exact
rectangle masses of the continuous model (:func:`~mindgap.envs.terrain.dynamics.subcell_probs`),
so the only approximation is that a position stands for its sub-cell's centre. Value
iteration under the true table gives the optimal route and a near-optimal reference
return for learners; under a belief table it gives the route the person expects.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..envs.terrain.dynamics import cell_of, pit_distance, subcell_probs, terrain_at
from ..envs.terrain.layout import GOAL, ICE, PIT, SAND, WALL
from ..envs.terrain.params import TerrainParams, TerrainState
from ..envs.terrain.world import reset, reward, step


def compass_actions(k: int = 16) -> np.ndarray:
    """[k, 2] actions on the boundary of the square [−1, 1]², evenly spaced in angle."""
    ang = 2 * np.pi * np.arange(k) / k
    d = np.stack([np.cos(ang), np.sin(ang)], -1)
    return (d / np.abs(d).max(-1, keepdims=True)).astype(np.float32)


class Discretised(NamedTuple):
    """A world cut into sub-cells.

    Attributes:
        positions: [N, 2] sub-cell centres (x, y) of the non-wall sub-cells.
        index: [H·n, W·n] state id of each sub-cell (−1 in walls).
        targets: [N, (3n)²] state id of each landing sub-cell of the 3×3 block (−1 in walls).
        probs: [N, K, (3n)² + 1] landing probabilities; the last column is "stay".
        rewards: [N, K] expected reward.
        terminal: [N] pit and goal sub-cells (absorbing, value 0).
        actions: [K, 2].
        n: sub-cells per cell side.
    """

    positions: jax.Array
    index: jax.Array
    targets: jax.Array
    probs: jax.Array
    rewards: jax.Array
    terminal: jax.Array
    actions: jax.Array
    n: int


def discretise(params: TerrainParams, n: int = 4, actions: np.ndarray | None = None) -> Discretised:
    """Build the sub-cell MDP of a world under ``params.dynamics``."""
    actions = jnp.asarray(compass_actions() if actions is None else actions, jnp.float32)
    grid = np.asarray(params.grid)
    h, w = grid.shape
    free = np.repeat(np.repeat(grid != WALL, n, 0), n, 1)
    index = np.full((h * n, w * n), -1, np.int32)
    index[free] = np.arange(free.sum())
    rows, cols = np.nonzero(free)
    positions = jnp.asarray(np.stack([(cols + 0.5) / n, (rows + 0.5) / n], -1), jnp.float32)
    padded = jnp.asarray(np.pad(index, n, constant_values=-1))  # an edge cell's block reaches one cell out
    targets, probs, rewards, terminal = _build(params, positions, padded, actions, n)
    return Discretised(positions, jnp.asarray(index), targets, probs, rewards, terminal, actions, n)


@partial(jax.jit, static_argnums=4)
def _build(params, positions, padded, actions, n):
    def block_targets(pos):
        rc = cell_of(pos)  # block top-left in padded sub-cell coordinates: (r − 1)·n + n
        return jax.lax.dynamic_slice(padded, (rc[0] * n, rc[1] * n), (3 * n, 3 * n)).reshape(-1)

    def one(pos, a):
        stay, probs = subcell_probs(params, pos, a, n)
        return jnp.concatenate([probs.reshape(-1), stay[None]])

    targets = jax.vmap(block_targets)(positions)
    probs = jax.vmap(jax.vmap(one, (None, 0)), (0, None))(positions, actions)
    terr = jax.vmap(lambda p: terrain_at(params, p))(positions)
    terminal = ((terr == GOAL) | (terr == PIT)) & (params.fixed_horizon < 0.5)  # a fixed horizon ends nowhere

    def landing_rewards(pos, tgt):
        land = jnp.where(tgt[:, None] >= 0, positions[jnp.maximum(tgt, 0)], pos)
        land = jnp.concatenate([land, pos[None]])
        s = TerrainState(pos, jnp.zeros((), jnp.int32), jnp.zeros((), bool))
        return jax.vmap(lambda q: reward(s, jnp.zeros(2), s._replace(pos=q), params))(land)

    r_land = jax.vmap(landing_rewards)(positions, targets)  # [N, J]: the reward does not depend on the action
    rewards = jnp.einsum("nkj,nj->nk", probs, r_land)
    return targets, probs, jnp.where(terminal[:, None], 0.0, rewards), terminal


@jax.jit
def _value_iteration(d: Discretised, discount: float, tol: float):
    ids = jnp.arange(d.positions.shape[0])
    nxt = jnp.concatenate([d.targets, ids[:, None]], -1)  # stay lands on the state itself

    def backup(v):
        v_next = jnp.where(nxt >= 0, v[jnp.maximum(nxt, 0)], 0.0)  # [N, J]
        q = d.rewards + discount * jnp.einsum("nkj,nj->nk", d.probs, v_next)
        return jnp.where(d.terminal[:, None], 0.0, q)

    def cond(c):
        _, delta, i = c
        return (delta > tol) & (i < 5000)

    def body(c):
        v, _, i = c
        v_new = backup(v).max(-1)
        return v_new, jnp.max(jnp.abs(v_new - v)), i + 1

    v, _, iters = jax.lax.while_loop(cond, body, (jnp.zeros(d.positions.shape[0]), jnp.inf, 0))
    return backup(v), iters


class Plan(NamedTuple):
    """Optimal values of a discretised world. q: [N, K]; policy: [N] action ids."""

    grid: Discretised
    q: jax.Array
    policy: jax.Array
    iterations: int


def plan(params: TerrainParams, n: int = 4, discount: float = 0.99, tol: float = 1e-4) -> Plan:
    """Value iteration on the sub-cell MDP of ``params`` (its own dynamics table)."""
    d = discretise(params, n)
    q, iters = _value_iteration(d, discount, tol)
    return Plan(d, q, jnp.argmax(q, -1), int(iters))


def plan_action(p: Plan, pos: jax.Array) -> jax.Array:
    """The planned action at a continuous position (that of its sub-cell)."""
    sub = jnp.floor(pos[::-1] * p.grid.n).astype(jnp.int32)
    sid = p.grid.index[sub[0], sub[1]]
    return p.grid.actions[p.policy[jnp.maximum(sid, 0)]]


def rollouts(key: jax.Array, params: TerrainParams, policy, count: int, policy_params=None):
    """Roll a policy out ``count`` times in the continuous world ``params``.

    Args:
        policy: ``policy(policy_params, pos) → action``; a module-level function, so that
            the compiled program is reused across calls (e.g. :func:`plan_action`).
        policy_params: a pytree handed to ``policy`` (e.g. a :class:`Plan`).

    Returns:
        (positions [count, T+1, 2], rewards [count, T], alive [count, T] — the step happened).
    """
    return _rollouts(key, params, policy_params, policy, int(params.horizon), count)


@partial(jax.jit, static_argnums=(3, 4, 5))
def _rollouts(key, params, policy_params, policy, horizon, count):
    def one(k):
        k0, k1 = jax.random.split(k)
        s0 = reset(k0, params)

        def body(s, kk):
            out = step(kk, s, policy(policy_params, s.pos), params)
            return out.state, (out.state.pos, out.reward, ~s.done)

        _, (pos, rew, alive) = jax.lax.scan(body, s0, jax.random.split(k1, horizon))
        return jnp.concatenate([s0.pos[None], pos]), rew, alive

    return jax.vmap(one)(jax.random.split(key, count))


class RouteStats(NamedTuple):
    """Summary of a batch of rollouts (means over rollouts)."""

    ret: float
    ret_std: float
    success: float
    fell: float
    steps: float
    ice: float
    sand: float
    pit_berth: float
    pit_mean: float

    def describe(self) -> str:
        berth = (
            f", pit distance {self.pit_mean:.2f} on average, {self.pit_berth:.2f} at the closest"
            if self.pit_berth < 1e5
            else ""
        )
        return (
            f"return {self.ret:.1f} ± {self.ret_std:.1f}, goal {self.success:.0%}, pit {self.fell:.0%}, "
            f"{self.steps:.0f} steps, {self.ice:.0%} on ice, {self.sand:.0%} on sand{berth}"
        )


def route_stats(params: TerrainParams, positions, rewards, alive) -> RouteStats:
    """Statistics of rollouts from :func:`rollouts` (terrain shares over the steps taken)."""
    terr = jax.vmap(jax.vmap(lambda p: terrain_at(params, p)))(positions[:, :-1])
    final = jax.vmap(lambda p: terrain_at(params, p))(positions[:, -1])
    berth = jax.vmap(jax.vmap(lambda p: pit_distance(params, p)))(positions)
    alive_f = np.asarray(alive, np.float64)
    n_steps = alive_f.sum(1)
    ret = np.asarray(rewards).sum(1)

    def share(code):
        return float(((np.asarray(terr) == code) * alive_f).sum() / max(n_steps.sum(), 1))

    visited = np.concatenate([np.ones_like(alive_f[:, :1]), alive_f], 1) > 0  # start + each step taken
    berth = np.asarray(berth, np.float64)
    return RouteStats(
        ret=float(ret.mean()),
        ret_std=float(ret.std()),
        success=float((np.asarray(final) == GOAL).mean()),
        fell=float((np.asarray(final) == PIT).mean()),
        steps=float(n_steps.mean()),
        ice=share(ICE),
        sand=share(SAND),
        pit_berth=float(np.mean(np.where(visited, berth, np.inf).min(1))),
        pit_mean=float(np.mean((berth * visited).sum(1) / visited.sum(1))),
    )
