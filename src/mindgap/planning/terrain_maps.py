"""Terrain maps of learned and believed dynamics: each cell's noise and stay probability.

PrefBias learns a belief f_φ over observations; these read it (and a terrain dynamics table)
out cell by cell, in the world's own units, so a learned belief can be drawn next to the
person's and its error measured (the belief error of Figs. 22–24). Two parts of a belief
are read: the noise of a move (:func:`belief_noise_map`, :func:`table_noise_map`) and the
probability of not moving at all, stuck or bumped (:func:`belief_stay_map`,
:func:`table_stay_map`; the part the redesigned nav worlds' person gets wrong).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from ..envs.terrain.dynamics import is_wall, log_prob_pos, move_model
from ..models.gaussian_dynamics import Norm
from ..models.mlp import Params
from ..models.prefbias_nets import belief_predict, belief_stay_prob

CROSS_ACTIONS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))
"""The actions :func:`belief_noise_map` averages over: full pushes along each axis."""


def _cell_centres(world_params):
    h, w = world_params.grid.shape
    rows, cols = jnp.meshgrid(jnp.arange(h), jnp.arange(w), indexing="ij")
    return rows, cols, jnp.stack([cols, rows], -1).astype(jnp.float32) + 0.5  # [H, W, 2] (x, y)


def _cell_inputs(world_params, actions):
    """Observations and actions at every cell centre × action: ([H, W, n, 2], [H, W, n, 2]), and positions [H, W, 2]."""
    h, w = world_params.grid.shape
    actions = jnp.asarray(CROSS_ACTIONS if actions is None else actions, jnp.float32)
    _, _, pos = _cell_centres(world_params)
    obs = 2.0 * pos / jnp.array([w, h], jnp.float32) - 1.0  # as envs.terrain.observe
    obs = jnp.broadcast_to(obs[:, :, None], (h, w, actions.shape[0], 2))
    return obs, jnp.broadcast_to(actions, obs.shape), pos


def belief_noise_map(
    params: Params, norm: Norm, world_params, min_std: float, actions: jax.Array | None = None
) -> jax.Array:
    """The belief's predicted noise at each cell of a terrain world, for drawing it on the map.

    At every cell centre, the standard deviation f_φ predicts for the next position,
    converted from observation units to cells and averaged over the two axes and over
    ``actions`` [n, 2] (default :data:`CROSS_ACTIONS`). Comparable with the ``noise``
    column of a :class:`~mindgap.envs.terrain.Dynamics` table.

    Returns:
        [H, W] float, NaN on walls.
    """
    h, w = world_params.grid.shape
    rows, cols, _ = _cell_centres(world_params)
    obs, act, _ = _cell_inputs(world_params, actions)
    _, std = belief_predict(params, norm, obs, act, min_std)  # [H, W, n, 2], observation units
    cells = (std * 0.5 * jnp.array([w, h], jnp.float32)).mean((-1, -2))
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, cells)


@jax.jit  # called from host code: op by op, each call compiled the dynamics' branches again
def table_noise_map(world_params) -> jax.Array:
    """The noise scale σ(s) a dynamics table gives each cell centre (terrain noise plus the pit term).

    Pass a world's parameters under a person's belief (``world.belief(name)``) to draw that
    belief's noise next to :func:`belief_noise_map`, or to measure how far a learned belief is
    from it. Returns [H, W] in cells, NaN on walls.
    """
    rows, cols, pos = _cell_centres(world_params)
    sigma = jax.vmap(jax.vmap(lambda p: move_model(world_params, p, jnp.zeros(2))[1]))(pos)
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, sigma)


def belief_stay_map(params: Params, norm: Norm, world_params, actions: jax.Array | None = None) -> jax.Array:
    """f_φ's probability of not moving at each cell centre, averaged over ``actions`` (default
    :data:`CROSS_ACTIONS`): [H, W], NaN on walls and everywhere for a network without a stay head."""
    rows, cols, _ = _cell_centres(world_params)
    obs, act, _ = _cell_inputs(world_params, actions)
    stay = belief_stay_prob(params, norm, obs, act).mean(-1)
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, stay)


@jax.jit  # called from host code: op by op, each call compiled the dynamics' branches again
def table_stay_map(world_params, actions: jax.Array | None = None) -> jax.Array:
    """The exact probability of not moving (stuck, or bumped against a wall) a dynamics table gives each
    cell centre, averaged over ``actions`` as :func:`belief_stay_map`: [H, W], NaN on walls."""
    rows, cols, _ = _cell_centres(world_params)
    _, act, pos = _cell_inputs(world_params, actions)

    def at(p, acts):
        return jnp.mean(jax.vmap(lambda a: jnp.exp(log_prob_pos(world_params, p, a, p)))(acts))

    stay = jax.vmap(jax.vmap(at))(pos, act)
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, stay)


@partial(jax.jit, static_argnames=("min_std",))
def noise_maps(carry, world_params, min_std: float):
    """Every seed's learned belief f_φ (posterior mean) and agent model f_ψ as :func:`belief_noise_map` s.

    Args:
        carry: a PrefBias run's final carry (``carry.model.posterior``, ``carry.model.dynamics``; leading seed axis).
        min_std: the dynamics models' noise floor (``PrefBiasConfig.dynamics.min_std``).

    Returns:
        (belief [seeds, H, W], agent [seeds, H, W]), NaN on walls.
    """

    def one(c):
        belief = belief_noise_map(c.model.posterior.belief.mean, c.model.posterior.norm, world_params, min_std)
        agent = belief_noise_map(c.model.dynamics.params, c.model.dynamics.norm, world_params, min_std)
        return belief, agent

    return jax.vmap(one)(carry)


@jax.jit
def stay_maps(carry, world_params):
    """Every seed's learned belief f_φ and agent model f_ψ as :func:`belief_stay_map` s: ([seeds, H, W], [seeds, H, W])."""

    def one(c):
        belief = belief_stay_map(c.model.posterior.belief.mean, c.model.posterior.norm, world_params)
        agent = belief_stay_map(c.model.dynamics.params, c.model.dynamics.norm, world_params)
        return belief, agent

    return jax.vmap(one)(carry)
