"""Can preferences identify a person's belief? The Fisher information of the belief's parameters.

A Bradley–Terry person with finite β (Eq. 3.4) answers from the score difference of two
equal-length segments, S = Σ_t [r_H(s_t, a_t) + log T_H(s_{t+1} | s_t, a_t; θ)]. A learner
models r_H with a free function of (s, a), so any part of log T_H that depends on (s, a)
alone can be absorbed into its reward: only the variation of log T_H *between outcomes of
the same (s, a)* pins θ. The efficient score of one transition is therefore

    g̃(s, a, s') = ∇_θ log T_H(s' | s, a; θ) − E_{s'' ~ T(·|s, a)} ∇_θ log T_H(s'' | s, a; θ),

the second term by Monte Carlo over fresh draws of the true dynamics, and a query's
information is β² p (1 − p) (ΔG)(ΔG)ᵀ with p the person's answer probability and ΔG the
difference of the two segments' summed g̃. Summed over a budget of queries (segments drawn
from an exploring agent's episodes: the optimal and the unaware policies of the design
check, half their actions uniformly random), the inverse gives each parameter's standard
error; a biased parameter is identifiable when the gap between belief and truth is at
least :data:`Z_IDENTIFIED` standard errors. Where the truth is deterministic, g̃ = 0 and
the information is nil, whatever the budget: the belief cannot be told from the reward.

θ is the belief's dynamics table (:class:`~mindgap.envs.terrain.params.Dynamics`): speed and
noise of every terrain the agent can stand on, the stuck probability where the belief or the
truth has one, and the pit noise where either has one.

Written by hand: the estimator is a few lines around the world's own exact ``log_prob_pos``.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..envs.terrain.dynamics import log_prob_pos, sample_next
from ..envs.terrain.layout import GOAL, PIT, TERRAINS, WALL
from ..envs.terrain.params import Dynamics, TerrainState
from ..envs.terrain.world import reset, reward, step

Z_IDENTIFIED = 3.0
"""A biased parameter is identified when |θ_H − θ_T| ≥ this many standard errors at the budget."""
EPSILON = 0.5
"""Share of the exploring agent's actions that are uniformly random."""


class Parameter(NamedTuple):
    """One belief parameter: its name, the truth's value, the person's, and its standard error at the budget."""

    name: str
    truth: float
    belief: float
    stderr: float

    @property
    def biased(self) -> bool:
        return abs(self.belief - self.truth) > 1e-6

    @property
    def z(self) -> float:
        """|belief − truth| in standard errors (inf where the information is exact, 0 where unbiased)."""
        gap = abs(self.belief - self.truth)
        if not self.biased:
            return 0.0
        return gap / self.stderr if self.stderr > 0 else float("inf")

    @property
    def identified(self) -> bool:
        return not self.biased or self.z >= Z_IDENTIFIED


def parameter_slots(params, true: Dynamics, belief: Dynamics) -> list[tuple[str, str, int | None]]:
    """(name, Dynamics field, terrain code or None) of the belief parameters θ of this world."""
    grid = np.asarray(params.grid)
    stops = (WALL, PIT) if float(params.fixed_horizon) > 0.5 else (WALL, PIT, GOAL)  # no step is taken from these
    present = sorted({int(c) for c in np.unique(grid) if c not in stops})
    slots = []
    for code in present:
        name = TERRAINS[code]
        slots += [(f"{name}.speed", "speed", code), (f"{name}.noise", "noise", code)]
        if float(true.stuck[code]) > 0 or float(belief.stuck[code]) > 0:
            slots.append((f"{name}.stuck", "stuck", code))
    if (grid == PIT).any() and (float(true.pit_noise) > 0 or float(belief.pit_noise) > 0):
        slots += [("pit_noise", "pit_noise", None), ("pit_scale", "pit_scale", None)]
    return slots


def _table_slots(dyn: Dynamics) -> tuple[tuple[str, str, int | None], ...]:
    """Every entry of a dynamics table as a slot (speed, noise and stuck of each terrain, the pit term's two).

    The Fisher information of the whole table holds θ's as its rows and columns for θ's slots: a
    parameter's score does not depend on which others are differentiated. Computing it for the
    table, whose shape is every terrain world's, compiles one program where θ's own slots would
    compile one per set of biased parameters.
    """
    per_terrain = tuple(
        (f"{TERRAINS[c]}.{f}", f, c) for c in range(len(np.asarray(dyn.speed))) for f in ("speed", "noise", "stuck")
    )
    return (*per_terrain, ("pit_noise", "pit_noise", None), ("pit_scale", "pit_scale", None))


def _get(dyn: Dynamics, slots) -> jax.Array:
    return jnp.stack([getattr(dyn, f) if c is None else getattr(dyn, f)[c] for _, f, c in slots]).astype(jnp.float32)


def _put(dyn: Dynamics, slots, theta: jax.Array) -> Dynamics:
    fields = dyn._asdict()
    for i, (_, f, c) in enumerate(slots):
        fields[f] = theta[i] if c is None else jnp.asarray(fields[f]).at[c].set(theta[i])
    return Dynamics(**fields)


def belief_information(
    world_params,
    belief_params,
    behaviour: list,
    actions: np.ndarray,
    index: jax.Array,
    n: int,
    *,
    beta: float | None,
    budget: int,
    segment: int,
    log_t_floor: float,
    episodes: int = 64,
    draws: int = 16,
    pairs: int = 4000,
    seed: int = 0,
) -> list[Parameter]:
    """Each belief parameter's standard error after ``budget`` answered queries (see the module docstring).

    Args:
        behaviour: time-dependent policies ``[H, N]`` (action ids on the sub-cell grid ``index``)
            whose ε-random episodes supply the segments.
        beta: the person's rationality; None (deterministic answers) identifies no scale, so
            every standard error is infinite.
    """
    slots = tuple(parameter_slots(world_params, world_params.dynamics, belief_params.dynamics))
    theta_t = _get(world_params.dynamics, slots)
    theta_h = _get(belief_params.dynamics, slots)
    if beta is None or not slots:
        se = np.full(len(slots), np.inf)
    else:
        key = rng.key(seed)
        k_roll, k_pair = jax.random.split(key)
        trans = [
            _episodes(k, world_params, jnp.asarray(pol), jnp.asarray(actions), index, n, episodes)
            for k, pol in zip(jax.random.split(k_roll, len(behaviour)), behaviour, strict=True)
        ]
        trans = jax.tree.map(lambda *x: jnp.concatenate(x), *trans)
        # one program for every world of a shape: the information of the whole table, then θ's rows and columns
        table = _table_slots(belief_params.dynamics)
        info = _information(
            k_pair,
            world_params,
            belief_params,
            trans,
            table,
            _get(belief_params.dynamics, table),
            float(beta),
            segment,
            log_t_floor,
            draws,
            pairs,
        )
        rows = [table.index(s) for s in slots]
        info = np.asarray(info, np.float64)[np.ix_(rows, rows)] * budget
        se = np.sqrt(np.clip(np.diag(np.linalg.pinv(info, hermitian=True)), 0.0, None))
        se = np.where(np.diag(info) > 1e-12, se, np.inf)
    return [
        Parameter(name, float(t), float(h), float(s))
        for (name, _, _), t, h, s in zip(slots, np.asarray(theta_t), np.asarray(theta_h), se, strict=True)
    ]


@partial(jax.jit, static_argnames=("n", "count"))
def _episodes(key, params, policy, actions, index, n: int, count: int):
    """``count`` ε-random episodes of a time-dependent sub-cell policy: (pos, act, next_pos, alive) each ``[E, H, ·]``."""
    horizon = policy.shape[0]

    def one(k):
        k0, k1 = jax.random.split(k)

        def body(s, xs):
            t, kk = xs
            k_eps, k_act, k_step = jax.random.split(kk, 3)
            sub = jnp.floor(s.pos[::-1] * n).astype(jnp.int32)
            sid = jnp.maximum(index[sub[0], sub[1]], 0)
            planned = actions[policy[t, sid]]
            noise = jax.random.uniform(k_act, (2,), minval=-1.0, maxval=1.0)
            a = jnp.where(jax.random.uniform(k_eps) < EPSILON, noise, planned)
            out = step(k_step, s, a, params)
            return out.state, (s.pos, a, out.state.pos, ~s.done)

        _, tr = jax.lax.scan(body, reset(k0, params), (jnp.arange(horizon), jax.random.split(k1, horizon)))
        return tr

    return jax.vmap(one)(jax.random.split(key, count))


@partial(jax.jit, static_argnames=("slots", "segment", "draws", "pairs"))
def _information(key, params, belief, trans, slots, theta_h, beta, segment, floor, draws, pairs):
    """The Fisher information of θ per query (averaged over ``pairs`` random pairs of segments)."""
    pos, act, nxt, alive = trans
    e, h = alive.shape
    k_draw, k_a, k_b = jax.random.split(key, 3)

    def log_t(theta, s, a, s2):
        p = belief._replace(dynamics=_put(belief.dynamics, slots, theta))
        return jnp.maximum(log_prob_pos(p, s, a, s2), floor)

    grad = jax.grad(log_t)

    def per_step(s, a, s2, k):
        again = jax.vmap(lambda kk: sample_next(kk, params, s, a))(jax.random.split(k, draws))
        centre = jax.vmap(lambda q: grad(theta_h, s, a, q))(again).mean(0)
        zero = jnp.zeros((), jnp.int32)
        r = reward(TerrainState(s, zero, False), a, TerrainState(s2, zero, False), params)
        return grad(theta_h, s, a, s2) - centre, r + log_t(theta_h, s, a, s2)

    keys = jax.random.split(k_draw, e * h).reshape(e, h)
    g, score = jax.vmap(jax.vmap(per_step))(pos, act, nxt, keys)  # [E, H, P], [E, H]
    cut = (h // segment) * segment
    segs = e * (h // segment)

    def segments(x):
        return x[:, :cut].reshape(segs, segment, *x.shape[2:])

    live = segments(alive)
    g_seg = jnp.sum(segments(g) * live[..., None], 1)  # [M, P]
    s_seg = jnp.sum(jnp.where(live, segments(score), 0.0), 1)  # [M]
    ia, ib = jax.random.randint(k_a, (pairs,), 0, segs), jax.random.randint(k_b, (pairs,), 0, segs)
    p = jax.nn.sigmoid(beta * (s_seg[ia] - s_seg[ib]))
    dg = g_seg[ia] - g_seg[ib]
    w = beta**2 * p * (1 - p)
    return jnp.einsum("q,qi,qj->ij", w, dg, dg) / pairs
