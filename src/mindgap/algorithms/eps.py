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

3. in between, SAC on the reshaped reward ``r_A + λ(u_H + H_T/s_H)`` with the fixed entropy
   coefficient α = λ·reward_scale/s_H, so that SAC's own entropy bonus is Eq. 4.6's
   policy-entropy term (line 10; :mod:`~mindgap.algorithms.eps_reward`).

u_H has unit spread over the buffer, so λ weighs it against r_A the same way in every
world, and its offset makes the λ-term a cost, ≤ 0 on every step of the buffer, as the −KL it
stands for (``EPSConfig.offset``). The two entropies, H_T and the policy's, are
weighted λ/s_H, with s_H = ``nats_per_unit`` (7) the same in
every world: the spread, in nats, that one unit of the standardised u_H stands for
(:mod:`~mindgap.algorithms.eps_reward`, "Scale of H_π").

With ``judged="decisions"`` (a person who judges the agent's decisions, not the world's answer)
T_A is not fitted and H_T leaves the reward; with ``absorbing`` u_H learns absorbing states and an
ended episode's λ-term goes on at their value (:mod:`~mindgap.algorithms.eps_config`).

``method="drlhp"`` is the DRLHP baseline of §4.4.1.1: the same preferences and ensemble, the
agent optimising the standardised u_H alone (no r_A, no H_T; SAC's α fixed at 1/s_H in the presets,
``EPSConfig.drlhp_alpha``).
T_A is not retrained once the query budget is spent: the reward is then fixed, as in the
engine's other methods.

The configuration is :mod:`~mindgap.algorithms.eps_config`'s; the explicability score of a
trained policy is :func:`~mindgap.algorithms.explicability.explicability_scores`.
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
from ..envs.interface import Env, action_width, check_env
from ..feedback.queries import select_queries
from ..models.gaussian_dynamics import DynamicsModel, Norm, dynamics_init, fit_norm, train_dynamics
from ..models.reward_ensemble import RewardState, ensemble_reward, preference_probs, reward_init, train_reward
from ..teachers.expectation import ExpectationTeacher
from ..teachers.host import HostTeacher
from .engine import Learner, WorldArgs, run_record
from .eps_config import EPSConfig, drlhp_agent_sac, eps_agent_sac
from .eps_reward import (
    EPSRewardParams,
    ExactSurrogate,
    absorbing_u,
    cost_offsets,
    entropy_mean_from_replay,
    eps_absorbing,
    eps_reward,
    normalised_u,
    policy_entropy_max,
    u_norm_from_replay,
)
from .sac_loop import n_actions


class EPSModel(NamedTuple):
    """One seed's EPS model: the ensemble that learns u_H, T_A, and how u_H and H_T are standardised."""

    reward: RewardState
    dynamics: DynamicsModel
    u_norm: jax.Array  # [2]: mean and std of u_H over the buffer
    h_shift: jax.Array  # subtracted from H_T (EPSConfig.offset): H_π,max, H_T's mean over the buffer, or 0
    started: jax.Array = jnp.zeros((), bool)  # a feedback round has fitted T_A


def expectation_reward(params: EPSRewardParams, obs, act, next_obs) -> jax.Array:
    """DRLHP's reward: the standardised u_H alone."""
    return normalised_u(params, obs, act, next_obs)


def u_params(model: EPSModel, person: ExpectationTeacher, cfg: EPSConfig):
    """What u_H is computed from: one seed's ensemble, or the person's own score (``cfg.surrogate``)."""
    if cfg.surrogate == "exact":
        return ExactSurrogate(person, jnp.asarray(cfg.teacher.log_t_floor, jnp.float32))
    return model.reward.params


def judges_transitions(cfg: EPSConfig) -> bool:
    """Whether EPS fits T_A and puts H_T in its reward: the person judges transitions, not decisions."""
    return cfg.judged == "transitions"


def _reward_params(m: EPSModel, w: WorldArgs, env: Env, cfg: EPSConfig, dynamics: bool = True) -> EPSRewardParams:
    """The reward's parameters; ``dynamics``: T_A enters them (EPS on a person who judges transitions)."""
    f = jnp.float32
    return EPSRewardParams(
        w.params,
        u_params(m, w.oracle, cfg),
        m.u_norm[0],
        m.u_norm[1],
        m.dynamics if dynamics and judges_transitions(cfg) else None,
        jnp.asarray(cfg.dynamics.min_std, f),
        m.h_shift,
        jnp.asarray(1.0 / cfg.nats_per_unit, f),
        jnp.asarray(cfg.lam, f),
        w.units,
        env,
    )


def _init(key, env: Env, cfg: EPSConfig):
    d, a = env.observation_space.dim, action_width(env.action_space)  # a discrete action enters one-hot
    k_loop, k_rew, k_dyn, k_run = jax.random.split(key, 4)
    norm = Norm(jnp.zeros(d + a), jnp.ones(d + a), jnp.zeros(d), jnp.ones(d))  # replaced at the first round
    model = EPSModel(
        reward_init(k_rew, d, a, cfg.reward, absorbing=cfg.absorbing),
        dynamics_init(k_dyn, d, a, cfg.dynamics, norm),
        jnp.array([0.0, 1.0], jnp.float32),
        jnp.zeros((), jnp.float32),
    )
    return model, k_loop, k_run


def _select(m: EPSModel, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig, fit_dynamics: bool = True):
    """Lines 4–5 of Algorithm 3: refit T_A to the buffer D (afresh the first time, only with
    ``fit_dynamics`` and a person who judges transitions), pick the queries."""
    key, k_dyn, k_fresh, k_q, k_t, k_r = jax.random.split(key, 6)
    dyn = m.dynamics
    if fit_dynamics and judges_transitions(cfg):
        valid = jnp.arange(buf.capacity) < buf.size
        n = n_actions(env) or None  # a discrete action enters T_A one-hot
        norm = fit_norm(buf.obs, buf.act, buf.next_obs, valid, act_width=n)
        fresh = dynamics_init(k_fresh, buf.obs.shape[-1], action_width(env.action_space), cfg.dynamics, norm)
        start = _where(m.started, dyn, fresh)
        dyn, _ = train_dynamics(k_dyn, buf.obs, buf.act, buf.next_obs, valid, cfg.dynamics, init=start)
    seg_a = seg_b = None
    if cfg.surrogate == "learned":
        probs = partial(preference_probs, m.reward.params)
        seg_a, seg_b = select_queries(
            k_q,
            buf,
            probs,
            cfg.per_round,
            cfg.segment,
            cfg.sampler,
            cfg.candidates,
            absorbing=cfg.absorbing is not None,
            from_start=cfg.queries_from_start,
        )
    return m._replace(dynamics=dyn, started=jnp.ones((), bool)), seg_a, seg_b, (key, k_t, k_r)


def _fit_u(m: EPSModel, prefs, buf, key, w: WorldArgs, cfg: EPSConfig):
    """Line 7 and §4.3.3: fit u_H to every answer and standardise it over the buffer."""
    loss, acc = jnp.zeros(()), jnp.ones(())
    if cfg.surrogate == "learned":
        rew, loss, acc = train_reward(m.reward, prefs, key, cfg.reward)
        m = m._replace(reward=rew)
    m = m._replace(u_norm=jnp.stack(u_norm_from_replay(u_params(m, w.oracle, cfg), buf)), h_shift=jnp.zeros(()))
    return m, (loss, acc)


def _learn(m: EPSModel, prefs, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig):
    """:func:`_fit_u`, then the λ-term's constant (``cfg.offset``: a cost by default)."""
    m, info = _fit_u(m, prefs, buf, key, w, cfg)
    if cfg.offset == "centred":
        m = m._replace(h_shift=entropy_mean_from_replay(_reward_params(m, w, env, cfg), buf))
    elif cfg.offset == "cost":  # the λ-term ≤ 0 on the buffer (eps_reward's docstring)
        u_mean, h_shift = cost_offsets(_reward_params(m, w, env, cfg), buf, policy_entropy_max(env))
        m = m._replace(u_norm=m.u_norm.at[0].set(u_mean), h_shift=h_shift)
    return m, info


def _reward(m: EPSModel, w: WorldArgs, env: Env, cfg: EPSConfig):
    """Line 10: r_A + λ(u_H + H_T) (and, with ``cfg.absorbing``, the λ-term of an absorbing step)."""
    return eps_reward, _reward_params(m, w, env, cfg), eps_absorbing if cfg.absorbing is not None else None


def _drlhp_select(m: EPSModel, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig):
    """The queries of :func:`_select`; DRLHP fits no T_A."""
    return _select(m, buf, key, w, env, cfg, fit_dynamics=False)


def _drlhp_learn(m: EPSModel, prefs, buf, key, w: WorldArgs, env: Env, cfg: EPSConfig):
    """u_H fitted and standardised (:func:`_fit_u`); DRLHP's reward has no λ-term to offset."""
    return _fit_u(m, prefs, buf, key, w, cfg)


def _drlhp_reward(m: EPSModel, w: WorldArgs, env: Env, cfg: EPSConfig):
    """The standardised u_H alone (and its absorbing states' value with ``cfg.absorbing``)."""
    params = _reward_params(m, w, env, cfg, dynamics=False)
    return expectation_reward, params, absorbing_u if cfg.absorbing is not None else None


def learned_reward(m: EPSModel):
    """What the ensemble learned, as ``(reward_fn, params)``: u_H's members' mean, unstandardised."""
    return ensemble_reward, m.reward.params


def _where(cond, a, b):
    return jax.tree.map(lambda x, y: jnp.where(cond, x, y), a, b)


def _learner(select, learn, reward, agent_sac) -> Learner:
    """A Learner of the EPS family: both share the model (u_H's ensemble, T_A, the standardisation)."""
    absorbing = lambda cfg: cfg.absorbing is not None  # noqa: E731
    return Learner(_init, select, learn, reward, absorbing=absorbing, agent_sac=agent_sac, asks=_asks)


def _asks(cfg: EPSConfig) -> bool:
    return cfg.surrogate == "learned"


EPS_LEARNER = _learner(_select, _learn, _reward, eps_agent_sac)
"""EPS (Algorithm 3) as a :class:`~mindgap.algorithms.engine.Learner`: SAC's α is λ/s_H (Eq. 4.6's H_π)."""

DRLHP_LEARNER = _learner(_drlhp_select, _drlhp_learn, _drlhp_reward, drlhp_agent_sac)
"""Expectation-DRLHP (§4.4.1.1) as a :class:`~mindgap.algorithms.engine.Learner`: the same answers and
ensemble, the agent on the standardised u_H alone with SAC's α as ``drlhp_alpha`` says."""


def prepare(world, cfg: EPSConfig, seeds: int, person, person_name: str = "biased"):
    """The engine's ``(teacher, meta, oracle)`` for :func:`~mindgap.algorithms.engine.run`: a simulated
    person answers inside the program and is u_H's oracle (the exact surrogate reads it); people
    through a host teacher answer outside it."""
    refuse_without_dynamics(world, "EPS")
    check_env(world.env, density=True, who="EPS", discrete_actions=True)
    host = not hasattr(person, "answer")  # a jittable person (one or a crowd) answers inside the program
    if host and cfg.surrogate == "exact":
        raise ValueError("the exact surrogate reads a simulated person's models; people cannot supply them")
    if host:
        meta = run_record(world, seeds, teacher=f"expectation:{person.name}", config=cfg.as_dict())
        return person, meta, None
    meta = run_record(
        world, seeds, teacher=f"expectation:{person_name}", person_hash=fingerprint(person), config=cfg.as_dict()
    )
    teacher = dataclasses.replace(person, cfg=cfg.teacher)
    return teacher, meta, teacher


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
        person: the simulated person (:func:`~mindgap.algorithms.expected_policy.expectation_teacher`;
            or any jittable teacher with ``answer`` and ``cfg``, e.g. the driving study's
            :class:`~mindgap.teachers.drivers.CrowdTeacher`), or a host teacher (people answering "which is more expected" through the study app).
        person_name: how the run record names the person (``biased``, ``unbiased``).

    Returns:
        the dict of :func:`mindgap.algorithms.engine.run` (``curve``, ``final_returns``,
        ``paths``, ``config``, ``carry``).
    """
    from . import methods

    cfg.check()
    m = methods.for_config(cfg)
    return methods.train(
        m, world, cfg, seeds, out=out, progress=progress, fresh=fresh, person=person, person_name=person_name
    )
