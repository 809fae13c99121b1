"""Simulated participants of the driving study (§4.4.2, Figs. 32–36, Table 5).

A participant of the training phase

* **answers the importance questions** of Fig. 32 (1 "NOT care" … 5 "Strongly care") for the
  four factors, in :data:`~mindgap.envs.driving.FEATURES` order: a latent importance per
  factor, the study's average plus a normal spread between people (``importance_std``),
  rounded to the scale. Their reward weights are their own answers normalised
  (:func:`~mindgap.envs.driving.importance_weights`), so people differ as their answers do;
  r_A, the engineered reward, is the same map of the valid participants' *average* answers.
* **believes** a braking car on sleet slows as on a dry road with probability ``biased``
  (the availability bias; 12 of the 14 valid participants of the study), else knows the
  sleet: their T_H is the world at sleet 0 or at the true sleet level.
* **expects** the agent to act by π_H, soft-optimal for their reward r_H under their belief
  (discrete SAC in the world as they imagine it; trained by the experiment,
  :mod:`~mindgap.experiments.driving`), and **answers expectation queries** by Bradley–Terry
  on how expected the clip's *decisions* look when the participant plays them out in the world
  they believe in (``rollout=True``, the study's default, with or without charging a crash their
  rollout does not reproduce: :mod:`~mindgap.teachers.believed_rollout`), or on
  Σ_t [log T_H + log π_H] at the clip's own
  states — the identifiable protocol (docs/experiments/identifiability.md), exactly
  :mod:`~mindgap.teachers.expectation`'s person — kept as an option (:class:`CrowdTeacher`
  asks one participant per query).

The participants' reward r_H (:func:`participant_reward`) reads two of Fig. 32's questions as
they were put to them. The fourth, "how important is **staying on the same lane**": a feature
that is 1 in the lane the car started in and falls to 0 one lane away. The engineered r_A keeps
the scenario's "lane following" (the offset from the nearest lane's centre, the text's name for
the factor). The difference is the study's own finding (§4.4.2.1): the importance ratings,
as engineered into r_A, "should have led to preferring the steering behavior", yet the
participants expected braking. With r_A's lane following in r_H a person on a dry road would
expect a lane change (measured: docs/experiments/driving.md), which the study did not see.
The second, "**distance with front car**", reads as the distance to the blue car the clips show
(Fig. 33 shows exactly one other car; :func:`distance_to_front_car`), whatever lane the car is
in, rather than r_A's gap to whichever car is ahead in the ego's lane, which jumps to its best
the moment the car leaves the lane. This reading is chosen to agree with a fact about the
study's *training participants* — they "preferred to brake than steer in general"
(§4.4.2.1) — and not with any learner's result; its effect on the scripted policies is measured
in docs/experiments/driving.md.

**Inattentive** recruits (``inattentive``) answer every question at random. The sanity
item of the study is a collision shown against a car that brakes in time (:func:`sanity_fails`):
a participant who finds the collision more expected fails and is dropped. The two episodes
differ in length (the collision ends its episode), so the item compares how expected each
looks *per step* (:func:`per_step_scores`), as the testing phase's ratings do: a sum of
log-likelihoods over unequal lengths favours the episode that ends first, and made most
attentive recruits fail (measured: docs/experiments/driving.md).

**Testing phase** (:func:`rate_rollouts`): *new* participants, drawn the same way, rate each
rollout 1–10 by how expected it looks — the rating model of §2.2.1 on the study's 1–10
scale: ``1 + 9 · (Π_t π_H(a_t|ŝ_t))^{1/n}`` plus normal noise (``rating_noise``), rounded
and clipped; an inattentive rater rates uniformly at random. The rating is of the car's
decisions (the geometric mean probability π_H gives them), played out in the rater's believed
world with a crash they did not expect charged as in their answers
(:mod:`~mindgap.teachers.believed_rollout`), or at the rollout's own states (ŝ_t = s_t) when
the study answers by states.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..data.segments import Segments
from ..envs.driving import FEATURES, STUDY_IMPORTANCE, importance_weights
from ..envs.driving.params import LANE_WIDTH, LENGTH, DrivingParams
from ..envs.driving.reward import combine, features
from ..envs.driving.sleet import braked_speed, log_prob_speed
from ..envs.driving.world import decode
from ..envs.interface import Env
from ..models.categorical import categorical_log_prob
from ..models.mlp import Params
from .believed_rollout import believed_per_step, believed_scores, whole_clip_scores
from .expectation import ExpectationTeacher, segment_scores
from .preference import TeacherConfig, labels_from_scores

LIKERT = (1, 5)
RATING = (1, 10)


@dataclasses.dataclass(frozen=True)
class DriverPopulation:
    """How the recruits of the driving study think, answer and rate."""

    importance_mean: tuple[float, ...] = STUDY_IMPORTANCE
    """Mean latent importance of each factor (Fig. 32's averages: 3.42, 4.57, 3.28, 3.78)."""
    importance_std: float = 0.8
    """Spread of a factor's latent importance between people (Likert points)."""
    biased: float = 12 / 14
    """Share who believe braking on sleet works as on a dry road (12 of 14 in the study)."""
    inattentive: float = 0.1
    """Share of recruits who answer at random (1 of 15 failed the study's sanity check)."""
    rating_noise: float = 1.0
    """σ of a testing-phase rating, in points of the 1–10 scale."""

    def __post_init__(self):
        m = np.asarray(self.importance_mean, np.float64)
        if m.shape != (len(FEATURES),) or np.any((m < LIKERT[0]) | (m > LIKERT[1])):
            raise ValueError(f"importance_mean must be {len(FEATURES)} ratings in [1, 5], got {self.importance_mean}")
        for name in ("biased", "inattentive"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a share in [0, 1], got {getattr(self, name)}")
        if self.inattentive >= 1.0:
            raise ValueError("inattentive must be below 1: someone has to pay attention")
        if self.importance_std < 0 or self.rating_noise < 0:
            raise ValueError("importance_std and rating_noise must be non-negative")


@dataclasses.dataclass(frozen=True)
class Driver:
    """One recruit: their answers, what they believe and want, and whether they pay attention.

    For an inattentive recruit ``importance`` holds random answers and ``weights`` and
    ``believed_sleet`` are what those answers and a random belief would give; they are not
    used to answer anything.
    """

    pid: str
    attentive: bool
    importance: tuple[int, ...]
    """Their answers to Fig. 32's four questions (1–5)."""
    believed_sleet: float
    """The sleet level of their belief T_H: 0 (the availability bias) or the true level."""

    @property
    def weights(self) -> np.ndarray:
        """[4] their reward weights: their answers normalised."""
        return importance_weights(self.importance)

    @property
    def biased(self) -> bool:
        return self.believed_sleet == 0.0


def check_sleet_level(sleet) -> float:
    """``sleet`` as a float in [0, 1], or one clear line."""
    s = float(sleet)
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"sleet must be in [0, 1] (0 a dry road, 1 full sleet), got {sleet}")
    return s


def sample_driver(key, pop: DriverPopulation, pid: str, true_sleet: float) -> Driver:
    """Draw one recruit of ``pop`` on a road at ``true_sleet``."""
    k_att, k_imp, k_bias, k_rand = jax.random.split(key, 4)
    attentive = bool(jax.random.uniform(k_att) >= pop.inattentive)
    if attentive:
        z = np.asarray(pop.importance_mean) + pop.importance_std * np.asarray(jax.random.normal(k_imp, (4,)))
        answers = np.clip(np.round(z), *LIKERT).astype(int)
    else:
        answers = np.asarray(jax.random.randint(k_rand, (4,), LIKERT[0], LIKERT[1] + 1))
    biased = bool(jax.random.uniform(k_bias) < pop.biased)
    return Driver(pid, attentive, tuple(int(a) for a in answers), 0.0 if biased else float(true_sleet))


def engineered_weights(drivers) -> np.ndarray:
    """r_A's weights: the map of the drivers' *average* importance answers (§4.4.2: "linearly combined")."""
    if not drivers:
        raise ValueError("no participant to engineer r_A from")
    return importance_weights(np.mean([d.importance for d in drivers], 0))


# ---------------------------------------------------------------------------------------
# the participant's reward and expected policy


class RewardH(NamedTuple):
    """A participant's reward r_H (:func:`participant_reward` reads it): their weights and the world's
    reward params (scales, collision penalty, start lane)."""

    weights: jax.Array
    world: DrivingParams


def stay_in_lane(y, start_lane) -> jax.Array:
    """Fig. 32's "staying on the same lane": 1 in the start lane, falling linearly to 0 one lane away."""
    return 1.0 - jnp.clip(jnp.abs(y - LANE_WIDTH * start_lane.astype(jnp.float32)) / LANE_WIDTH, 0.0, 1.0)


def distance_to_front_car(n: dict, rw) -> jax.Array:
    """Fig. 32's "distance with front car" read as the distance to *the* front car, the blue car of
    Fig. 33, in whatever lane either is: its bumper gap over the desired gap (r_A's scale), clipped to
    [0, 1]; 0 while beside it; 1 once it is behind. ``n`` is :func:`~mindgap.envs.driving.world.decode`'s."""
    dx = n["others_dx"][0]
    desired = rw.standstill + rw.headway * jnp.maximum(n["speed"], 0.0)
    return jnp.where(dx > 0, jnp.clip((dx - LENGTH) / desired, 0.0, 1.0), 1.0)


def participant_features(next_obs: jax.Array, params: DrivingParams) -> jax.Array:
    """[4] the features a participant rates a step by: r_A's speed and relative speed,
    :func:`distance_to_front_car` and :func:`stay_in_lane` (module docstring)."""
    n = decode(next_obs, params)
    phi = features(n["y"], n["heading"], n["speed"], n["others_dx"], n["others_y"], n["others_speed"], params.rewards)
    phi = phi.at[1].set(distance_to_front_car(n, params.rewards))
    return phi.at[3].set(stay_in_lane(n["y"], params.start_lane))


def participant_reward(p: RewardH, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """r_H of transitions [B, ·] → [B] (a ``reward_fn`` of the SAC loop; module docstring)."""
    del obs, act

    def one(o2):
        crashed = decode(o2, p.world)["crashed"]
        rw = p.world.rewards._replace(weights=p.weights)
        return combine(participant_features(o2, p.world), crashed, rw)

    return jax.vmap(one)(next_obs)


# ---------------------------------------------------------------------------------------
# answering queries


@partial(
    jax.tree_util.register_dataclass,
    data_fields=["beliefs", "policies", "attentive"],
    meta_fields=["env", "cfg", "rollout", "crash", "whole_clip"],
)
@dataclasses.dataclass(frozen=True)
class CrowdTeacher:
    """The valid participants of the training phase as one jittable teacher.

    Each query goes to one participant drawn uniformly; an attentive one answers by
    Bradley–Terry on their score of the two clips — with ``rollout``, the clip's decisions played
    out in their believed world (:mod:`~mindgap.teachers.believed_rollout`), else as
    :class:`~mindgap.teachers.expectation.ExpectationTeacher` (Σ log T_H + log π_H under their
    own belief and π_H) — and an inattentive one (who passed the sanity item by luck) at random.

    Attributes:
        beliefs: the world's params under each participant's belief (leading axis P).
        policies: their π_H actors (categorical; leading axis P).
        attentive: [P] bool.
        env: the world's functions (static).
        cfg: how they answer (static).
    """

    beliefs: Any
    policies: Params
    attentive: jax.Array
    env: Env
    cfg: TeacherConfig = TeacherConfig()
    rollout: bool = False
    """Score a clip by its decisions played out in the believed world
    (:func:`~mindgap.teachers.believed_rollout.believed_scores`) instead of Σ log T_H + log π_H
    at its own states."""
    crash: bool = True
    """With ``rollout``: charge a crash the participant's rollout does not reproduce."""
    whole_clip: bool = True
    """Judge a clip that ends early (a crash) at the rate of the decisions it shows, over the clip's
    whole length (:func:`~mindgap.teachers.believed_rollout.whole_clip_scores`); False: the plain sum
    over its steps, which favours a clip for ending sooner."""

    @property
    def size(self) -> int:
        return int(self.attentive.shape[0])

    def scores(self, seg: Segments) -> jax.Array:
        """Every participant's score of each segment: [P, K]."""

        def one(belief, policy):
            if self.rollout:
                return believed_scores(seg, policy, belief, self.cfg, self.crash, self.whole_clip)
            score = segment_scores(seg, ExpectationTeacher(belief, policy, self.env), self.cfg)
            if self.whole_clip:
                score = whole_clip_scores(score, (seg.mask > 0).sum(-1), seg.mask.shape[-1])
            return score

        return jax.vmap(one)(self.beliefs, self.policies)

    def answer(self, key: jax.Array, seg_a: Segments, seg_b: Segments):
        """(labels [K], answered [K]): which of each pair is more expected, one participant per query."""
        k_who, k_bt, k_rand = jax.random.split(key, 3)
        k = seg_a.mask.shape[0]
        who = jax.random.randint(k_who, (k,), 0, self.attentive.shape[0])
        both = self.scores(jax.tree.map(lambda a, b: jnp.concatenate([a, b]), seg_a, seg_b))  # [P, 2K]
        mine = both[who, jnp.arange(k)], both[who, k + jnp.arange(k)]
        labels, answered = labels_from_scores(k_bt, *mine, self.cfg)
        random = jax.random.bernoulli(k_rand, 0.5, (k,)).astype(jnp.float32)
        return jnp.where(self.attentive[who], labels, random), answered


def prefers_first(key, scores_a: jax.Array, scores_b: jax.Array, attentive: bool, cfg: TeacherConfig) -> bool:
    """One participant's answer to one query from their two scores (random when inattentive)."""
    if not attentive:
        return bool(jax.random.bernoulli(key, 0.5))
    label, _ = labels_from_scores(key, jnp.atleast_1d(scores_a), jnp.atleast_1d(scores_b), cfg)
    return bool(label[0] > 0.5)


def per_step_scores(seg: Segments, teacher: ExpectationTeacher, cfg: TeacherConfig) -> jax.Array:
    """How expected each episode looks per step it lasted: Σ_t [log T_H + log π_H] / (its steps), [K]."""
    return segment_scores(seg, teacher, cfg) / jnp.maximum(seg.mask.sum(-1), 1)


def reward_sums(seg: Segments, reward: RewardH) -> jax.Array:
    """How much a participant likes each segment: Σ_t r_H over the steps that happened, [K].

    r_H reads the states steps reach only, so ``seg.obs`` and ``seg.act`` may be None."""
    k, n = seg.mask.shape
    r = participant_reward(reward, None, None, seg.next_obs.reshape(k * n, -1)).reshape(k, n)
    return jnp.sum(jnp.where(seg.mask > 0, r, 0.0), -1)


def sanity_fails(key, collision_score, safe_score, attentive: bool, cfg: TeacherConfig) -> bool:
    """The study's sanity item: the participant picks the collision over braking in time (Bradley–Terry on
    the two clips' scores: :func:`per_step_scores`, or :func:`reward_sums` for a preference item)."""
    return prefers_first(key, collision_score, safe_score, attentive, cfg)


def bias_answer(key, believed_sleet: float, attentive: bool, params: DrivingParams, beta: float = 1.0) -> bool:
    """The bias-validation question (§4.4.2): shown, on a sleety day, a braking step that slows as on a
    dry road and one that slows at full sleet's typical grip, does the participant pick the first as
    the more expected? Chosen by Bradley–Terry on log T_H of the two outcomes under their belief."""
    if not attentive:
        return bool(jax.random.bernoulli(key, 0.5))
    v, target = jnp.float32(25.0), jnp.float32(20.0)
    g = params.grip
    outcomes = [braked_speed(v, target, m) for m in (g.dry_mean, g.sleet_mean)]
    lp = [log_prob_speed(v, target, o, jnp.float32(believed_sleet), g) for o in outcomes]
    p = jax.nn.sigmoid(beta * jnp.clip(lp[0] - lp[1], -50.0, 50.0))
    return bool(jax.random.bernoulli(key, p))


# ---------------------------------------------------------------------------------------
# the testing phase


def expectedness(policy: Params, obs: jax.Array, act: jax.Array, alive: jax.Array) -> jax.Array:
    """(Π_t π_H(a_t|s_t))^{1/n} over the steps that happened: obs [T, d], act [T, 1], alive [T] → []."""
    lp = categorical_log_prob(policy, obs, act)
    n = jnp.maximum(alive.sum(), 1)
    return jnp.exp(jnp.sum(jnp.where(alive, lp, 0.0)) / n)


def rate_rollouts(
    key,
    policy: Params,
    attentive: bool,
    obs,
    act,
    alive,
    noise: float,
    belief=None,
    cfg: TeacherConfig = TeacherConfig(),
    crash: bool = True,
) -> np.ndarray:
    """One rater's 1–10 ratings of rollouts ``obs [R, T+1, d]``, ``act [R, T, 1]``, ``alive [R, T]`` (module docstring).

    With ``belief`` (the world's params as the rater believes it) the decisions are played out in
    that world, exp(S_i / n) of :mod:`~mindgap.teachers.believed_rollout` (with ``crash``, a crash the
    rater did not expect charged); without, the geometric mean of π_H at the rollout's own states."""
    k_noise, k_rand = jax.random.split(key)
    r = obs.shape[0]
    if not attentive:
        return np.asarray(jax.random.randint(k_rand, (r,), RATING[0], RATING[1] + 1), np.float64)
    if belief is not None:
        seg = Segments(obs[:, :-1], act, obs[:, 1:], alive.astype(jnp.float32))
        e = jnp.exp(believed_per_step(seg, policy, belief, cfg, crash))
    else:
        e = jax.vmap(lambda o, a, m: expectedness(policy, o, a, m))(obs[:, :-1], act, alive)
    mean = RATING[0] + (RATING[1] - RATING[0]) * e
    noisy = mean + noise * jax.random.normal(k_noise, (r,))
    return np.clip(np.round(np.asarray(noisy, np.float64)), *RATING)


def rating_fails(ratings: np.ndarray, sanity: int) -> str:
    """Why a testing-phase response is dropped ("" when valid): the collision rollout (index
    ``sanity``) not rated lowest (ties allowed), or every rollout rated the same."""
    r = np.asarray(ratings, np.float64)
    if np.ptp(r) == 0:
        return "every rollout got the same rating"
    if r[sanity] > np.delete(r, sanity).min():
        return "failed the sanity check (the collision not rated lowest)"
    return ""
