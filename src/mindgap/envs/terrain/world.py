"""The functional API of terrain worlds: ``reset``, ``step``, ``log_prob``, ``reward``, ``observe``.

Pure functions of (key, state, action, params); all are jittable and vmappable over any
of their arguments, so thousands of worlds, seeds or beliefs step together::

    states = jax.vmap(reset, (0, None))(keys, params)
    out = jax.vmap(step, (0, 0, 0, None))(keys, states, actions, params)

Call them inside a jitted program, or wrap them (``jax.jit(step)``): called eagerly, their
control flow compiles again at every call, close to a second a step on a CPU core.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from ..interface import Box, Env, Step, pick_belief
from .dynamics import OFFSETS, cell_of, is_wall, log_prob_pos, sample_next, terrain_at, trapped
from .layout import GOAL, PIT, Layout
from .params import Dynamics, TerrainParams, TerrainState


def reset(key: jax.Array, params: TerrainParams) -> TerrainState:
    """A start position: the centre of a random start cell, jittered by ± ``start_jitter``."""
    k_cell, k_jit = jax.random.split(key)
    rc = params.starts[jax.random.randint(k_cell, (), 0, params.starts.shape[0])]
    jitter = jax.random.uniform(k_jit, (2,), minval=-params.start_jitter, maxval=params.start_jitter)
    pos = rc[::-1].astype(jnp.float32) + 0.5 + jitter
    return TerrainState(pos=pos, t=jnp.zeros((), jnp.int32), done=jnp.zeros((), bool))


def potential(params: TerrainParams, pos: jax.Array) -> jax.Array:
    """Φ(pos): geodesic distance to the goal, continuous across cells.

    The minimum over the passable 3×3 neighbours c of D(c) + |pos − centre(c)| (distance to
    the goal rectangle for a goal cell), where D is the cell-level Dijkstra distance.
    """
    rc = cell_of(pos)
    h, w = params.grid.shape
    tr, tc = rc[0] + OFFSETS[:, 0], rc[1] + OFFSETS[:, 1]
    trc, tcc = jnp.clip(tr, 0, h - 1), jnp.clip(tc, 0, w - 1)
    code = params.grid[trc, tcc]
    usable = ~is_wall(params, tr, tc) & (code != PIT)
    corner = jnp.stack([tc, tr], -1).astype(pos.dtype)  # (x, y)
    to_centre = jnp.linalg.norm(pos - (corner + 0.5), axis=-1)
    to_rect = jnp.linalg.norm(jnp.maximum(jnp.maximum(corner - pos, 0.0), pos - (corner + 1.0)), axis=-1)
    cand = params.potential[trc, tcc] + jnp.where(code == GOAL, to_rect, to_centre)
    return jnp.min(jnp.where(usable, cand, jnp.inf))


def reward(state: TerrainState, action: jax.Array, next_state: TerrainState, params: TerrainParams) -> jax.Array:
    """r(s, a, s') of :class:`~mindgap.envs.terrain.params.Rewards` (either form); 0 once the episode is over."""
    del action  # the reward of these worlds depends on where the agent goes, not how hard it pushes
    rw = params.rewards
    here = terrain_at(params, state.pos)
    r_state = rw.step + jnp.where(here == GOAL, rw.goal, 0.0) + jnp.where(here == PIT, rw.pit, 0.0)
    # Φ counts outside the goal and the pits only (a pit's own term is its cost; deep inside a wide
    # pit no passable cell is near and Φ is not defined)
    r_state = r_state - rw.distance * jnp.where((here == GOAL) | (here == PIT), 0.0, potential(params, state.pos))
    terr = terrain_at(params, next_state.pos)
    # Φ = 0 in every terminal cell: over a whole episode the progress terms then add up to
    # Φ(start) whichever way it ends, so they shape learning without changing which
    # episodes are better (potential-based shaping, Ng et al. 1999).
    phi_next = jnp.where((terr == GOAL) | (terr == PIT), 0.0, potential(params, next_state.pos))
    r = (
        rw.step
        + rw.progress * (potential(params, state.pos) - phi_next)
        + jnp.where(terr == GOAL, rw.goal, 0.0)
        + jnp.where(terr == PIT, rw.pit, 0.0)
    )
    return jnp.where(state.done, 0.0, jnp.where(rw.state_form > 0.5, r_state, r))


def step(key: jax.Array, state: TerrainState, action: jax.Array, params: TerrainParams) -> Step:
    """One transition: sample the next position, score it, end the episode on pit, goal or horizon.

    With a fixed horizon (``params.fixed_horizon``) only the horizon ends it; a pit traps the
    agent, which stays put until then.
    """
    pos = jnp.where(state.done | trapped(params, state.pos), state.pos, sample_next(key, params, state.pos, action))
    terr = terrain_at(params, pos)
    terminated = ~state.done & (params.fixed_horizon < 0.5) & ((terr == GOAL) | (terr == PIT))
    t = state.t + jnp.where(state.done, 0, 1)
    truncated = ~state.done & ~terminated & (t >= params.horizon)
    nxt = TerrainState(pos=pos, t=t, done=state.done | terminated | truncated)
    return Step(nxt, reward(state, action, nxt, params), terminated, truncated)


def log_prob(state: TerrainState, action: jax.Array, next_state: TerrainState, params: TerrainParams) -> jax.Array:
    """Exact log p(s' | s, a) (see :mod:`~mindgap.envs.terrain.dynamics`); a finished state stays put."""
    live = log_prob_pos(params, state.pos, action, next_state.pos)
    still = jnp.where(jnp.all(next_state.pos == state.pos), 0.0, -jnp.inf)
    return jnp.where(state.done, still, live)


def observe(state: TerrainState, params: TerrainParams) -> jax.Array:
    """Observation: the position scaled to [−1, 1]² (x by the width, y by the height)."""
    h, w = params.grid.shape
    return 2.0 * state.pos / jnp.array([w, h], state.pos.dtype) - 1.0


def position(obs: jax.Array, params: TerrainParams) -> jax.Array:
    """Inverse of :func:`observe`."""
    h, w = params.grid.shape
    return (obs + 1.0) * 0.5 * jnp.array([w, h], obs.dtype)


def obs_reward(obs: jax.Array, action: jax.Array, next_obs: jax.Array, params: TerrainParams) -> jax.Array:
    """:func:`reward` of a transition given as observations (it depends on positions only)."""
    zero = jnp.zeros((), jnp.int32)
    s, s2 = position(obs, params), position(next_obs, params)
    return reward(TerrainState(s, zero, False), action, TerrainState(s2, zero, False), params)


def obs_log_prob(obs: jax.Array, action: jax.Array, next_obs: jax.Array, params: TerrainParams) -> jax.Array:
    """The exact log density of a live transition given as observations (:func:`log_prob_pos`)."""
    return log_prob_pos(params, position(obs, params), action, position(next_obs, params))


TERRAIN_ENV = Env(
    reset=reset,
    step=step,
    observe=observe,
    observation_space=Box((2,)),
    action_space=Box((2,)),
    reward=obs_reward,
    log_prob=obs_log_prob,
)
"""The terrain worlds as an :class:`~mindgap.envs.interface.Env` (one object: learners compile once for all of them)."""


@dataclasses.dataclass(frozen=True)
class TerrainWorld:
    """A named world: its layout, parameters under the true dynamics, and named beliefs.

    Attributes:
        name: the world's name.
        layout: the parsed ASCII layout.
        params: parameters with the true dynamics.
        beliefs: belief name → dynamics table (a person's view of the same world).
        description: one paragraph on what the world tests.
        source: the file it was read from, if any.
        expect: what the planning check must show (see :mod:`~mindgap.envs.terrain.files`).
    """

    name: str
    layout: Layout
    params: TerrainParams
    beliefs: dict[str, Dynamics]
    description: str = ""
    source: str | None = None
    expect: dict = dataclasses.field(default_factory=dict)

    def belief(self, name: str | None = None) -> TerrainParams:
        """Parameters of the world as a person with belief ``name`` sees it (default: the first)."""
        return self.params.with_dynamics(pick_belief(self.name, self.beliefs, name))

    @property
    def env(self) -> Env:
        """The world's functions (:data:`TERRAIN_ENV`)."""
        return TERRAIN_ENV

    @property
    def horizon(self) -> int:
        """Steps of an episode at most."""
        return int(self.params.horizon)

    def fingerprint_tree(self):
        """What a run record hashes to recognise this world: its parameters and belief tables."""
        return (self.params, self.beliefs)

    def trace(self, obs):
        """Positions along observed paths ``obs [..., T+1, 2]`` (for drawing on the map)."""
        return position(obs, self.params)

    def obs_units(self) -> jax.Array:
        """[2] cells per unit of observation along (x, y): the observation maps the map onto [−1, 1]²."""
        h, w = self.params.grid.shape
        return jnp.array([w, h], jnp.float32) / 2.0

    @property
    def true_dynamics(self) -> Dynamics:
        return self.params.dynamics
