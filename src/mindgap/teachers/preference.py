"""The simulated person who compares two segments (§3.3.3.2, Eqs. 3.4–3.5, B-Pref's knobs).

The person scores a segment by ``Σ_t γ^{L−1−t} [r_H(s_t, a_t, s_{t+1}) + log T_H(s_{t+1} | s_t, a_t)]``
— what they want plus how plausible each step looks under their belief — and prefers
the higher score with Bradley–Terry probability ``σ(β (S₁ − S₂))``. The B-Pref knobs
(Lee et al. 2021b) make the answers less than ideal: ``gamma`` (myopia), ``mistake``
(flip probability), ``skip`` and ``equal`` thresholds. With ``belief=None`` the log T_H
term is off and this is the ordinary B-Pref teacher.

Only the real steps of a segment (``mask``) count. The absorbing steps after a terminal
transition (:class:`~mindgap.data.segments.AbsorbingSegments`; Kostrikov et al. 2019)
add nothing: after the goal or a pit the true reward is 0 and nothing moves, so there is
no log T_H term either — the person judges the episode that happened, while the learner
models the same steps with its absorbing-state reward.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp

from ..data.segments import Segments
from ..envs.interface import Env


@dataclasses.dataclass(frozen=True)
class TeacherConfig:
    """How the simulated person answers (hashable: it is a static argument of jitted code)."""

    beta: float | None = 1.0
    """Rationality of Bradley–Terry (Eq. 3.4: P(σ₁ ≻ σ₂) = sigmoid(β (S₁ − S₂))). None answers
    deterministically (B-Pref's oracle), under which the scale of the score is not identified:
    a learner can match hard labels with any score scaled up, so the belief's level is lost
    (docs/experiments/identifiability.md)."""
    gamma: float = 1.0
    """Myopic discount: step t of L counts γ^(L−1−t)."""
    mistake: float = 0.0
    """Probability of flipping an answer."""
    skip: float = 0.0
    """Skip a query when both scores are below skip × (largest |score| in the batch); 0 never skips."""
    equal: float = 0.0
    """Answer "equal" (label 0.5) when |S₁ − S₂| < equal × (largest |score| in the batch)."""
    log_t_floor: float = -20.0
    """Per-step floor on log T_H, so one step that looks impossible cannot decide alone."""
    use_belief: bool = True
    """Include the log T_H term (False: the ordinary B-Pref teacher; for an expectation teacher, one who
    judges the agent's decisions by log π_H alone)."""
    relative: bool = False
    """An expectation teacher scores each decision against the most expected one in its state,
    log π_H(a|s) − max_a' log π_H(a'|s) (0 for the decision they expected, whatever the state), instead
    of log π_H(a|s), which also says how sure they are of the state's decision: a comparison of segments
    from different states then favours the states where the person is sure. Discrete actions only."""


@partial(jax.jit, static_argnames=("env", "cfg"))
def segment_scores(seg: Segments, env: Env, world_params, belief_params, cfg: TeacherConfig) -> jax.Array:
    """The person's score of each segment. seg [K, L, ·] → [K]; absorbing steps score 0.

    r_H is ``env.reward`` under ``world_params``; log T_H is ``env.log_prob`` under ``belief_params``.
    An env without a reward function (a user's gymnasium env) is scored by the rewards it
    returned, ``seg.env_reward``, as B-Pref's scripted teacher scores segments; only the
    ordinary teacher (no belief) can be.
    Jitted: called outside a jitted program (a world check, a host teacher), op by op it compiled
    each of the dynamics' branches again on every call.
    """
    if env.reward is None:
        if seg.env_reward is None or (belief_params is not None and cfg.use_belief):
            raise ValueError(
                "a person without the env's reward function scores only segments cut from a buffer, by r alone"
            )
        return discounted_sum(seg.env_reward, seg.mask, cfg.gamma)

    def step_score(o, a, o2):
        r = env.reward(o, a, o2, world_params)
        if belief_params is not None and cfg.use_belief:
            r = r + jnp.maximum(env.log_prob(o, a, o2, belief_params), cfg.log_t_floor)
        return r

    per_step = jax.vmap(jax.vmap(step_score))(seg.obs, seg.act, seg.next_obs)  # [K, L]
    return discounted_sum(per_step, seg.mask, cfg.gamma)


def discounted_sum(per_step: jax.Array, mask: jax.Array, gamma: float) -> jax.Array:
    """Myopic segment score ``Σ_t γ^{L−1−t} x_t`` over the real steps: per_step, mask [K, L] → [K]."""
    length = mask.shape[-1]
    weights = gamma ** jnp.arange(length - 1, -1, -1, dtype=jnp.float32)
    return jnp.sum(jnp.where(mask, per_step, 0.0) * weights, axis=-1)


def answer(key: jax.Array, seg_a: Segments, seg_b: Segments, env: Env, world_params, belief_params, cfg: TeacherConfig):
    """Labels for K queries: 1 = first preferred, 0 = second, 0.5 = equal; and which were answered.

    Returns:
        (labels [K] float32, answered [K] bool).
    """
    sa = segment_scores(seg_a, env, world_params, belief_params, cfg)
    sb = segment_scores(seg_b, env, world_params, belief_params, cfg)
    return labels_from_scores(key, sa, sb, cfg)


def labels_from_scores(key: jax.Array, sa: jax.Array, sb: jax.Array, cfg: TeacherConfig):
    """Bradley–Terry answers with B-Pref's knobs, given the person's scores of both sides ([K] each).

    Shared by every simulated person that compares segments by a score (this module's and
    :mod:`~mindgap.teachers.expectation`); ``cfg.gamma`` is applied when scoring.

    Returns:
        (labels [K] float32, answered [K] bool).
    """
    k_bt, k_mistake = jax.random.split(key)
    scale = jnp.max(jnp.abs(jnp.concatenate([sa, sb])))
    answered = jnp.ones(sa.shape, bool)
    if cfg.skip > 0:
        answered = jnp.maximum(sa, sb) >= cfg.skip * scale
    if cfg.beta is None:
        labels = jnp.where(sa == sb, 0.5, (sa > sb).astype(jnp.float32))
    else:
        p = jax.nn.sigmoid(cfg.beta * (sa - sb))
        labels = jax.random.bernoulli(k_bt, p).astype(jnp.float32)
    if cfg.mistake > 0:
        flip = jax.random.bernoulli(k_mistake, cfg.mistake, labels.shape)
        labels = jnp.where(flip, 1.0 - labels, labels)
    if cfg.equal > 0:
        labels = jnp.where(jnp.abs(sa - sb) < cfg.equal * scale, 0.5, labels)
    return labels, answered


@partial(jax.tree_util.register_dataclass, data_fields=["world", "belief"], meta_fields=["env", "cfg"])
@dataclasses.dataclass(frozen=True)
class PreferenceTeacher:
    """The simulated person as a value the engine passes into its compiled programs.

    Attributes:
        world: the true world's params (r_H is ``env.reward`` under them).
        belief: params of the person's believed dynamics (log T_H is ``env.log_prob`` under
            them), or None for the ordinary B-Pref teacher.
        env: the world's functions (static).
        cfg: how the person answers (static).
    """

    world: Any
    belief: Any
    env: Env
    cfg: TeacherConfig

    def answer(self, key: jax.Array, seg_a: Segments, seg_b: Segments):
        """:func:`answer` of this person: (labels [K], answered [K])."""
        return answer(key, seg_a, seg_b, self.env, self.world, self.belief, self.cfg)
