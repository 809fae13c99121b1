"""Simulated participants of the coffee-robot study (§2.3.2, Table 2).

A participant has two latent attitudes on the questionnaire's 1–5 scale: ``z₁``, how
likely they think the robot spills the coffee while holding an umbrella (Q1), and
``z₂``, how much they care about the robot getting wet (Q2). Their Likert answers are
the attitudes rounded to the scale; the attitudes themselves set what they believe and
want, with the spread of individuals:

- believed spill probability ``p = spill_at_1 + (spill_at_5 − spill_at_1)(z₁ − 1)/4``
  (clipped to ``[0.01, 0.99]``); every other belief equals the truth;
- reward weights ``w = (w_coffee, −wet_per_point · max(z₂ − 1, 0))``, with
  ``w_coffee ~ N(coffee_weight, coffee_weight_std²)`` (at least 0.5).

An attentive participant rates each demonstration like a :class:`RatingTeacher`
(β = 1, noise σ) and reports it on their own part of the slider: ``low + (high −
low) · r / 10`` rounded to the slider's step (people differ in how they use a scale;
the fit normalises it away). An inattentive one answers and rates uniformly at random
and quickly. The study's filters then apply (§2.3.2): the sanity-check demonstration
must get the lowest rating (ties allowed), the responses must not be all equal, and
the questionnaire must take at least ``min_minutes``.

The defaults of :data:`POPULATIONS` put the mean Likert answers near Table 2 (mobile
2.92 / 2.83, humanoid 3.58 / 3.67): the humanoid is believed clumsier with an umbrella
and its wetting is cared about more, while it truly spills less.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..data.demos import Demonstrations
from ..envs.coffee import ROBOTS, CoffeeParams, coffee_transitions
from ..envs.tabular import TabularMDP
from .rating import RatingTeacher

LIKERT = (1, 5)
QUESTIONS = ("q1", "q2")
"""Q1: how much more likely the robot may spill the coffee while using an umbrella;
Q2: how much the participant cares about the robot being wet (1 lowest, 5 highest)."""


@dataclass(frozen=True)
class Population:
    """How the participants shown one robot type think, answer and rate."""

    robot: str
    """``mobile`` or ``humanoid``."""
    q1_mean: float
    """Mean latent spill attitude ``z₁`` (Likert scale)."""
    q2_mean: float
    """Mean latent care about wetness ``z₂`` (Likert scale)."""
    q1_std: float = 0.8
    """Spread of ``z₁`` between people."""
    q2_std: float = 0.8
    """Spread of ``z₂`` between people."""
    spill_at_1: float = 0.02
    """Believed spill probability of someone at ``z₁ = 1`` ("extremely unlikely")."""
    spill_at_5: float = 0.9
    """Believed spill probability at ``z₁ = 5`` ("extremely likely")."""
    wet_per_point: float = 2.0
    """Wetness penalty per Likert point above 1 ("not care")."""
    coffee_weight: float = 4.0
    """Mean weight of "user has coffee"."""
    coffee_weight_std: float = 0.5
    """Its spread between people."""
    rating_noise: float = 0.5
    """``σ`` of an attentive participant's ratings."""
    slider_step: float = 1.0
    """Resolution of the rating slider (0 for continuous ratings)."""
    slider_low: tuple[float, float] = (0.0, 1.5)
    """Range of the lowest slider position a participant uses."""
    slider_high: tuple[float, float] = (8.5, 10.0)
    """Range of the highest slider position a participant uses."""
    inattentive: float = 0.35
    """Share of recruits who answer at random."""
    minutes_attentive: float = 7.0
    """Median minutes an attentive participant spends (log-normal, σ 0.35)."""
    minutes_inattentive: float = 2.5
    """Median minutes an inattentive one spends (log-normal, σ 0.4)."""

    def __post_init__(self):
        if self.robot not in ROBOTS:
            raise ValueError(f"unknown robot type {self.robot!r}: use one of {', '.join(ROBOTS)}")
        if not 0.0 <= self.inattentive < 1.0:
            raise ValueError("inattentive must lie in [0, 1)")
        if min(self.q1_std, self.q2_std, self.rating_noise, self.slider_step, self.coffee_weight_std) < 0:
            raise ValueError("spreads, noise and slider step must be non-negative")
        for name in ("spill_at_1", "spill_at_5"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a probability")
        lo, hi = self.slider_low, self.slider_high
        if not (0.0 <= lo[0] <= lo[1] < hi[0] <= hi[1] <= 10.0):
            raise ValueError("need 0 <= slider_low <= slider_high <= 10 with the low range below the high one")


POPULATIONS = {
    "mobile": Population("mobile", q1_mean=2.92, q2_mean=2.83),
    "humanoid": Population("humanoid", q1_mean=3.58, q2_mean=3.67),
}


@dataclass(frozen=True)
class Participant:
    """One simulated participant: answers, true belief and reward, rating habits.

    For an inattentive participant the belief and weights are NaN (they have none).
    """

    pid: str
    robot: str
    attentive: bool
    q1: int
    q2: int
    spill: float
    """Believed spill probability (holding coffee and umbrella)."""
    coffee_weight: float
    wet_weight: float
    """Weight of "robot wet" (≤ 0; the wetness penalty is its negative)."""
    slider: tuple[float, float]
    minutes: float

    @property
    def weights(self) -> np.ndarray:
        return np.array([self.coffee_weight, self.wet_weight], np.float32)

    def belief(self) -> np.ndarray:
        """``[64, 4, 64]`` the participant's believed dynamics."""
        return coffee_transitions(CoffeeParams(spill=self.spill))

    def teacher(self, mdp: TabularMDP, noise: float = 0.5) -> RatingTeacher:
        """The rater inside an attentive participant (true world ``mdp``)."""
        if not self.attentive:
            raise ValueError(f"participant {self.pid} is inattentive: they rate at random, not by a model")
        return RatingTeacher(mdp, jnp.asarray(self.weights), jnp.asarray(self.belief(), jnp.float32), noise=noise)


def _likert(z) -> int:
    return int(np.clip(np.round(z), *LIKERT))


@jax.jit
def _draws(key):
    """All the random numbers of one recruit in one call: uniforms, normals, random Likert answers."""
    k_u, k_z, k_q = jax.random.split(key, 3)
    return (
        jax.random.uniform(k_u, (3,)),
        jax.random.normal(k_z, (4,)),
        jax.random.randint(k_q, (2,), LIKERT[0], LIKERT[1] + 1),
    )


def sample_participant(key, pop: Population, pid: str) -> Participant:
    """Draw one recruit of ``pop`` (attentive or not)."""
    u, z, answers = (np.asarray(x) for x in _draws(key))
    attentive = bool(u[0] >= pop.inattentive)
    slider = (
        float(pop.slider_low[0] + u[1] * (pop.slider_low[1] - pop.slider_low[0])),
        float(pop.slider_high[0] + u[2] * (pop.slider_high[1] - pop.slider_high[0])),
    )
    if not attentive:
        minutes = float(pop.minutes_inattentive * np.exp(0.4 * z[3]))
        nan = float("nan")
        return Participant(pid, pop.robot, False, int(answers[0]), int(answers[1]), nan, nan, nan, slider, minutes)
    z1 = pop.q1_mean + pop.q1_std * z[0]
    z2 = pop.q2_mean + pop.q2_std * z[1]
    spill = pop.spill_at_1 + (pop.spill_at_5 - pop.spill_at_1) * (z1 - 1.0) / 4.0
    return Participant(
        pid,
        pop.robot,
        True,
        _likert(z1),
        _likert(z2),
        float(np.clip(spill, 0.01, 0.99)),
        float(max(pop.coffee_weight + pop.coffee_weight_std * z[2], 0.5)),
        float(-pop.wet_per_point * max(z2 - 1.0, 0.0)),
        slider,
        float(pop.minutes_attentive * np.exp(0.35 * z[3])),
    )


def respond(key, participant: Participant, pop: Population, mdp: TabularMDP, demos: Demonstrations) -> np.ndarray:
    """The participant's slider ratings ``[N]`` in ``[0, 10]`` of ``demos`` shown in the world ``mdp``."""
    if participant.attentive:
        rated = participant.teacher(mdp, pop.rating_noise).rate(key, demos)
        r = np.asarray(rated.ratings, np.float64)
        low, high = participant.slider
        r = low + (high - low) * r / 10.0
    else:
        r = np.asarray(jax.random.uniform(key, (demos.count,), minval=0.0, maxval=10.0), np.float64)
    if pop.slider_step > 0:
        r = np.round(r / pop.slider_step) * pop.slider_step
    return np.clip(r, 0.0, 10.0)


def screen(ratings, minutes: float, sanity: int, *, min_minutes: float = 3.0) -> str:
    """Why a response is dropped by the study's filters, or ``""`` when it is valid.

    Args:
        ratings: ``[N]`` the participant's ratings.
        minutes: time spent on the study.
        sanity: index of the sanity-check demonstration (random actions).
        min_minutes: shortest credible response time (3 min in §2.3.2).
    """
    r = np.asarray(ratings, np.float64)
    if minutes < min_minutes:
        return f"too fast ({minutes:.1f} min < {min_minutes:g})"
    if np.ptp(r) == 0:
        return "every demonstration got the same rating"
    if r[sanity] > np.delete(r, sanity).min():
        return "failed the sanity check (random demonstration not rated lowest)"
    return ""


@dataclass(frozen=True)
class Response:
    """A recruit's questionnaire answers and ratings, and whether the filters kept it."""

    participant: Participant
    ratings: np.ndarray
    dropped: str
    """Why the filters dropped it (empty when valid)."""

    @property
    def valid(self) -> bool:
        return not self.dropped


def recruit(
    key,
    pop: Population,
    mdp: TabularMDP,
    demos: Demonstrations,
    n_valid: int,
    *,
    sanity: int,
    min_minutes: float = 3.0,
    max_recruits: int = 500,
) -> list[Response]:
    """Recruit participants one by one until ``n_valid`` pass the filters (as on MTurk).

    Returns every recruit's response, valid or not, in recruiting order; participant
    ids are ``<robot>-<k>``.

    Raises:
        RuntimeError: when ``max_recruits`` recruits do not yield ``n_valid`` valid ones.
    """
    out: list[Response] = []
    n_ok = 0
    for k in range(max_recruits):
        if n_ok == n_valid:
            break
        k_who, k_rate = jax.random.split(jax.random.fold_in(key, k))
        person = sample_participant(k_who, pop, f"{pop.robot}-{k + 1:02d}")
        ratings = respond(k_rate, person, pop, mdp, demos)
        why = screen(ratings, person.minutes, sanity, min_minutes=min_minutes)
        out.append(Response(person, ratings, why))
        n_ok += not why
    if n_ok < n_valid:
        raise RuntimeError(
            f"only {n_ok} of {max_recruits} {pop.robot} recruits passed the filters; "
            f"need {n_valid} (lower the inattentive share or raise max_recruits)"
        )
    return out
