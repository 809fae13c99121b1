"""Choosing which pairs of segments to ask about (§3.3.3.3; PEBBLE's samplers).

Draw ``candidates × K`` random pairs and keep the K that score highest:

* ``uniform`` — the first K (no scoring);
* ``disagreement`` — the standard deviation over ensemble members of P(a ≻ b);
* ``entropy`` — the binary entropy of the members' mean P(a ≻ b);
* ``preference_disagreement`` — how differently a pair would be judged by someone who knows
  the agent's dynamics and by the person as modelled (PrefBias, §3.3.3.3).

The samplers are one registry (:data:`SAMPLERS`). A learner supplies a :class:`QueryModel`,
functions that say what it predicts about candidate pairs, so this module knows no model:
PEBBLE's ensemble, PrefBias's posterior draws (:mod:`~mindgap.algorithms.prefbias_queries`) and
EPS's u_H ensemble all use it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..data.replay import Replay
from ..data.segments import sample_segments, take


class QueryModel(NamedTuple):
    """What a learner tells the samplers about a batch of candidate pairs.

    Attributes:
        members: ``(seg_a, seg_b) → P(a ≻ b) [E, M]`` of each of its E members (ensemble
            members, or joint draws from a posterior).
        belief_divergence: ``(seg_a, seg_b) → [M]``, how differently the pairs would be judged
            by someone who knows the agent's dynamics and by the person as modelled; None for a
            learner without a model of the person's belief.
    """

    members: Callable
    belief_divergence: Callable | None = None


def _disagreement(model: QueryModel, seg_a, seg_b) -> jax.Array:
    return query_scores(model.members(seg_a, seg_b), "disagreement")


def _entropy(model: QueryModel, seg_a, seg_b) -> jax.Array:
    return query_scores(model.members(seg_a, seg_b), "entropy")


def _belief_divergence(model: QueryModel, seg_a, seg_b) -> jax.Array:
    if model.belief_divergence is None:
        raise ValueError("preference_disagreement needs a learner with a model of the person's belief (PrefBias)")
    return model.belief_divergence(seg_a, seg_b)


class Sampler(NamedTuple):
    """A query sampler: ``score(model, seg_a, seg_b) → [M]`` (higher is asked first), or None to keep
    the first K candidates unscored; ``needs_belief``: it reads ``QueryModel.belief_divergence``."""

    score: Callable | None
    needs_belief: bool = False


SAMPLERS: dict[str, Sampler] = {
    "uniform": Sampler(None),
    "disagreement": Sampler(_disagreement),
    "entropy": Sampler(_entropy),
    "preference_disagreement": Sampler(_belief_divergence, needs_belief=True),
}
"""Every query sampler by name (PrefBias's ``preference_disagreement`` is §3.3.3.3's)."""


def sampler_names(belief: bool) -> tuple[str, ...]:
    """The samplers a learner can use: all of them if it models the person's belief, else those that do not need it."""
    return tuple(name for name, s in SAMPLERS.items() if belief or not s.needs_belief)


def check_sampler(name: str, belief: bool) -> None:
    """Refuse a sampler that does not exist or that needs a belief model the learner lacks."""
    names = sampler_names(belief)
    if name not in names:
        raise ValueError(f"unknown sampler {name!r}: choose from {', '.join(names)}")


def query_scores(probs: jax.Array, sampler: str) -> jax.Array:
    """Score candidate pairs from the members' P(a ≻ b) [E, M] → [M] (higher is asked first)."""
    if sampler == "disagreement":
        return probs.std(0)
    if sampler == "entropy":
        p = jnp.clip(probs.mean(0), 1e-6, 1 - 1e-6)
        return -(p * jnp.log(p) + (1 - p) * jnp.log(1 - p))
    if sampler == "uniform":
        return -jnp.arange(probs.shape[-1], dtype=jnp.float32)
    raise ValueError(f"unknown sampler {sampler!r}: choose from uniform, disagreement, entropy")


def candidate_pairs(ka, kb, buf: Replay, count: int, length: int, absorbing: bool = False, from_start: bool = False):
    """``count`` random pairs of segments of ``length`` steps, side a drawn with ``ka``, side b with ``kb``
    (with ``from_start``, both from episodes' first steps: :func:`~mindgap.data.segments.sample_segments`)."""
    a = sample_segments(buf, ka, count, length, absorbing, from_start)
    return a, sample_segments(buf, kb, count, length, absorbing, from_start)


def keep_best(seg_a, seg_b, scores: jax.Array, k: int):
    """The ``k`` pairs with the highest ``scores [M]``."""
    top = jax.lax.top_k(scores, k)[1]
    return take(seg_a, top), take(seg_b, top)


def select_pairs(
    ka,
    kb,
    buf: Replay,
    model: QueryModel,
    k: int,
    length: int,
    sampler: str,
    candidates: int,
    absorbing: bool = False,
    from_start: bool = False,
):
    """K pairs of segments to show the person: the best K of ``candidates × K`` random pairs
    (side a drawn with ``ka``, side b with ``kb``) by ``sampler`` (:data:`SAMPLERS`), or the first K
    when it scores none.

    Args:
        model: what the learner says about candidate pairs (:class:`QueryModel`).
        absorbing: keep the steps after a terminal transition as absorbing steps
            (:class:`~mindgap.data.segments.AbsorbingSegments`).
        from_start: segments start at episodes' first steps (``Schedule.queries_from = "start"``).

    Returns:
        (seg_a, seg_b), each [K, L, ·].
    """
    if sampler not in SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}: choose from {', '.join(SAMPLERS)}")
    score = SAMPLERS[sampler].score
    seg_a, seg_b = candidate_pairs(ka, kb, buf, k * (1 if score is None else candidates), length, absorbing, from_start)
    if score is None:
        return seg_a, seg_b
    return keep_best(seg_a, seg_b, score(model, seg_a, seg_b), k)


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
    """:func:`select_pairs` for a learner whose only say is its members' P(a ≻ b):
    ``probs_fn: (seg_a, seg_b) → [E, M]`` (PEBBLE's and EPS's ensembles)."""
    ka, kb = jax.random.split(key)
    return select_pairs(ka, kb, buf, QueryModel(probs_fn), k, length, sampler, candidates, absorbing, from_start)
