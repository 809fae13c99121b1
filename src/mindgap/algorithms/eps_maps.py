"""Maps of EPS's learned surrogate u_H over a terrain world (Fig. 28), for drawing next to the routes."""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from ..teachers.expectation import ExpectationTeacher
from .engine import Carry
from .eps import u_params
from .eps_config import EPSConfig
from .eps_reward import raw_u


def surrogate_maps(carry: Carry, world_params, person: ExpectationTeacher, cfg: EPSConfig, k: int = 4):
    """Every seed's :func:`surrogate_map`, of what its u_H is computed from (``cfg.surrogate``): [seeds, H·k, W·k]."""
    if cfg.surrogate == "exact":
        u = u_params(carry.model, person, cfg)
        return jax.vmap(lambda norm: surrogate_map(u, norm, world_params, k))(carry.model.u_norm)
    m = carry.model
    return jax.vmap(surrogate_map, in_axes=(0, 0, None, None))(m.reward.params, m.u_norm, world_params, k)


@partial(jax.jit, static_argnames=("k",))
def surrogate_map(u_params, u_norm: jax.Array, world_params, k: int = 4) -> jax.Array:
    """The standardised u_H on a k×k grid of points per cell, averaged over 16 full-speed directions (Fig. 28).

    Returns [H·k, W·k] (the layout of :func:`~mindgap.plotting.terrain.save_fields`); the
    walls are masked when drawn.
    """
    h, w = world_params.grid.shape
    ys, xs = (jnp.arange(h * k) + 0.5) / k, (jnp.arange(w * k) + 0.5) / k
    pos = jnp.stack(jnp.meshgrid(xs, ys), -1).reshape(-1, 2)  # (x, y), row-major over [H·k, W·k]
    obs = 2.0 * pos / jnp.array([w, h], jnp.float32) - 1.0
    angles = jnp.linspace(0.0, 2 * jnp.pi, 16, endpoint=False)
    acts = jnp.stack([jnp.cos(angles), jnp.sin(angles)], -1)
    flat = jnp.repeat(obs, 16, axis=0)
    u = (raw_u(u_params, flat, jnp.tile(acts, (obs.shape[0], 1)), flat) - u_norm[0]) / u_norm[1]
    return u.reshape(h * k, w * k, 16).mean(-1)
