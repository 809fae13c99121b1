"""PEBBLE, DRLHP and the SAC oracle as learners of the engine (:mod:`~mindgap.algorithms.engine`).

* ``sac`` ("the oracle") asks nobody and optimises the world's own reward;
* ``pebble`` (Lee et al. 2021): state-entropy pre-training for ``explore_steps`` with a critic
  reset after it, then a reward ensemble (:mod:`~mindgap.models.reward_ensemble`) learned from
  preferences with uncertainty sampling, the buffer relabelled after every round;
* ``drlhp`` (Christiano et al. 2017): the same without pre-training or critic reset; its
  policy optimiser is SAC here (the original used A2C/TRPO) so that all methods differ only
  in how they learn the reward.

``absorbing`` gives the learned reward absorbing states (Kostrikov et al. 2019,
"Discriminator-Actor-Critic"): segments keep the steps after a goal or pit as absorbing
steps, each ensemble member learns their reward ``r_abs``, and the buffer's terminal
transitions carry the absorbing state's value ``γ r_abs / (1 − γ)``. Without it a learned
reward suffers termination bias: segments that reach the goal are cut short, their learned
return is a sum of fewer bounded rewards, the critic values the end of an episode at 0, and
the agent learns to hover next to the goal rather than enter it. ``absorbing_state`` picks
DAC's single absorbing state (``single``) or one per terminal state (``terminal``, the
default: goals and pits must not share one; see :mod:`~mindgap.models.reward_ensemble`).
"""

from __future__ import annotations

import dataclasses
from functools import partial
from pathlib import Path

import jax

from ..envs.gym_world import NO_BELIEF, GymWorld
from ..envs.interface import Env, action_width
from ..feedback.queries import check_sampler, select_queries
from ..models.reward_ensemble import (
    ABSORBING_STATES,
    RewardConfig,
    RewardState,
    absorbing_reward,
    ensemble_reward,
    preference_probs,
    reward_init,
    train_reward,
)
from ..teachers.host import HostTeacher
from .engine import FAST_SCHEDULE as FAST_SCHEDULE
from .engine import Learner, Schedule, preference_teacher

METHODS = ("sac", "pebble", "drlhp")
ABSORBING_DEFAULT = {"sac": False, "pebble": True, "drlhp": False}
"""Whether each method's preset (:func:`method_config`) gives the learned reward absorbing states:
on for PEBBLE, off for DRLHP (not measured with them). The measurements behind it:
docs/experiments/pbrl.md, "Absorbing states on d1".
"""


@dataclasses.dataclass(frozen=True)
class PbRLConfig(Schedule):
    """One run of the engine (all seeds share it): ``method`` sac (oracle on the true reward), pebble or drlhp."""

    reward: RewardConfig = RewardConfig()
    """The reward ensemble."""
    sampler: str = "disagreement"
    """uniform, disagreement or entropy."""
    candidates: int = 10
    """Pairs drawn per query kept (score-based samplers)."""
    absorbing: bool = False
    """Absorbing-state treatment of terminals for the learned reward (Kostrikov et al. 2019; not for sac)."""
    absorbing_state: str = "terminal"
    """With ``absorbing``: ``terminal`` (one absorbing state per terminal state) or ``single`` (DAC's one)."""

    def check(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r}: choose from {', '.join(METHODS)}")
        check_sampler(self.sampler, belief=False)
        self.check_schedule()
        if self.method != "sac" and (self.queries < 1 or self.per_round < 1):
            raise ValueError("queries and per_round must be at least 1")
        if self.method == "sac" and self.absorbing:
            raise ValueError("absorbing applies to a learned reward (pebble, drlhp), not to sac")
        if self.absorbing_state not in ABSORBING_STATES:
            raise ValueError(
                f"absorbing_state must be one of {', '.join(ABSORBING_STATES)}, got {self.absorbing_state!r}"
            )

    def as_dict(self) -> dict:
        """The run record's config; the absorbing fields only when on, so run folders from before them still resume."""
        d = super().as_dict()
        if not self.absorbing:
            del d["absorbing"], d["absorbing_state"]
        return d

    def absorbing_heads(self) -> str | None:
        """The ``absorbing`` argument of :func:`~mindgap.models.reward_ensemble.reward_init`."""
        return self.absorbing_state if self.absorbing else None

    def absorbing_fn(self):
        """The ``absorbing_fn`` of relabel and run_chunk: r_abs of the ensemble mean, or None."""
        return absorbing_reward if self.absorbing else None


def method_config(method: str, **overrides) -> PbRLConfig:
    """The defaults of each method, with ``overrides`` applied."""
    base = {
        "sac": dict(method="sac", queries=0),
        "pebble": dict(method="pebble", explore_steps=4000, reset_critic=True, sampler="disagreement"),
        "drlhp": dict(method="drlhp", sampler="disagreement"),
    }
    if method not in base:
        raise ValueError(f"unknown method {method!r}: choose from {', '.join(METHODS)}")
    cfg = PbRLConfig(**{**base[method], "absorbing": ABSORBING_DEFAULT[method], **overrides})
    cfg.check()
    return cfg


FAST_REWARD = RewardConfig(hidden=(8, 8), updates=10, batch_size=8)
"""The reward ensemble of the ``fast`` preset."""


def fast_config(method: str, **overrides) -> PbRLConfig:
    """:func:`method_config` on the engine's fast schedule, with a tiny ensemble (and 250 pre-training steps
    for PEBBLE): seconds once compiled; for tests and dry runs, not for results."""
    base = dict(FAST_SCHEDULE, reward=FAST_REWARD)
    if method == "pebble":
        base["explore_steps"] = 250
    return method_config(method, **{**base, **overrides})


def _init(key, env: Env, cfg: PbRLConfig):
    obs_dim, act_dim = env.observation_space.dim, action_width(env.action_space)  # a discrete action enters one-hot
    k_loop, k_rew, k_run = jax.random.split(key, 3)
    return reward_init(k_rew, obs_dim, act_dim, cfg.reward, absorbing=cfg.absorbing_heads()), k_loop, k_run


def _select(model: RewardState, replay, key, w, env, cfg: PbRLConfig):
    """The round's queries: the ``per_round`` pairs the ensemble is least sure of (``cfg.sampler``)."""
    key, k_q, k_t, k_r = jax.random.split(key, 4)
    probs = partial(preference_probs, model.params)
    seg_a, seg_b = select_queries(
        k_q, replay, probs, cfg.per_round, cfg.segment, cfg.sampler, cfg.candidates, cfg.absorbing,
        from_start=cfg.queries_from_start,
    )  # fmt: skip
    return model, seg_a, seg_b, (key, k_t, k_r)


def _learn(model: RewardState, prefs, replay, key, w, env, cfg: PbRLConfig):
    """Fit the ensemble to every answer so far (Eq. 3.1): (state, (loss, accuracy))."""
    state, loss, acc = train_reward(model, prefs, key, cfg.reward)
    return state, (loss, acc)


def _reward(model: RewardState, w, env, cfg: PbRLConfig):
    """The ensemble's mean (and its absorbing states' reward)."""
    return ensemble_reward, model.params, cfg.absorbing_fn()


def learned_reward(model: RewardState):
    """What the ensemble learned, as ``(reward_fn, params)``: its members' mean."""
    return ensemble_reward, model.params


def _oracle_init(key, env: Env, cfg: PbRLConfig):
    k_loop, _, k_run = jax.random.split(key, 3)  # the learners' split, so seeds draw alike
    return (), k_loop, k_run


def _ask_nothing(model, replay, key, w, env, cfg):
    raise AssertionError("the oracle asks nobody, so the engine never runs its feedback rounds")


def _oracle_reward(model, w, env, cfg: PbRLConfig):
    """The world's own reward."""
    return None, model, None


REWARD_LEARNER = Learner(_init, _select, _learn, _reward, absorbing=lambda cfg: cfg.absorbing)
"""PEBBLE and DRLHP as one :class:`~mindgap.algorithms.engine.Learner`: both fit the reward
ensemble to preferences and differ only in their schedule (PEBBLE's pre-training and critic reset)."""

ORACLE_LEARNER = Learner(_oracle_init, _ask_nothing, _ask_nothing, _oracle_reward, asks=lambda cfg: False)
"""SAC on the world's own reward: no model, no queries."""


def prepare(world, cfg: PbRLConfig, seeds: int, teacher: str | HostTeacher = "true", belief: str | None = None):
    """The person who answers (None for the oracle), the run record, and no oracle of u_H:
    the engine's ``(teacher, meta, oracle)`` for :func:`~mindgap.algorithms.engine.run`."""
    if isinstance(world, GymWorld) and cfg.method != "sac" and teacher == "biased" and world.env.log_prob is None:
        raise ValueError(f"the biased teacher needs {NO_BELIEF}, or use --teacher true")
    person, meta = preference_teacher(world, cfg, seeds, teacher, belief, who=cfg.method)
    return (None if cfg.method == "sac" else person), meta, None


def train(
    world,
    cfg: PbRLConfig,
    seeds: int = 1,
    teacher: str | HostTeacher = "true",
    belief: str | None = None,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
    seed_ids: tuple[int, ...] | None = None,
) -> dict:
    """Run ``seeds`` seeds of ``cfg.method`` on ``world`` (only the seeds ``seed_ids`` of them, given
    those: a seed slice, :func:`mindgap.algorithms.methods.train`); checkpoint to ``out``.

    Args:
        world: a :class:`~mindgap.envs.interface.World` (a terrain world, a user's own, or a
            :class:`~mindgap.envs.gym_world.GymWorld`, run by :mod:`~mindgap.algorithms.host_loop`).
        teacher: ``"biased"`` — the person scores segments with r_H + log T_H under
            ``belief`` (default: the world's first); ``"true"`` — the ordinary B-Pref
            teacher (r_H only); a :class:`~mindgap.teachers.host.HostTeacher` (e.g. people
            through the study app) — asked outside jit each round. Unused by ``sac``.

    Returns:
        the dict of :func:`mindgap.algorithms.engine.run`: ``curve`` (rows of seed, step,
        return, queries), ``final_returns`` [seeds, episodes], ``paths``, ``config``, ``carry``.
    """
    from . import methods

    cfg.check()
    m = methods.for_config(cfg)
    kw = dict(out=out, progress=progress, fresh=fresh, seed_ids=seed_ids)
    return methods.train(m, world, cfg, seeds, teacher=teacher, belief=belief, **kw)
