"""Explicable policy search (Algorithm 3) and the DRLHP baseline on expectation preferences.

The loop of Algorithm 3 on the engine of :mod:`~mindgap.algorithms.pbrl` (same phases,
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

from .. import rng
from ..data.fingerprint import fingerprint
from ..data.prefs import PrefData, prefs_add, prefs_init
from ..data.replay import relabel
from ..envs.interface import Env, check_env
from ..feedback.queries import SAMPLERS, select_queries
from ..models.actor import actor_dist
from ..models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_init, fit_norm, train_dynamics
from ..models.reward_ensemble import RewardConfig, RewardState, preference_probs, reward_init, train_reward
from ..teachers import expectation
from ..teachers.expectation import ExpectationTeacher
from ..teachers.preference import TeacherConfig
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
from .pbrl import FAST_SCHEDULE, Schedule, drive, run_record
from .sac import SACConfig
from .sac_loop import LoopState, dims, loop_init, run_chunk

METHODS = ("eps", "drlhp")
SURROGATES = ("learned", "exact")


@dataclasses.dataclass(frozen=True)
class EPSConfig(Schedule):
    """One EPS (or expectation-DRLHP) run; all seeds share it (hashable, a static jit argument).

    The schedule's fields (steps, chunks, evaluation, SAC, budget, teacher knobs) are
    :class:`~mindgap.algorithms.pbrl.Schedule`'s; for EPS the SAC's α is replaced by
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


class EPSCarry(NamedTuple):
    """Everything a run carries between chunks, each leaf with a leading seed axis."""

    loop: LoopState
    reward: RewardState
    prefs: PrefData
    dynamics: DynamicsModel
    u_norm: jax.Array  # [2]: mean and std of u_H over the buffer
    h_shift: jax.Array  # subtracted from H_T: its mean over the buffer (or 0)
    key: jax.Array
    queries: jax.Array


def expectation_reward(params: EPSRewardParams, obs, act, next_obs) -> jax.Array:
    """DRLHP's reward: the standardised u_H alone."""
    return normalised_u(params, obs, act, next_obs)


def _reward_fn(cfg: EPSConfig):
    return eps_reward if cfg.method == "eps" else expectation_reward


def u_params(c: EPSCarry, person: ExpectationTeacher, cfg: EPSConfig):
    """What u_H is computed from: one seed's ensemble, or the person's own score (``cfg.surrogate``)."""
    if cfg.surrogate == "exact":
        return ExactSurrogate(person, jnp.asarray(cfg.teacher.log_t_floor, jnp.float32))
    return c.reward.params


class WorldArgs(NamedTuple):
    """The true world as EPS's jitted programs take it: its params and :meth:`~mindgap.envs.interface.World.obs_units`."""

    params: object
    units: jax.Array


def _reward_params(env: Env, w: WorldArgs, c: EPSCarry, person: ExpectationTeacher, cfg: EPSConfig) -> EPSRewardParams:
    f = jnp.float32
    return EPSRewardParams(
        w.params,
        u_params(c, person, cfg),
        c.u_norm[0],
        c.u_norm[1],
        c.dynamics,
        jnp.asarray(cfg.dynamics.min_std, f),
        c.h_shift,
        jnp.asarray(cfg.lam, f),
        w.units,
        env,
    )


def _init(keys, env: Env, world_params, cfg: EPSConfig) -> EPSCarry:
    d, a = dims(env)

    def one(k):
        k_loop, k_rew, k_dyn, k_run = jax.random.split(k, 4)
        norm = Norm(jnp.zeros(d + a), jnp.ones(d + a), jnp.zeros(d), jnp.ones(d))  # replaced at the first round
        return EPSCarry(
            loop_init(k_loop, env, world_params, cfg.agent_sac(), cfg.total_steps),
            reward_init(k_rew, d, a, cfg.reward),
            prefs_init(cfg.queries, cfg.segment, d, a),
            dynamics_init(k_dyn, d, a, cfg.dynamics, norm),
            jnp.array([0.0, 1.0], jnp.float32),
            jnp.zeros((), jnp.float32),
            k_run,
            jnp.zeros((), jnp.int32),
        )

    return jax.vmap(one)(keys)


def _where(cond, a, b):
    return jax.tree.map(lambda x, y: jnp.where(cond, x, y), a, b)


def _round_one(c: EPSCarry, env: Env, w: WorldArgs, person: ExpectationTeacher, cfg: EPSConfig, tcfg: TeacherConfig):
    """One seed's feedback round (lines 4–7 of Algorithm 3), then relabelling."""
    key, k_dyn, k_fresh, k_q, k_t, k_r = jax.random.split(c.key, 6)
    buf = c.loop.replay
    dyn = c.dynamics
    if cfg.method == "eps":
        valid = jnp.arange(buf.capacity) < buf.size
        norm = fit_norm(buf.obs, buf.act, buf.next_obs, valid)
        fresh = dynamics_init(k_fresh, buf.obs.shape[-1], buf.act.shape[-1], cfg.dynamics, norm)
        dyn, _ = train_dynamics(
            k_dyn, buf.obs, buf.act, buf.next_obs, valid, cfg.dynamics, init=_where(c.queries == 0, fresh, dyn)
        )
    left = cfg.queries - c.queries
    if cfg.surrogate == "learned":
        seg_a, seg_b = select_queries(
            k_q,
            buf,
            partial(preference_probs, c.reward.params),
            cfg.per_round,
            cfg.segment,
            cfg.sampler,
            cfg.candidates,
        )
        labels, answered = expectation.answer(k_t, seg_a, seg_b, person, tcfg)
        answered = answered & (jnp.arange(cfg.per_round) < left)  # never past the budget
        prefs = prefs_add(c.prefs, seg_a, seg_b, labels, answered)
        rew, loss, acc = train_reward(c.reward, prefs, k_r, cfg.reward)
        c = c._replace(reward=rew, prefs=prefs)
    else:  # the person's own score: nothing to ask or fit
        loss, acc = jnp.zeros(()), jnp.ones(())
    u_norm = jnp.stack(u_norm_from_replay(u_params(c, person, cfg), buf))
    c = c._replace(dynamics=dyn, u_norm=u_norm, key=key)
    if cfg.method == "eps" and cfg.centre_entropy:
        c = c._replace(h_shift=entropy_mean_from_replay(_reward_params(env, w, c, person, cfg), buf))
    replay = relabel(buf, _reward_fn(cfg), _reward_params(env, w, c, person, cfg))
    shown = jnp.minimum(cfg.per_round, left)
    return c._replace(loop=c.loop._replace(replay=replay), queries=c.queries + shown), (loss, acc)


@partial(jax.jit, static_argnames=("env", "cfg", "tcfg"))
def _feedback(carry: EPSCarry, env: Env, w: WorldArgs, person: ExpectationTeacher, cfg: EPSConfig, tcfg: TeacherConfig):
    return jax.vmap(lambda c: _round_one(c, env, w, person, cfg, tcfg))(carry)


def _chunk(carry: EPSCarry, env: Env, w: WorldArgs, person: ExpectationTeacher, cfg: EPSConfig, phase: str):
    learned = phase == "train"
    sac = cfg.agent_sac()

    def one(c: EPSCarry):
        return run_chunk(
            c.loop,
            env,
            w.params,
            _reward_params(env, w, c, person, cfg),
            n_steps=cfg.chunk,
            cfg=sac,
            phase=phase,
            reward_fn=_reward_fn(cfg) if learned else None,
        )

    return carry._replace(loop=jax.vmap(one)(carry))


def train(
    world,
    cfg: EPSConfig,
    person: ExpectationTeacher,
    seeds: int = 1,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
    person_name: str = "biased",
) -> dict:
    """Run ``seeds`` seeds of EPS (or expectation-DRLHP) on a terrain world; checkpoint to ``out``.

    Args:
        world: a :class:`~mindgap.envs.terrain.TerrainWorld`.
        person: the simulated person (:func:`~mindgap.teachers.expectation.expectation_teacher`).
        person_name: how the run record names the person (``biased``, ``unbiased``).

    Returns:
        the dict of :func:`mindgap.algorithms.pbrl.train` (``curve``, ``final_returns``,
        ``paths``, ``config``, ``carry``).
    """
    cfg.check()
    check_env(world.env, density=True, who="EPS")
    env, w = world.env, WorldArgs(world.params, world.obs_units())
    tcfg = cfg.teacher
    meta = run_record(
        world, seeds, teacher=f"expectation:{person_name}", person_hash=fingerprint(person), config=cfg.as_dict()
    )
    carry = _init(jax.random.split(rng.key(cfg.seed), seeds), env, w.params, cfg)

    def feedback(c):
        return _feedback(c, env, w, person, cfg, tcfg)[0]

    def chunk(c, phase):
        return _chunk(c, env, w, person, cfg, phase)

    # the engine's schedule reads cfg.sac (learning_starts) — the same for the agent's SAC
    return drive(world, cfg, seeds, meta, carry, feedback, chunk, out=out, progress=progress, fresh=fresh)


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
