"""Segments of experience for preference queries, cut from the replay buffer.

A segment is ``length`` consecutive transitions of one episode. Episodes may end inside
a segment (goal, pit, horizon): the steps after the end are masked out, so they count
neither for the simulated person nor for the reward model.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .replay import Replay


class Segments(NamedTuple):
    """obs, next_obs [K, L, d]; act [K, L, a]; mask [K, L] (True for real steps)."""

    obs: jax.Array
    act: jax.Array
    next_obs: jax.Array
    mask: jax.Array


def sample_segments(buf: Replay, key: jax.Array, count: int, length: int) -> Segments:
    """``count`` segments starting at uniformly drawn stored transitions."""
    start = jax.random.randint(key, (count,), 0, jnp.maximum(buf.size, 1))
    idx = (start[:, None] + jnp.arange(length)[None, :]) % buf.capacity  # [K, L]
    ep = buf.ep_step[idx]
    contiguous = (ep == ep[:, :1] + jnp.arange(length)[None, :]) & (ep >= 0)
    ended_before = jnp.cumsum(buf.terminal[idx], axis=1) - buf.terminal[idx]  # a terminal earlier in the segment
    mask = jnp.cumprod(contiguous & (ended_before == 0), axis=1).astype(bool)
    return Segments(buf.obs[idx], buf.act[idx], buf.next_obs[idx], mask)


def take(seg: Segments, idx: jax.Array) -> Segments:
    """The segments at ``idx``."""
    return jax.tree.map(lambda x: x[idx], seg)
