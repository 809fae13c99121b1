"""How expected a driving clip's decisions look, played out as the participant believes (§4.4.2, §4.3.1).

The driving study asked its participants "How should your autonomous car behave? … select
the one that is more expected" (Fig. 33), of clips of the car's response to a braking front
car, and §4.3.1 compares trajectories by "only the observable part" of them. A participant who
believes braking on sleet works as on a dry road does not watch the road's response and find
each weak braking step impossible; they judge whether the car *decided* as they expect, and
they see those decisions play out in the road they imagine. So a clip
(o_0, a_0, …, a_{L−1}) is scored by rolling its decisions forward in the participant's
believed world from the clip's first state:

    ŝ_0 = s(o_0),   ŝ_{t+1} = advance(ŝ_t, a_t, μ̄_H, onset_t),
    S_i(clip) = Σ_t γ^{L−1−t} max(log π_H,i(a_t | ŝ_t), floor)  +  floor · [crash(clip) ≠ crash(ŝ)],

where μ̄_H is the braking factor the participant expects (the mean of their belief's factor:
0.95 for a dry-road believer), onset_t is the front car's braking *as the clip shows it* (it
started braking at step t in the clip), ``advance`` is the world's own deterministic step
(:func:`~mindgap.envs.driving.world.advance`), and the last term charges a clip whose crash (or
absence of one) the participant's rollout of the same decisions does not reproduce: a crash
they did not expect, or one they expected that did not come. Steps after the believed rollout
ended (it crashed) are not scored; the crash term has said what there is to say. Without the
crash term (``crash=False``, the study's ``--answers-by rollout-behaviour``) the participant judges
the decisions alone, as the study's question asks ("How should your autonomous car behave?"),
however the road answered them. With
``cfg.relative`` each decision is scored against the most expected one in its state, as for the
state protocol (:class:`~mindgap.teachers.preference.TeacherConfig`).

Participants answer by Bradley–Terry on S_i (:class:`~mindgap.teachers.drivers.CrowdTeacher`)
and rate 1–10 by the geometric-mean form of §2.2.1, 1 + 9 · exp(S_i / n) over the n decisions
of the clip (:func:`~mindgap.teachers.drivers.rate_rollouts`; with the crash term, a crash the
participant did not expect rates lowest). Written by hand: the rollout is the scenario's own step with the
participant's expected draws, which no library provides.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..data.segments import Segments
from ..envs.driving.params import DrivingParams
from ..envs.driving.sleet import factor_mean_std
from ..envs.driving.world import advance, observe, state_from_obs
from ..models.categorical import categorical_log_prob, logits
from ..models.mlp import Params
from .preference import TeacherConfig, discounted_sum


def expected_factor(belief: DrivingParams) -> jax.Array:
    """μ̄_H: the braking factor the participant expects, their belief's mean (0.95 on a dry road)."""
    return factor_mean_std(belief.sleet, belief.grip)[0]


def believed_steps(obs: jax.Array, act: jax.Array, next_obs: jax.Array, mask: jax.Array, belief: DrivingParams):
    """One clip [L, ·] played out in the believed world: (believed observations ô_t [L, d], whether ŝ_t
    is live [L], whether the believed rollout crashed by the clip's end [])."""
    mu = expected_factor(belief)
    braking = obs[:, 7] > 0.5
    onset = (~braking) & (next_obs[:, 7] > 0.5)  # the front car starts braking at this step in the clip
    s0 = state_from_obs(obs[0], belief)

    def body(s, x):
        a, on, real = x
        o = observe(s, belief)
        live = ~s.done & real
        nxt = advance(s, a, mu, on, belief)
        s2 = jax.tree.map(lambda new, old: jnp.where(live, new, old), nxt, s)
        return s2, (o, live)

    last, (o_hat, live) = jax.lax.scan(body, s0, (act[:, 0], onset, mask > 0))
    return o_hat, live, last.crashed


def clip_crashed(seg: Segments) -> jax.Array:
    """Whether each clip [K, L, ·] ends in a collision (the crash flag of a real step's next observation): [K]."""
    return jnp.any((seg.mask > 0) & (seg.next_obs[..., 6] > 0.5), -1)


def believed_scores(
    seg: Segments,
    policy: Params,
    belief: DrivingParams,
    cfg: TeacherConfig,
    crash: bool = True,
    whole_clip: bool = False,
) -> jax.Array:
    """S_i of each clip (module docstring): seg [K, L, ·] → [K]. ``crash=False`` leaves the crash term out:
    the participant judges the decisions alone, however the road answered them. ``whole_clip`` judges a
    clip that ends early at the rate of the decisions it shows (:func:`whole_clip_scores`)."""

    def one(obs, act, next_obs, mask):
        o_hat, live, crashed = believed_steps(obs, act, next_obs, mask, belief)
        lp = categorical_log_prob(policy, o_hat, act)
        if cfg.relative:
            lp = lp - jnp.max(logits(policy, o_hat), -1)
        per_step = jnp.where(live, jnp.maximum(lp, cfg.log_t_floor), 0.0)
        return discounted_sum(per_step, mask, cfg.gamma), crashed, jnp.sum(live & (mask > 0))

    score, believed_crash, scored = jax.vmap(one)(seg.obs, seg.act, seg.next_obs, seg.mask)
    if whole_clip:
        score = whole_clip_scores(score, scored, seg.mask.shape[-1])
    if not crash:
        return score
    return score + jnp.where(clip_crashed(seg) != believed_crash, cfg.log_t_floor, 0.0)


def whole_clip_scores(score: jax.Array, scored: jax.Array, length: int) -> jax.Array:
    """A clip's score over its whole length at the rate of the decisions it shows: ``S · L / n`` [K].

    Every clip of the study is shown at one length (Fig. 33), and a decision of a categorical π_H
    never scores above 0, so a sum over the n decisions a clip holds favours a clip that ends
    early (it crashed) for having fewer decisions to judge. Scaled to the clip's length L, each
    clip is judged by how expected its decisions are per decision — the form its rating takes
    (§2.2.1's geometric mean) — and a clip that runs its whole length scores as before."""
    return score * (length / jnp.maximum(scored, 1))


def believed_per_step(
    seg: Segments, policy: Params, belief: DrivingParams, cfg: TeacherConfig, crash: bool = True
) -> jax.Array:
    """S_i / n over the n decisions each clip holds: [K] (the rating's and the sanity item's per-step form)."""
    return believed_scores(seg, policy, belief, cfg, crash) / jnp.maximum(seg.mask.sum(-1), 1)
