"""Choosing queries for PrefBias (§3.3.3.3): the engine's three samplers and preference disagreement.

Draw ``candidates × K`` random pairs of segments and keep the K that score highest:

* ``uniform`` — K random pairs, no scoring;
* ``disagreement`` — the standard deviation of p̂(a ≻ b | w, φ) (Eq. 3.4) over ``samples``
  joint draws of all weights of r_w and f_φ from the posterior;
* ``entropy`` — the binary entropy of the mean of those draws;
* ``preference_disagreement`` — ``KL[p̂(·; r_w, f_ψ) ‖ p̂(·; r_w, f_φ)]``, how differently a
  pair would be judged by someone who knows the agent's dynamics (the learned f_ψ) and by
  the person as currently modelled (f_φ), both with the posterior-mean reward and weights.
  Pairs where the two differ most are the most informative about the belief.

The first three reuse :func:`~mindgap.feedback.queries.query_scores` on the posterior
draws, which play the role of the reward ensemble's members.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..data.replay import Replay
from ..data.segments import Segments
from ..feedback.queries import candidate_pairs, keep_best, query_scores
from ..models.bayes import sample_params
from ..models.gaussian_dynamics import DynamicsModel
from .prefbias_inference import PrefBiasConfig, PrefBiasState, preference_prob

SAMPLERS = ("uniform", "disagreement", "entropy", "preference_disagreement")


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
    """Score M candidate pairs with ``sampler`` (higher is asked first): [M]."""
    if sampler == "preference_disagreement":
        return preference_disagreement(state, dynamics, seg_a, seg_b, cfg)
    if sampler in ("disagreement", "entropy"):
        return query_scores(posterior_preferences(state, seg_a, seg_b, key, samples, cfg), sampler)
    if sampler == "uniform":
        return -jnp.arange(seg_a.mask.shape[0], dtype=jnp.float32)
    raise ValueError(f"unknown sampler {sampler!r}: choose from {', '.join(SAMPLERS)}")


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
    """K pairs of segments to show the person, the best K of ``candidates × K`` random pairs.

    Jittable with ``k, length, sampler, cfg, candidates, samples, from_start`` static; ``from_start``:
    segments start at episodes' first steps (``Schedule.queries_from``).

    Returns:
        (seg_a, seg_b), each [K, L, ·]: :class:`~mindgap.data.segments.AbsorbingSegments`
        when ``cfg.absorbing``, else plain segments.
    """
    if sampler not in SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}: choose from {', '.join(SAMPLERS)}")
    ka, kb, ks = jax.random.split(key, 3)
    m = k * (1 if sampler == "uniform" else candidates)
    seg_a, seg_b = candidate_pairs(ka, kb, buf, m, length, cfg.absorbing, from_start)
    if sampler == "uniform":
        return seg_a, seg_b
    return keep_best(seg_a, seg_b, candidate_scores(state, dynamics, seg_a, seg_b, ks, sampler, cfg, samples), k)
