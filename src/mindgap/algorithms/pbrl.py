"""The preference-based RL engine and its three configurations: SAC (oracle), PEBBLE, DRLHP.

One loop, vmapped over seeds, in jitted chunks (:func:`~mindgap.algorithms.sac_loop.run_chunk`):

1. ``random``: uniformly random actions until ``sac.learning_starts``;
2. ``explore`` (PEBBLE only, Lee et al. 2021): SAC on the k-nearest-neighbour state-entropy
   reward for ``explore_steps``; the critic is then reset, the policy kept;
3. ``train``: every ``feedback_every`` steps while the query budget lasts, a round of
   feedback — pick ``per_round`` pairs of segments with the sampler, ask the simulated
   person (:mod:`~mindgap.teachers.preference`), fit the reward ensemble, relabel the
   whole buffer — and in between SAC on the ensemble's mean reward.

SAC ("the oracle") skips the feedback and optimises the world's own reward. DRLHP
(Christiano et al. 2017) is the same loop without exploration pre-training or critic
reset, with disagreement sampling; its policy optimiser is SAC here (the original used
A2C/TRPO) so that all methods differ only in how they learn the reward.

``absorbing`` (PEBBLE and DRLHP) gives the learned reward absorbing states (Kostrikov
et al. 2019, "Discriminator-Actor-Critic"): segments keep the steps after a goal or pit
as absorbing steps, each ensemble member learns their reward ``r_abs``, and the buffer's
terminal transitions carry the absorbing state's value ``γ r_abs / (1 − γ)``. Without it
a learned reward suffers termination bias: segments that reach the goal are cut short,
their learned return is a sum of fewer bounded rewards, the critic values the end of an
episode at 0, and the agent learns to hover next to the goal rather than enter it.
``absorbing_state`` picks DAC's single absorbing state (``single``) or one per terminal
state (``terminal``, the default: goals and pits must not share one; see
:mod:`~mindgap.models.reward_ensemble`).

Runs checkpoint after every chunk to ``OUT/checkpoint.npz`` and resume from it.
"""

from __future__ import annotations

import dataclasses
import json
from functools import partial
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from .._io import atomic_write
from ..checkpoint import load_pytree, save_pytree
from ..data.fingerprint import fingerprint
from ..data.prefs import PrefData, prefs_add, prefs_init
from ..data.replay import relabel
from ..data.segments import Segments
from ..envs.interface import Env
from ..feedback.queries import SAMPLERS, select_queries
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
from ..teachers.preference import TeacherConfig, answer
from .sac import SACConfig, sac_init
from .sac_loop import LoopState, dims, evaluate, loop_init, run_chunk

METHODS = ("sac", "pebble", "drlhp")
EXPLORATION = {"noise_color": 1.0, "entropy_bonus": 1.0}
"""How every learner's SAC explores by default (:attr:`Schedule.sac`: SAC, PEBBLE, DRLHP,
PrefBias, EPS): pink action noise and a decaying state-entropy bonus (see
:class:`~mindgap.algorithms.sac.SACConfig`). With plain white noise one seed in five never
found the goal of nav2 and d2–d4 with the true reward, and EPS took d3's icy road in 1 seed
of 3 (3 of 3 with it; README, "Learning from preferences")."""
ABSORBING_DEFAULT = {"sac": False, "pebble": True, "drlhp": False}
"""Whether each method's preset (:func:`method_config`) gives the learned reward absorbing states.

PEBBLE: on, by measurement (true teacher, 800 queries, 80 a round, 5 seeds, with
:data:`EXPLORATION`): d1 (60 000 steps) 100.1 ± 0.7, 99% of the SAC oracle; nav1
(30 000 steps) −1.2 ± 0.2, 99% of the oracle's improvement over never arriving. With
plain exploration it lifted d1 from −93.8 ± 2.5 to 56.8 ± 79.1 but left one nav1 seed
unstable (−9.5 ± 17.7 against −1.0 ± 0.4). DRLHP: off, unmeasured with it.
"""


@dataclasses.dataclass(frozen=True)
class Schedule:
    """What every run config of the engine shares: the schedule, the budget and the teacher's knobs.

    PEBBLE/DRLHP/SAC (:class:`PbRLConfig`), PrefBias and EPS extend it with their models
    and redeclare a field where their default differs; :func:`drive` reads these fields.
    """

    method: str = "pebble"
    """Which learner (each config lists its own)."""
    total_steps: int = 40_000
    """Environment steps per seed."""
    chunk: int = 1000
    """Steps per jitted chunk; every boundary below is a multiple of it."""
    eval_every: int = 2000
    """Steps between evaluations of the greedy policy under the true reward."""
    eval_episodes: int = 10
    """Episodes per evaluation."""
    sac: SACConfig = SACConfig(hidden=(64, 64), learning_starts=1000, **EXPLORATION)
    """The agent's SAC (exploring as :data:`EXPLORATION` says)."""
    queries: int = 800
    """Total query budget (pairs shown)."""
    per_round: int = 50
    """Queries per feedback round."""
    feedback_every: int = 2000
    """Steps between feedback rounds."""
    segment: int = 10
    """Steps per segment."""
    explore_steps: int = 0
    """State-entropy pre-training steps (PEBBLE's phase; 0 for none)."""
    knn: int = 5
    """k of the k-NN entropy estimate."""
    reset_critic: bool = False
    """Re-initialise the critic after pre-training (PEBBLE)."""
    teacher: TeacherConfig = TeacherConfig()
    """Answering knobs of the simulated person (β, mistakes, skips, …)."""
    seed: int = 0
    """Base seed; seed i of a run uses seed + i."""

    def check_schedule(self) -> None:
        for name in ("total_steps", "eval_every", "feedback_every", "explore_steps"):
            if getattr(self, name) % self.chunk:
                raise ValueError(f"{name} ({getattr(self, name)}) must be a multiple of chunk ({self.chunk})")
        if self.sac.learning_starts % self.chunk:
            raise ValueError(f"sac.learning_starts must be a multiple of chunk ({self.chunk})")
        if self.learning_steps() >= self.total_steps:
            raise ValueError("total_steps leaves no steps for learning after the random and exploration phases")

    def learning_steps(self) -> int:
        """First step of the ``train`` phase (and of the first feedback round)."""
        return self.sac.learning_starts + self.explore_steps

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


FAST_SCHEDULE = dict(
    total_steps=1500,
    chunk=250,
    eval_every=500,
    eval_episodes=4,
    feedback_every=250,
    queries=30,
    per_round=10,
    segment=5,
    sac=SACConfig(hidden=(16, 16), batch_size=32, learning_starts=250),
)
"""The schedule of the learners' ``fast`` presets (seconds once compiled; tests and dry runs)."""


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
        if self.sampler not in SAMPLERS:
            raise ValueError(f"unknown sampler {self.sampler!r}: choose from {', '.join(SAMPLERS)}")
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


class Carry(NamedTuple):
    """Everything a run carries between chunks, each leaf with a leading seed axis."""

    loop: LoopState
    reward: RewardState
    prefs: PrefData
    key: jax.Array
    queries: jax.Array


def _init(keys, env: Env, world_params, cfg: PbRLConfig) -> Carry:
    obs_dim, act_dim = dims(env)

    def one(k):
        k_loop, k_rew, k_run = jax.random.split(k, 3)
        return Carry(
            loop_init(k_loop, env, world_params, cfg.sac, cfg.total_steps),
            reward_init(k_rew, obs_dim, act_dim, cfg.reward, absorbing=cfg.absorbing_heads()),
            prefs_init(max(cfg.queries, 1), cfg.segment, obs_dim, act_dim, absorbing=cfg.absorbing),
            k_run,
            jnp.zeros((), jnp.int32),
        )

    return jax.vmap(one)(keys)


def _select_one(c: Carry, cfg: PbRLConfig):
    """First half of one seed's feedback round: the queries to show (and the keys for the rest)."""
    key, k_q, k_t, k_r = jax.random.split(c.key, 4)
    probs = partial(preference_probs, c.reward.params)
    seg_a, seg_b = select_queries(
        k_q, c.loop.replay, probs, cfg.per_round, cfg.segment, cfg.sampler, cfg.candidates, cfg.absorbing
    )
    return c._replace(key=key), seg_a, seg_b, k_t, k_r


def _learn_one(c: Carry, seg_a, seg_b, labels, answered, k_r, cfg: PbRLConfig):
    """Second half: keep the answers within the budget, fit the ensemble, relabel the buffer."""
    left = cfg.queries - c.queries
    answered = answered & (jnp.arange(cfg.per_round) < left)  # never past the budget
    prefs = prefs_add(c.prefs, seg_a, seg_b, labels, answered)
    rew, loss, acc = train_reward(c.reward, prefs, k_r, cfg.reward)
    replay = relabel(c.loop.replay, ensemble_reward, rew.params, absorbing_fn=cfg.absorbing_fn(), gamma=cfg.sac.gamma)
    shown = jnp.minimum(cfg.per_round, left)
    c = c._replace(loop=c.loop._replace(replay=replay), reward=rew, prefs=prefs, queries=c.queries + shown)
    return c, (loss, acc)


@partial(jax.jit, static_argnames=("env", "cfg", "tcfg"))
def _feedback(carry: Carry, env: Env, world_params, belief_params, cfg: PbRLConfig, tcfg: TeacherConfig):
    """One feedback round of every seed: query, answer, fit the ensemble, relabel the buffer."""

    def one(c: Carry):
        c, seg_a, seg_b, k_t, k_r = _select_one(c, cfg)
        labels, answered = answer(k_t, seg_a, seg_b, env, world_params, belief_params, tcfg)
        return _learn_one(c, seg_a, seg_b, labels, answered, k_r, cfg)

    return jax.vmap(one)(carry)


@partial(jax.jit, static_argnames=("cfg",))
def _select(carry: Carry, cfg: PbRLConfig):
    return jax.vmap(lambda c: _select_one(c, cfg))(carry)


@partial(jax.jit, static_argnames=("cfg",))
def _learn(carry: Carry, seg_a, seg_b, labels, answered, k_r, cfg: PbRLConfig):
    return jax.vmap(lambda *xs: _learn_one(*xs, cfg))(carry, seg_a, seg_b, labels, answered, k_r)


def host_answers(teacher: HostTeacher, seg_a: Segments, seg_b: Segments, queries, per_round: int, budget: int):
    """Ask a host teacher every seed's queries ``[S, K, L, ·]`` in one call.

    Only the queries the budget still allows are shown (``queries [S]``: pairs shown so far);
    the rest come back unanswered.

    Returns:
        (labels [S, K] float32, answered [S, K] bool), as JAX arrays.
    """
    seeds = queries.shape[0]
    ask = int(min(per_round, budget - int(queries.min())))

    def flat(seg):
        return type(seg)(*(np.asarray(x)[:, :ask].reshape(seeds * ask, *x.shape[2:]) for x in seg))

    got, ok = teacher(flat(seg_a), flat(seg_b))
    labels = np.zeros((seeds, per_round), np.float32)
    answered = np.zeros((seeds, per_round), bool)
    labels[:, :ask] = np.asarray(got, np.float32).reshape(seeds, ask)
    answered[:, :ask] = np.asarray(ok, bool).reshape(seeds, ask)
    return jnp.asarray(labels), jnp.asarray(answered)


@partial(jax.jit, static_argnames=("cfg",))
def _reset_critic(carry, cfg):
    """Re-initialise every seed's critic (PEBBLE, after pre-training); any carry with ``loop`` and ``key``."""

    def one(c):
        key, k = jax.random.split(c.key)
        fresh = sac_init(k, c.loop.replay.obs.shape[-1], c.loop.replay.act.shape[-1], cfg.sac)
        sac = c.loop.sac
        params = sac.params._replace(critic=fresh.params.critic, target=fresh.params.critic)
        sac = sac._replace(params=params, critic_opt=fresh.critic_opt)
        return c._replace(loop=c.loop._replace(sac=sac), key=key)

    return jax.vmap(one)(carry)


def _chunk(carry: Carry, env: Env, world_params, cfg: PbRLConfig, phase: str) -> Carry:
    learned = cfg.method != "sac" and phase == "train"
    loop = jax.vmap(
        lambda ls, rp: run_chunk(
            ls,
            env,
            world_params,
            rp,
            n_steps=cfg.chunk,
            cfg=cfg.sac,
            phase=phase,
            reward_fn=ensemble_reward if learned else None,
            knn=cfg.knn,
            absorbing_fn=cfg.absorbing_fn() if learned else None,
        )
    )(carry.loop, carry.reward.params)
    return carry._replace(loop=loop)


def _evaluate(carry, world, episodes: int, step: int, base_seed: int):
    keys = jax.random.split(rng.key(10_000 + base_seed + step), carry.queries.shape[0])
    actors = carry.loop.sac.params.actor
    return jax.vmap(lambda k, a: evaluate(k, world.env, a, world.params, episodes, world.horizon))(keys, actors)


def train(
    world,
    cfg: PbRLConfig,
    seeds: int = 1,
    teacher: str | HostTeacher = "true",
    belief: str | None = None,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
) -> dict:
    """Run ``seeds`` seeds of ``cfg.method`` on a terrain world; checkpoint to ``out``.

    Args:
        world: a :class:`~mindgap.envs.terrain.TerrainWorld`.
        teacher: ``"biased"`` — the person scores segments with r_H + log T_H under
            ``belief`` (default: the world's first); ``"true"`` — the ordinary B-Pref
            teacher (r_H only); a :class:`~mindgap.teachers.host.HostTeacher` (e.g. people
            through the study app) — asked outside jit each round.

    Returns:
        dict with ``curve`` (rows of seed, step, return, queries), ``final_returns``
        [seeds, episodes], ``paths`` (per seed, greedy rollouts) and ``config``.
    """
    return run_engine(
        world,
        cfg,
        seeds,
        teacher,
        belief,
        out,
        progress,
        fresh,
        init=_init,
        feedback=_feedback,
        select=_select,
        learn=_learn,
        chunk=_chunk,
    )


def run_engine(world, cfg, seeds, teacher, belief, out, progress, fresh, *, init, feedback, select, learn, chunk):
    """The body of a learner's ``train`` (PEBBLE/DRLHP/SAC here, PrefBias): set up the teacher, run :func:`drive`.

    Args:
        init: ``(keys [S], world params, cfg) → carry``.
        feedback: one jitted round of every seed with the simulated person,
            ``(carry, world params, belief params, cfg, teacher cfg) → (carry, info)``.
        select, learn: the round's two jitted halves, ``(carry, cfg) → (carry, seg_a, seg_b, k_t, k_r)``
            and ``(carry, seg_a, seg_b, labels, answered, k_r, cfg) → (carry, info)``, around a host
            teacher (people) asked outside jit.
        chunk: ``(carry, world params, cfg, phase) → carry``.
    """
    cfg.check()
    host, belief_params, tcfg, meta = teacher_setup(world, cfg, seeds, teacher, belief)
    params = world.params
    carry = init(jax.random.split(rng.key(cfg.seed), seeds), world.env, params, cfg)

    def one_round(c):
        if host is None:
            return feedback(c, world.env, params, belief_params, cfg, tcfg)[0]
        c, seg_a, seg_b, _, k_r = select(c, cfg)
        labels, answered = host_answers(host, seg_a, seg_b, c.queries, cfg.per_round, cfg.queries)
        return learn(c, seg_a, seg_b, labels, answered, k_r, cfg)[0]

    def one_chunk(c, phase):
        return chunk(c, world.env, params, cfg, phase)

    return drive(world, cfg, seeds, meta, carry, one_round, one_chunk, out=out, progress=progress, fresh=fresh)


def teacher_setup(world, cfg, seeds: int, teacher, belief: str | None):
    """Check the teacher and seeds; the host teacher (or None), the simulated person's belief and config, run record.

    Returns:
        (host teacher or None, belief parameters or None, TeacherConfig, metadata dict).
    """
    host = teacher if callable(teacher) else None
    if host is None and teacher not in ("biased", "true"):
        raise ValueError(f"teacher must be 'biased', 'true' or a host teacher, got {teacher!r}")
    belief_params = world.belief(belief) if teacher == "biased" else None
    tcfg = dataclasses.replace(cfg.teacher, use_belief=teacher == "biased")
    meta = run_record(world, seeds, teacher=teacher if host is None else host.name, belief=belief)
    meta["config"] = cfg.as_dict()
    return host, belief_params, tcfg, meta


def run_record(world, seeds: int, **extra) -> dict:
    """What a run folder's config.json records of the world and seeds (checked; resuming compares it), plus ``extra``."""
    if seeds < 1:
        raise ValueError("seeds must be at least 1")
    meta = {"world": world.name, "source": world.source, "world_hash": fingerprint(world.fingerprint_tree())}
    return {**meta, "seeds": seeds, **extra}


def drive(world, cfg, seeds: int, meta: dict, carry, feedback, chunk, *, out=None, progress=True, fresh=False) -> dict:
    """The engine's driver, shared by PbRL and PrefBias: phases, feedback rounds, evaluation, checkpoints.

    Args:
        cfg: a run config with the fields of :class:`PbRLConfig` the schedule reads (``method``,
            ``total_steps``, ``chunk``, ``eval_every``, ``eval_episodes``, ``sac``, ``queries``,
            ``feedback_every``, ``reset_critic``, ``seed``, ``learning_steps()``).
        carry: the initial carry of every seed (a NamedTuple with ``loop``, ``key``, ``queries``).
        feedback: ``carry → carry``, one feedback round of every seed.
        chunk: ``(carry, phase) → carry``, ``cfg.chunk`` environment steps of every seed.

    Returns:
        dict with ``curve``, ``final_returns``, ``paths``, ``config`` and the final ``carry``.
    """
    step, rows = 0, []
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        cfg_path, ckpt = out / "config.json", out / "checkpoint.npz"
        if fresh:
            ckpt.unlink(missing_ok=True)
        if cfg_path.exists() and ckpt.exists():
            if json.loads(cfg_path.read_text()) != json.loads(json.dumps(meta)):
                raise ValueError(f"{out} holds a run with other settings; use another --out or --fresh")
            carry, extra = load_pytree(ckpt, carry)
            step = int(extra["step"])
            rows = [tuple(r) for r in extra["rows"].tolist()]
        atomic_write(cfg_path, json.dumps(meta, indent=2))

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=cfg.total_steps, initial=step, desc=f"{cfg.method} {world.name}", unit="step")
    first_feedback = cfg.learning_steps()
    while step < cfg.total_steps:
        if step < cfg.sac.learning_starts:
            phase = "random"
        elif step < first_feedback:
            phase = "explore"
        else:
            phase = "train"
        if cfg.method != "sac" and phase == "train":
            due = (step - first_feedback) % cfg.feedback_every == 0
            if due and int(carry.queries.min()) < cfg.queries:
                carry = feedback(carry)
            if step == first_feedback and cfg.reset_critic:
                carry = _reset_critic(carry, cfg)
        carry = chunk(carry, phase)
        step += cfg.chunk
        if step % cfg.eval_every == 0 or step == cfg.total_steps:
            rets = np.asarray(_evaluate(carry, world, cfg.eval_episodes, step, cfg.seed)[0])
            q = np.asarray(carry.queries)
            rows += [(s, step, float(rets[s].mean()), int(q[s])) for s in range(seeds)]
            if bar is not None:
                bar.set_postfix(ret=f"{rets.mean():.1f}", queries=int(q.mean()))
        if out is not None:
            save_pytree(out / "checkpoint.npz", carry, step=step, rows=np.asarray(rows, np.float64).reshape(-1, 4))
        if bar is not None:
            bar.update(cfg.chunk)
    if bar is not None:
        bar.close()
    final, obs, alive = _evaluate(carry, world, max(cfg.eval_episodes, 20), cfg.total_steps + 1, cfg.seed)
    pos = world.trace(obs)
    paths = []
    for s in range(seeds):
        seed_paths = []
        for e in range(min(3, pos.shape[1])):
            n = int(np.asarray(alive[s, e]).sum())
            seed_paths.append(np.asarray(pos[s, e, : n + 1]))
        paths.append(seed_paths)
    return {"curve": rows, "final_returns": np.asarray(final), "paths": paths, "config": meta, "carry": carry}
