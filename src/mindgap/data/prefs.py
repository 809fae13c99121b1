"""Answered preference queries: a fixed-capacity store of pairs of segments and their labels.

Every learner from preferences keeps one (PEBBLE's ensemble, PrefBias's posterior, EPS's u_H).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .segments import Segments, with_absorbing


class PrefData(NamedTuple):
    """Answered queries, fixed capacity: seg_a, seg_b [Q, L, ·]; label [Q]; count."""

    seg_a: Segments
    seg_b: Segments
    label: jax.Array
    count: jax.Array


def prefs_init(capacity: int, length: int, obs_dim: int, act_dim: int, absorbing: bool = False) -> PrefData:
    """An empty store; with ``absorbing`` it keeps the absorbing steps of the segments too."""
    seg = Segments(
        jnp.zeros((capacity, length, obs_dim)),
        jnp.zeros((capacity, length, act_dim)),
        jnp.zeros((capacity, length, obs_dim)),
        jnp.zeros((capacity, length), bool),
    )
    seg = with_absorbing(seg, absorbing)
    return PrefData(seg, seg, jnp.zeros(capacity), jnp.zeros((), jnp.int32))


def prefs_add(data: PrefData, seg_a: Segments, seg_b: Segments, label: jax.Array, answered: jax.Array) -> PrefData:
    """Append the answered queries (skipped ones are dropped).

    Segments are stored in the store's own form: absorbing steps are kept only by a store
    made with ``absorbing=True`` (plain segments added to one have none).
    """
    absorbing = hasattr(data.seg_a, "absorbed")
    seg_a, seg_b = with_absorbing(seg_a, absorbing), with_absorbing(seg_b, absorbing)
    cap = data.label.shape[0]
    slot = data.count + jnp.cumsum(answered) - 1
    slot = jnp.where(answered & (slot < cap), slot, cap)  # cap: out of range, dropped by the scatter

    def put(store, new):
        return jax.tree.map(lambda s, n: s.at[slot].set(n, mode="drop"), store, new)

    return PrefData(
        put(data.seg_a, seg_a),
        put(data.seg_b, seg_b),
        data.label.at[slot].set(label, mode="drop"),
        jnp.minimum(data.count + answered.sum(), cap),
    )
