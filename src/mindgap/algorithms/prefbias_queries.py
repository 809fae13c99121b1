"""Choosing queries for PrefBias (§3.3.3.3): what its posterior says to the samplers of
:mod:`~mindgap.feedback.queries`.

Draw ``candidates × K`` random pairs of segments and keep the K that score highest:

* ``uniform`` — K random pairs, no scoring;
* ``disagreement`` — the standard deviation of p̂(a ≻ b | w, φ) (Eq. 3.4) over ``samples``
  joint draws of all weights of r_w and f_φ from the posterior;
* ``entropy`` — the binary entropy of the mean of those draws;
* ``preference_disagreement`` — ``KL[p̂(·; r_w, f_ψ) ‖ p̂(·; r_w, f_φ)]``, how differently a
  pair would be judged by someone who knows the agent's dynamics (the learned f_ψ) and by
  the person as currently modelled (f_φ), both with the posterior-mean reward and weights.
  Pairs where the two differ most are the most informative about the belief.

The posterior draws play the role of the reward ensemble's members
(:class:`~mindgap.feedback.queries.QueryModel`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..data.replay import Replay
from ..data.segments import Segments
from ..feedback.queries import SAMPLERS as SAMPLERS  # the one registry of samplers, re-exported
from ..feedback.queries import QueryModel, select_pairs
from ..models.bayes import sample_params
from ..models.gaussian_dynamics import DynamicsModel
from .prefbias_inference import PrefBiasConfig, PrefBiasState, preference_prob


def posterior_preferences(state: PrefBiasState, seg_a: Segments, seg_b: Segments, key: jax.Array, samples: int, cfg):
    """p̂(a ≻ b) under ``samples`` joint draws (w, φ) ~ q(w) q(φ), each drawn once for all pairs: [S, M]."""

    def one(k):
        k_w, k_phi = jax.random.split(k)
        w, phi = sample_params(state.reward, k_w), sample_params(state.belief, k_phi)
        return preference_prob(w, phi, state.norm, seg_a, seg_b, cfg, state.log_unit)

    return jax.vmap(one)(jax.random.split(key, samples))


def bernoulli_kl(p: jax.Array, q: jax.Array, eps: float = 1e-6) -> jax.Array:
    """KL[Bern(p) ‖ Bern(q)], elementwise, with both clipped to [eps, 1 − eps]."""
    p, q = jnp.clip(p, eps, 1 - eps), jnp.clip(q, eps, 1 - eps)
    return p * (jnp.log(p) - jnp.log(q)) + (1 - p) * (jnp.log1p(-p) - jnp.log1p(-q))


def preference_disagreement(
    state: PrefBiasState, dynamics: DynamicsModel, seg_a: Segments, seg_b: Segments, cfg: PrefBiasConfig
) -> jax.Array:
    """KL[p̂(q; r_w, f_ψ) ‖ p̂(q; r_w, f_φ)] per candidate pair q (§3.3.3.3): [M].

    r_w and f_φ at their posterior means; f_ψ read through its own normalisation.
    """
    w = state.reward.mean
    p_agent = preference_prob(w, dynamics.params, dynamics.norm, seg_a, seg_b, cfg, state.log_unit)
    p_person = preference_prob(w, state.belief.mean, state.norm, seg_a, seg_b, cfg, state.log_unit)
    return bernoulli_kl(p_agent, p_person)


def query_model(state: PrefBiasState, dynamics: DynamicsModel, key: jax.Array, samples: int, cfg) -> QueryModel:
    """What PrefBias says about candidate pairs: its posterior draws' P(a ≻ b) (``samples`` joint
    draws with ``key``) and :func:`preference_disagreement`."""
    return QueryModel(
        lambda seg_a, seg_b: posterior_preferences(state, seg_a, seg_b, key, samples, cfg),
        lambda seg_a, seg_b: preference_disagreement(state, dynamics, seg_a, seg_b, cfg),
    )


def candidate_scores(
    state: PrefBiasState,
    dynamics: DynamicsModel,
    seg_a: Segments,
    seg_b: Segments,
    key: jax.Array,
    sampler: str,
    cfg: PrefBiasConfig,
    samples: int = 8,
) -> jax.Array:
    """Score M candidate pairs with ``sampler`` (higher is asked first; ``uniform``: in order): [M]."""
    if sampler not in SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}: choose from {', '.join(SAMPLERS)}")
    score = SAMPLERS[sampler].score
    if score is None:
        return -jnp.arange(seg_a.mask.shape[0], dtype=jnp.float32)
    return score(query_model(state, dynamics, key, samples, cfg), seg_a, seg_b)


def select_queries(
    key: jax.Array,
    buf: Replay,
    state: PrefBiasState,
    dynamics: DynamicsModel,
    k: int,
    length: int,
    sampler: str,
    cfg: PrefBiasConfig,
    candidates: int = 3,
    samples: int = 8,
    from_start: bool = False,
) -> tuple[Segments, Segments]:
    """K pairs of segments to show the person, the best K of ``candidates × K`` random pairs
    (:func:`~mindgap.feedback.queries.select_pairs` with :func:`query_model`).

    Jittable with ``k, length, sampler, cfg, candidates, samples, from_start`` static; ``from_start``:
    segments start at episodes' first steps (``Schedule.queries_from``).

    Returns:
        (seg_a, seg_b), each [K, L, ·]: :class:`~mindgap.data.segments.AbsorbingSegments`
        when ``cfg.absorbing``, else plain segments.
    """
    ka, kb, ks = jax.random.split(key, 3)
    model = query_model(state, dynamics, ks, samples, cfg)
    return select_pairs(ka, kb, buf, model, k, length, sampler, candidates, cfg.absorbing, from_start)
