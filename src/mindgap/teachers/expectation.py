"""The simulated person who says which of two segments is *more expected* (§4.3.3).

The person scores a segment by how likely they find it under their own model of the
agent — the believed dynamics T_H and the expected policy π_H:

    S(σ) = Σ_t γ^{L−1−t} [log T_H(s_{t+1} | s_t, a_t) + log π_H(a_t | s_t)],

which is Σ_t u_H(s_t, a_t) for the surrogate reward u_H of §4.3.3, and answers with
Bradley–Terry probability ``σ(β (S₁ − S₂))`` (the expectation preference of §4.3.3,
Christiano et al. 2017). The B-Pref knobs (myopia ``gamma``, ``mistake``, ``skip``,
``equal``) act exactly as for the preference teacher: both share
:func:`~mindgap.teachers.preference.labels_from_scores` and
:class:`~mindgap.teachers.preference.TeacherConfig`.

Choices:

* log T_H is the world's exact ``log_prob`` under the person's params (for the terrain
  worlds :func:`~mindgap.envs.terrain.log_prob_pos` under the person's dynamics table — a
  point-mass probability when the agent did not move, a density per cell² otherwise), as
  for the preference teacher.
* π_H is the SAC policy of :mod:`~mindgap.algorithms.expected_policy`; its density is over
  actions in (−1, 1)^a, the tanh Jacobian included, so that u_H and SAC's policy entropy
  (also over squashed actions) are measured alike and their Jacobian terms cancel in Eq. 4.6.
  On a world with a :class:`~mindgap.envs.interface.Discrete` action space π_H is a discrete
  SAC policy and log π_H the log-probability of the action taken
  (:func:`~mindgap.models.categorical.categorical_log_prob`).
* ``cfg.log_t_floor`` floors each of the two terms per step, so that one step the person
  finds (nearly) impossible cannot decide a comparison alone.
* ``cfg.use_belief=False`` leaves log T_H out: a person who judges the agent's decisions by
  log π_H alone and not how the world responded (the driving study's ablation,
  docs/experiments/driving.md). A person without bias is the same teacher with the true table
  (``belief = world.params``) and the π_H trained under it.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp

from ..data.segments import Segments
from ..envs.interface import Discrete, Env
from ..models.actor import actor_dist
from ..models.categorical import categorical_log_prob, logits
from ..models.mlp import Params
from ..models.squashed import squashed_log_prob
from .preference import TeacherConfig, discounted_sum, labels_from_scores


@partial(jax.tree_util.register_dataclass, data_fields=["belief", "policy"], meta_fields=["env", "cfg"])
@dataclasses.dataclass(frozen=True)
class ExpectationTeacher:
    """The person's model of the agent, as arrays (pass it into jitted code like any pytree).

    Attributes:
        belief: the world's params under the person's dynamics (T_H).
        policy: actor parameters of π_H (:func:`~mindgap.algorithms.sac.actor_dist` reads them).
        env: the world's functions (static: part of the pytree's structure, not a leaf);
            ``env.log_prob`` gives log T_H under ``belief``.
        cfg: how the person answers (static), for :meth:`answer`.
    """

    belief: Any
    policy: Params
    env: Env
    cfg: TeacherConfig = TeacherConfig()

    def answer(self, key: jax.Array, seg_a: Segments, seg_b: Segments):
        """Which of each pair this person finds more expected (:func:`answer` with ``self.cfg``)."""
        return answer(key, seg_a, seg_b, self, self.cfg)


def expected_log_prob(actor: Params, obs: jax.Array, act: jax.Array, discrete: bool = False) -> jax.Array:
    """log π_H(a|s) of the person's expected policy (a tanh-Gaussian density over actions; with
    ``discrete`` a categorical policy's log-probability of the action index): [..., ·] → [...]."""
    if discrete:
        return categorical_log_prob(actor, obs, act)
    mean, log_std = actor_dist(actor, obs)
    return squashed_log_prob(mean, log_std, act)


def step_log_likelihood(
    teacher: ExpectationTeacher, obs, act, next_obs, floor: float, outcomes: bool = True, relative: bool = False
) -> jax.Array:
    """log T_H(s'|s,a) + log π_H(a|s) of single steps, each term floored: obs, next_obs [..., d], act [..., a] → [...].

    ``outcomes=False`` leaves out log T_H: the person judges the agent's decisions and not how the
    world responded to them (the rating model of §2.2.1 read as a comparison). ``relative`` scores a
    decision against the state's most expected one, log π_H(a|s) − max_a' log π_H(a'|s)
    (:class:`~mindgap.teachers.preference.TeacherConfig`; discrete actions only)."""

    discrete = isinstance(teacher.env.action_space, Discrete)
    if relative and not discrete:
        raise ValueError("relative expectation scores need a discrete action space (a most expected action)")

    def one(o, a, o2):
        log_pi = expected_log_prob(teacher.policy, o, a, discrete)
        if relative:
            log_pi = log_pi - jnp.max(logits(teacher.policy, o), -1)
        log_pi = jnp.maximum(log_pi, floor)
        if not outcomes:
            return log_pi
        return jnp.maximum(teacher.env.log_prob(o, a, o2, teacher.belief), floor) + log_pi

    batch = obs.shape[:-1]
    flat = jax.vmap(one)(
        obs.reshape(-1, obs.shape[-1]), act.reshape(-1, act.shape[-1]), next_obs.reshape(-1, next_obs.shape[-1])
    )
    return flat.reshape(batch)


@partial(jax.jit, static_argnames=("cfg",))
def segment_scores(seg: Segments, teacher: ExpectationTeacher, cfg: TeacherConfig) -> jax.Array:
    """The person's score of each segment (how expected it is): seg [K, L, ·] → [K].

    Jitted on its own (the exact densities take seconds to compile), so that host code,
    and :func:`answer` called outside jit, reuse one compiled program per shape.
    """
    per_step = step_log_likelihood(
        teacher, seg.obs, seg.act, seg.next_obs, cfg.log_t_floor, cfg.use_belief, cfg.relative
    )
    return discounted_sum(per_step, seg.mask, cfg.gamma)


def answer(key: jax.Array, seg_a: Segments, seg_b: Segments, teacher: ExpectationTeacher, cfg: TeacherConfig):
    """Which of each pair is more expected: 1 = first, 0 = second, 0.5 = equal; and which were answered.

    Jittable (``cfg`` static) and vmappable over seeds.

    Returns:
        (labels [K] float32, answered [K] bool).
    """
    k = seg_a.mask.shape[0]
    both = segment_scores(jax.tree.map(lambda a, b: jnp.concatenate([a, b]), seg_a, seg_b), teacher, cfg)
    return labels_from_scores(key, both[:k], both[k:], cfg)  # scored in one batch: one compiled density
