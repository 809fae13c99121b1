"""Choosing which pairs of segments to ask about (§3.3.3.3; PEBBLE's samplers).

Draw ``candidates × K`` random pairs and keep the K that score highest:

* ``uniform`` — the first K (no scoring);
* ``disagreement`` — the standard deviation over ensemble members of P(a ≻ b);
* ``entropy`` — the binary entropy of the members' mean P(a ≻ b).

PrefBias adds ``preference disagreement`` on top of the same interface.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..models.reward_ensemble import preference_probs
from .replay import Replay
from .segments import sample_segments, take

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


def select_queries(key, buf: Replay, reward_params, k: int, length: int, sampler: str, candidates: int):
    """K pairs of segments to show the person. Returns (seg_a, seg_b), each [K, L, ·]."""
    ka, kb = jax.random.split(key)
    m = k * (1 if sampler == "uniform" else candidates)
    seg_a, seg_b = sample_segments(buf, ka, m, length), sample_segments(buf, kb, m, length)
    if sampler == "uniform":
        return seg_a, seg_b
    top = jax.lax.top_k(query_scores(preference_probs(reward_params, seg_a, seg_b), sampler), k)[1]
    return take(seg_a, top), take(seg_b, top)
