"""Choosing which pairs of segments to ask about (§3.3.3.3; PEBBLE's samplers).

Draw ``candidates × K`` random pairs and keep the K that score highest:

* ``uniform`` — the first K (no scoring);
* ``disagreement`` — the standard deviation over ensemble members of P(a ≻ b);
* ``entropy`` — the binary entropy of the members' mean P(a ≻ b).

A learner supplies the members' P(a ≻ b) as a function (``probs_fn``), so this module knows
no model: PEBBLE's ensemble, PrefBias's posterior draws and EPS's u_H ensemble all use it.
PrefBias adds ``preference disagreement`` on top (:mod:`~mindgap.algorithms.prefbias_queries`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..data.replay import Replay
from ..data.segments import sample_segments, take

SAMPLERS = ("uniform", "disagreement", "entropy")


def query_scores(probs: jax.Array, sampler: str) -> jax.Array:
    """Score candidate pairs from the members' P(a ≻ b) [E, M] → [M] (higher is asked first)."""
    if sampler == "disagreement":
        return probs.std(0)
    if sampler == "entropy":
        p = jnp.clip(probs.mean(0), 1e-6, 1 - 1e-6)
        return -(p * jnp.log(p) + (1 - p) * jnp.log(1 - p))
    if sampler == "uniform":
        return -jnp.arange(probs.shape[-1], dtype=jnp.float32)
    raise ValueError(f"unknown sampler {sampler!r}: choose from {', '.join(SAMPLERS)}")


def candidate_pairs(ka, kb, buf: Replay, count: int, length: int, absorbing: bool = False, from_start: bool = False):
    """``count`` random pairs of segments of ``length`` steps, side a drawn with ``ka``, side b with ``kb``
    (with ``from_start``, both from episodes' first steps: :func:`~mindgap.data.segments.sample_segments`)."""
    a = sample_segments(buf, ka, count, length, absorbing, from_start)
    return a, sample_segments(buf, kb, count, length, absorbing, from_start)


def keep_best(seg_a, seg_b, scores: jax.Array, k: int):
    """The ``k`` pairs with the highest ``scores [M]``."""
    top = jax.lax.top_k(scores, k)[1]
    return take(seg_a, top), take(seg_b, top)


def select_queries(
    key,
    buf: Replay,
    probs_fn,
    k: int,
    length: int,
    sampler: str,
    candidates: int,
    absorbing: bool = False,
    from_start: bool = False,
):
    """K pairs of segments to show the person.

    Args:
        probs_fn: ``(seg_a, seg_b) → P(a ≻ b) [E, M]`` of each of the learner's E members.
        absorbing: keep the steps after a terminal transition as absorbing steps
            (:class:`~mindgap.data.segments.AbsorbingSegments`).
        from_start: segments start at episodes' first steps (``Schedule.queries_from = "start"``).

    Returns:
        (seg_a, seg_b), each [K, L, ·].
    """
    ka, kb = jax.random.split(key)
    m = k * (1 if sampler == "uniform" else candidates)
    seg_a, seg_b = candidate_pairs(ka, kb, buf, m, length, absorbing, from_start)
    if sampler == "uniform":
        return seg_a, seg_b
    return keep_best(seg_a, seg_b, query_scores(probs_fn(seg_a, seg_b), sampler), k)
