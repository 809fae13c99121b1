"""Explicable policy search (Algorithm 3) and the DRLHP baseline on expectation preferences.

The loop of Algorithm 3 on the engine of :mod:`~mindgap.algorithms.engine` (same phases,
checkpoints, evaluation and curve rows), vmapped over seeds in jitted chunks:

1. ``random`` steps until ``sac.learning_starts`` (line 3 with a uniform policy);
2. every ``feedback_every`` steps while the budget lasts, a feedback round:

   * fit T_A, a Gaussian dynamics model, to the replay buffer D (line 4): afresh with the
     buffer's normalisation the first time, warm-started after;
   * pick ``per_round`` pairs of segments with the uncertainty sampler of the engine and ask
     the simulated person which is *more expected* (lines 5–6;
     :mod:`~mindgap.teachers.expectation`: Bradley–Terry on Σ log T_H + log π_H);
   * fit the reward ensemble u_H to all answers (line 7), standardise it over the buffer
     (§4.3.3) and relabel the whole buffer with the reshaped reward;

3. in between, SAC on the reshaped reward ``r_A + λ(u_H + H_T)`` with the fixed entropy
   coefficient α = λ·reward_scale/s_H, so that SAC's own entropy bonus is Eq. 4.6's
   policy-entropy term (line 10; :mod:`~mindgap.algorithms.eps_reward`).

u_H has unit spread over the buffer, so λ weighs it against r_A the same way in every
world. The policy entropy is weighted λ/s_H, with s_H = ``nats_per_unit`` (7) the same in
every world: the spread, in nats, that one unit of the standardised u_H stands for
(:mod:`~mindgap.algorithms.eps_reward`, "Scale of H_π").

``method="drlhp"`` is the DRLHP baseline of §4.4.1.1: the same preferences and ensemble, the
agent optimising the standardised u_H alone (no r_A, no H_T; SAC's α tuned as usual).
T_A is not retrained once the query budget is spent: the reward is then fixed, as in the
engine's other methods.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..data.fingerprint import fingerprint
from ..envs.gym_world import refuse_without_dynamics
from ..envs.interface import Env, check_env
from ..feedback.queries import SAMPLERS, select_queries
from ..models.actor import actor_dist
from ..models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_init, fit_norm, train_dynamics
from ..models.reward_ensemble import RewardConfig, RewardState, preference_probs, reward_init, train_reward
from ..teachers.expectation import ExpectationTeacher
from ..teachers.host import HostTeacher
from .engine import FAST_SCHEDULE, Learner, Schedule, WorldArgs, run, run_record
from .eps_reward import (
    EPSRewardParams,
    ExactSurrogate,
    entropy_mean_from_replay,
    eps_reward,
    eps_sac_config,
    normalised_u,
    u_norm_from_replay,
)
from .explicability import explicability
from .sac import SACConfig

METHODS = ("eps", "drlhp")
SURROGATES = ("learned", "exact")


@dataclasses.dataclass(frozen=True)
class EPSConfig(Schedule):
    """One EPS (or expectation-DRLHP) run; all seeds share it (hashable, a static jit argument).

    The schedule's fields (steps, chunks, evaluation, SAC, budget, teacher knobs) are
    :class:`~mindgap.algorithms.engine.Schedule`'s; for EPS the SAC's α is replaced by
    λ·reward_scale/nats_per_unit.
    """

    method: str = "eps"
    """eps (Algorithm 3) or drlhp (u_H alone, the baseline of §4.4.1.1)."""
    lam: float = 2.0
    """λ, the reconciliation factor of Eq. 4.6 (the dissertation tunes it in [2.0, 2.8])."""
    total_steps: int = 60_000
    """Environment steps per seed."""
    reward: RewardConfig = RewardConfig()
    """The ensemble that learns u_H."""
    dynamics: DynamicsConfig = DynamicsConfig()
    """T_A, the agent's Gaussian dynamics model (H_T)."""
    per_round: int = 80
    """Queries per feedback round."""
    sampler: str = "disagreement"
    """uniform, disagreement or entropy (uncertainty sampling, §4.3.3)."""
    candidates: int = 10
    """Pairs drawn per query kept (score-based samplers)."""
    nats_per_unit: float = 7.0
    """s_H: the per-step spread, in nats, of the person's log T_H + log π_H that one unit of the
    standardised u_H stands for; the policy entropy is weighted λ/s_H (α = λ·reward_scale/s_H) so
    that u_H + H_π keeps the balance of the KL it comes from. Fixed across worlds: measured 6.6–7.2
    over uniform-random transitions of d1–d4 and 7.4 over EPS's d3 buffers. With 7, λ = 2 gives
    α ≈ 0.29. A weight of λ itself (``nats_per_unit=1``, α = 2 — eight times SAC's tuned α in d3)
    gave a wider policy, less explicable than SAC's on the same road (d3: −501 against −425;
    narrowing the trained policies' pre-tanh std by e⁻¹ alone took them to −399). Trained with
    λ/7, d3's EPS earns 101.1 instead of 97.2, but its explicability did not improve
    (−569 ± 160, 5 seeds)."""
    centre_entropy: bool = False
    """Subtract H_T's mean over the buffer, as u_H is centred (a differential entropy's constant
    depends on the units of the state). Off by default, as Eq. 4.6 is written: measured on d1
    and d3 (3 seeds, 40 000 steps), centring left every seed idling short of the goal, while
    the uncentred H_T — about −3 nats per step in cells where T_A fits well — charges each
    step and keeps the agent moving (d1: 2 of 3 seeds reach the goal by a wide detour)."""

    surrogate: str = "learned"
    """``learned``: u_H is the ensemble fitted to the person's answers (Algorithm 3). ``exact``:
    u_H is the person's own per-step log T_H + log π_H (:class:`~.eps_reward.ExactSurrogate`),
    standardised over the buffer the same way; no query is asked (the rounds still come on the
    same schedule, refit T_A and relabel, and count their budget as shown). An oracle
    ablation, not a method: it needs the person's models, which only a simulation has."""

    def check(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r}: choose from {', '.join(METHODS)}")
        if self.surrogate not in SURROGATES:
            raise ValueError(f"unknown surrogate {self.surrogate!r}: choose from {', '.join(SURROGATES)}")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"unknown sampler {self.sampler!r}: choose from {', '.join(SAMPLERS)}")
        if self.lam < 0:
            raise ValueError(f"λ must be non-negative, got {self.lam}")
        if not self.nats_per_unit > 0:
            raise ValueError(f"nats_per_unit must be positive, got {self.nats_per_unit}")
        self.check_schedule()
        if self.queries < 1 or self.per_round < 1:
            raise ValueError("queries and per_round must be at least 1")

    def as_dict(self) -> dict:
        d = super().as_dict()
        if self.surrogate == "learned":  # recorded only when set, so earlier run folders still resume
            del d["surrogate"]
        return d

    def agent_sac(self) -> SACConfig:
        """The SAC the agent runs: α fixed to λ·reward_scale/nats_per_unit for EPS, as configured for DRLHP."""
        return eps_sac_config(self.sac, self.lam, self.nats_per_unit) if self.method == "eps" else self.sac


_FAST = dict(
    **FAST_SCHEDULE,
    reward=RewardConfig(members=2, hidden=(8, 8), updates=10, batch_size=8),
    dynamics=DynamicsConfig(hidden=(8, 8), max_epochs=3, steps_per_epoch=5, batch_size=32),
)
PRESETS = ("full", "fast")


def eps_config(preset: str = "full", **overrides) -> EPSConfig:
    """A preset with ``overrides`` applied, checked (``fast``: tiny networks, 1500 steps; for tests)."""
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}: choose from {', '.join(PRESETS)}")
    cfg = EPSConfig(**{**(_FAST if preset == "fast" else {}), **overrides})
    cfg.check()
    return cfg


class EPSModel(NamedTuple):
    """One seed's EPS model: the ensemble that learns u_H, T_A, and how u_H and H_T are standardised."""

    reward: RewardState
    dynamics: DynamicsModel
    u_norm: jax.Array  # [2]: mean and std of u_H over the buffer
    h_shift: jax.Array  # subtracted from H_T: its mean over the buffer (or 0)
    started: jax.Array = jnp.zeros((), bool)  # a feedback round has fitted T_A


def expectation_reward(params: EPSRewardParams, obs, act, next_obs) -> jax.Array:
    """DRLHP's reward: the standardised u_H alone."""
    return normalised_u(params, obs, act, next_obs)


def _reward_fn(cfg: EPSConfig):
    return eps_reward if cfg.method == "eps" else expectation_reward


def u_params(model: EPSModel, person: ExpectationTeacher, cfg: EPSConfig):
    """What u_H is computed from: one seed's ensemble, or the person's own score (``cfg.surrogate``)."""
    if cfg.surrogate == "exact":
        return ExactSurrogate(person, jnp.asarray(cfg.teacher.log_t_floor, jnp.float32))
    return model.reward.params


def _reward_params(m: EPSModel, w: WorldArgs, env: Env, cfg: EPSConfig) -> EPSRewardParams:
    f = jnp.float32
    return EPSRewardParams(
        w.params,
        u_params(m, w.oracle, cfg),
        m.u_norm[0],
        m.u_norm[1],
        m.dynamics,
        jnp.asarray(cfg.dynamics.min_std, f),
        m.h_shift,
        jnp.asarray(cfg.lam, f),
        w.units,
        env,
    )


def _init(key, env: Env, cfg: EPSConfig):
    d, a = env.observation_space.dim, env.action_space.dim
    k_loop, k_rew, k_dyn, k_run = jax.random.split(key, 4)
    norm = Norm(jnp.zeros(d + a), jnp.ones(d + a), jnp.zeros(d), jnp.ones(d))  # replaced at the first round
    model = EPSModel(
        reward_init(k_rew, d, a, cfg.reward),
        dynamics_init(k_dyn, d, a, cfg.dynamics, norm),
        jnp.array([0.0, 1.0], jnp.float32),
        jnp.zeros((), jnp.float32),
    )
    return model, k_loop, k_run


def _select(m: EPSModel, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig):
    """Lines 4–5 of Algorithm 3: refit T_A to the buffer D (afresh the first time), pick the queries."""
    key, k_dyn, k_fresh, k_q, k_t, k_r = jax.random.split(key, 6)
    dyn = m.dynamics
    if cfg.method == "eps":
        valid = jnp.arange(buf.capacity) < buf.size
        norm = fit_norm(buf.obs, buf.act, buf.next_obs, valid)
        fresh = dynamics_init(k_fresh, buf.obs.shape[-1], buf.act.shape[-1], cfg.dynamics, norm)
        start = _where(m.started, dyn, fresh)
        dyn, _ = train_dynamics(k_dyn, buf.obs, buf.act, buf.next_obs, valid, cfg.dynamics, init=start)
    seg_a = seg_b = None
    if cfg.surrogate == "learned":
        probs = partial(preference_probs, m.reward.params)
        seg_a, seg_b = select_queries(k_q, buf, probs, cfg.per_round, cfg.segment, cfg.sampler, cfg.candidates)
    return m._replace(dynamics=dyn, started=jnp.ones((), bool)), seg_a, seg_b, (key, k_t, k_r)


def _learn(m: EPSModel, prefs, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig):
    """Line 7 and §4.3.3: fit u_H to every answer, standardise it (and optionally H_T) over the buffer."""
    loss, acc = jnp.zeros(()), jnp.ones(())
    if cfg.surrogate == "learned":
        rew, loss, acc = train_reward(m.reward, prefs, key, cfg.reward)
        m = m._replace(reward=rew)
    m = m._replace(u_norm=jnp.stack(u_norm_from_replay(u_params(m, w.oracle, cfg), buf)))
    if cfg.method == "eps" and cfg.centre_entropy:
        m = m._replace(h_shift=entropy_mean_from_replay(_reward_params(m, w, env, cfg), buf))
    return m, (loss, acc)


def _reward(m: EPSModel, w: WorldArgs, env: Env, cfg: EPSConfig):
    """Line 10: r_A + λ(u_H + H_T) for EPS, the standardised u_H alone for DRLHP."""
    return _reward_fn(cfg), _reward_params(m, w, env, cfg), None


def _where(cond, a, b):
    return jax.tree.map(lambda x, y: jnp.where(cond, x, y), a, b)


LEARNER = Learner(
    _init, _select, _learn, _reward, agent_sac=lambda cfg: cfg.agent_sac(), asks=lambda cfg: cfg.surrogate == "learned"
)
"""EPS (Algorithm 3) and expectation-DRLHP as a :class:`~mindgap.algorithms.engine.Learner`."""


def train(
    world,
    cfg: EPSConfig,
    person: ExpectationTeacher | HostTeacher,
    seeds: int = 1,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
    person_name: str = "biased",
) -> dict:
    """Run ``seeds`` seeds of EPS (or expectation-DRLHP) on ``world``; checkpoint to ``out``.

    Args:
        world: a :class:`~mindgap.envs.interface.World` whose env has ``reward`` and ``log_prob``.
        person: the simulated person (:func:`~mindgap.algorithms.expected_policy.expectation_teacher`),
            or a host teacher (people answering "which is more expected" through the study app).
        person_name: how the run record names the person (``biased``, ``unbiased``).

    Returns:
        the dict of :func:`mindgap.algorithms.engine.run` (``curve``, ``final_returns``,
        ``paths``, ``config``, ``carry``).
    """
    cfg.check()
    refuse_without_dynamics(world, "EPS")
    check_env(world.env, density=True, who="EPS")
    host = not isinstance(person, ExpectationTeacher)
    if host and cfg.surrogate == "exact":
        raise ValueError("the exact surrogate reads a simulated person's models; people cannot supply them")
    if host:
        meta = run_record(world, seeds, teacher=f"expectation:{person.name}", config=cfg.as_dict())
        teacher, oracle = person, None
    else:
        meta = run_record(
            world, seeds, teacher=f"expectation:{person_name}", person_hash=fingerprint(person), config=cfg.as_dict()
        )
        teacher = oracle = dataclasses.replace(person, cfg=cfg.teacher)
    return run(world, LEARNER, cfg, teacher, meta, seeds, out=out, progress=progress, fresh=fresh, oracle=oracle)


def explicability_scores(key, world, person: ExpectationTeacher, actors, episodes: int = 100, agent_dist=actor_dist):
    """Explicability score (Eq. 4.4) of each seed's policy over ``episodes`` stochastic rollouts.

    Args:
        actors: the policies' parameters with a leading seed axis: SAC actors, or what
            ``agent_dist`` reads (e.g. a :class:`~mindgap.algorithms.policy_shaping.ShapedPolicy`
            with :func:`~mindgap.algorithms.policy_shaping.shaped_dist`).

    Returns:
        one dict per seed: score, its standard error, its dynamics and policy parts
        (see :class:`~mindgap.algorithms.explicability.Explicability`) and the mean return
        of those rollouts.
    """
    seeds = jax.tree.leaves(actors)[0].shape[0]
    out = []
    for s, k in enumerate(jax.random.split(key, seeds)):
        actor = jax.tree.map(lambda a: a[s], actors)
        e = explicability(k, world, person.belief, actor, person.policy, episodes, agent_dist)
        out.append(
            {
                "score": float(e.score),
                "stderr": float(e.stderr),
                "dynamics_part": float(e.dynamics),
                "policy_part": float(e.policy),
                "stochastic_return": float(jnp.mean(e.returns)),
            }
        )
    return out
