"""The learning engine every method runs on: one schedule, one feedback round, one run record.

A method is a :class:`Learner`, a bundle of pure functions over its own model (PEBBLE's
reward ensemble, PrefBias's posteriors and f_ψ, EPS's u_H and T_A); the engine owns the rest,
for every seed at once (vmapped, in jitted chunks of environment steps):

1. ``random``: uniformly random actions until ``sac.learning_starts``;
2. ``explore`` (``explore_steps`` > 0, PEBBLE's pre-training; Lee et al. 2021): SAC on the
   k-nearest-neighbour state-entropy reward; with ``reset_critic`` the critic is then reset;
3. ``train``: every ``feedback_every`` steps while the query budget lasts, a feedback round —
   the learner picks ``per_round`` pairs of segments (``select``), the teacher answers, the
   answers within the budget join the preference dataset, the learner fits its model to all
   of them (``learn``) and the whole replay buffer is relabelled with the reward the learner
   now offers (``reward``) — and in between SAC on that reward.

A world declares its action space: on a :class:`~mindgap.envs.interface.Discrete` one the agent
is discrete SAC (:mod:`~mindgap.algorithms.sac_discrete`) and the learners' networks read actions
one-hot; the schedule is the same. A teacher is a value: a jittable simulated person with ``answer(key, seg_a, seg_b) → (labels,
answered)`` (the round is then one compiled program), or a
:class:`~mindgap.teachers.host.HostTeacher` — people through the study app — asked outside
jit between the round's two compiled halves. A :class:`~mindgap.envs.gym_world.GymWorld` runs the same
schedule with its envs stepped on the host (:mod:`~mindgap.algorithms.host_loop`). Runs checkpoint after every chunk to
``OUT/checkpoint.npz``, resume from it, and refuse a folder made with other settings.

A run may train some of its seeds alone (``seed_ids``, a *seed slice*: a full run's job can take
longer than a session has, :mod:`~mindgap.experiments._seed_slices`): a seed's key comes from its
index in the whole run (:func:`seed_keys`), never from how many seeds train beside it. (Under
``vmap``, JAX draws every row's random bits of ``rbg`` keys from the batch's first key, so the
numbers a seed draws beside others are not those it draws alone, except seed 0's.)
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from .._io import atomic_write
from ..checkpoint import load_pytree, save_pytree
from ..data.fingerprint import fingerprint
from ..data.prefs import PrefData, prefs_add, prefs_init
from ..data.replay import relabel
from ..envs.gym_world import GymWorld
from ..envs.interface import Env, check_env
from ..teachers.preference import PreferenceTeacher, TeacherConfig
from .sac import SACConfig
from .sac_loop import LoopState, agent_init, dims, evaluate, loop_init, run_chunk

EXPLORATION = {"noise_color": 1.0, "entropy_bonus": 1.0}
"""How every learner's SAC explores by default (:attr:`Schedule.sac`: SAC, PEBBLE, DRLHP,
PrefBias, EPS): pink action noise and a decaying state-entropy bonus (see
:class:`~mindgap.algorithms.sac.SACConfig`). Why: docs/experiments/pbrl.md, "SAC, the oracle"."""


QUERIES_FROM = ("anywhere", "start")
"""Where query segments may start (:attr:`Schedule.queries_from`)."""


@dataclasses.dataclass(frozen=True)
class Schedule:
    """What every method's config shares: the schedule, the budget and the simulated person's knobs.

    Each method's config extends it with its models and redeclares a field where its default differs.
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
    queries_from: str = "anywhere"
    """Where query segments start: ``anywhere`` in the replay buffer, or ``start``, an episode's first
    step, so that both segments of a pair show what the agent did from the world's starting situation
    (a study that sets a scene and asks which continuation is expected, as Fig. 33 does)."""
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
        if self.queries_from not in QUERIES_FROM:
            raise ValueError(f"queries_from must be one of {', '.join(QUERIES_FROM)}, got {self.queries_from!r}")
        for name in ("total_steps", "eval_every", "feedback_every", "explore_steps"):
            if getattr(self, name) % self.chunk:
                raise ValueError(f"{name} ({getattr(self, name)}) must be a multiple of chunk ({self.chunk})")
        if self.sac.learning_starts % self.chunk:
            raise ValueError(f"sac.learning_starts must be a multiple of chunk ({self.chunk})")
        if self.chunk % self.sac.train_every:
            raise ValueError(f"chunk ({self.chunk}) must be a multiple of sac.train_every ({self.sac.train_every})")
        if self.learning_steps() >= self.total_steps:
            raise ValueError("total_steps leaves no steps for learning after the random and exploration phases")

    @property
    def queries_from_start(self) -> bool:
        """Whether query segments start at episodes' first steps (:attr:`queries_from` is ``start``)."""
        return self.queries_from == "start"

    def learning_steps(self) -> int:
        """First step of the ``train`` phase (and of the first feedback round)."""
        return self.sac.learning_starts + self.explore_steps

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        if self.queries_from == "anywhere":  # recorded only when set, so earlier run folders still resume
            del d["queries_from"]
        if d.get("sac", {}).get("survival_entropy") == "paid":  # the same, for SAC's survival_entropy
            del d["sac"]["survival_entropy"]
        if d.get("sac", {}).get("alpha_extra") == 0.0:  # and its alpha_extra
            del d["sac"]["alpha_extra"]
        if d.get("sac", {}).get("train_every") == 1:  # and its train_every
            del d["sac"]["train_every"]
        return d


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
"""The schedule of every method's ``fast`` preset (seconds once compiled; tests and dry runs)."""


class WorldArgs(NamedTuple):
    """The true world as the compiled programs take it: its params and ``World.obs_units()``.

    ``oracle``: what an oracle ablation may read of the simulated person (EPS's exact
    surrogate); None otherwise.
    """

    params: Any
    units: jax.Array
    oracle: Any = None


class Learner(NamedTuple):
    """A method as pure functions of its model; ``env`` and ``cfg`` are static, the rest arrays.

    Attributes:
        init: ``(key, env, cfg) → (model, k_loop, k_run)``: the model and the keys of the SAC
            loop and of the run.
        select: ``(model, replay, key, w, env, cfg) → (model, seg_a, seg_b, (key, k_teacher, k_learn))``:
            the round's queries (and any model the learner refits from the buffer first); seg
            None when the learner asks nothing (``asks``).
        learn: ``(model, prefs, replay, key, w, env, cfg) → (model, info)``: fit to every answer so far.
        reward: ``(model, w, env, cfg) → (reward_fn, reward_params, absorbing_fn)``: what SAC
            optimises and the buffer is relabelled with; ``reward_fn`` None for the world's own
            reward; both functions hashable (module-level), ``absorbing_fn`` None without
            absorbing states.
        agent_sac: ``cfg → SACConfig`` of the agent.
        absorbing: ``cfg → bool``, whether segments keep absorbing steps.
        asks: ``cfg → bool``, whether rounds ask the teacher (False: the model needs no answers).
    """

    init: Callable
    select: Callable
    learn: Callable
    reward: Callable
    agent_sac: Callable = lambda cfg: cfg.sac
    absorbing: Callable = lambda cfg: False
    asks: Callable = lambda cfg: True


class Carry(NamedTuple):
    """Everything a run carries between chunks, each leaf with a leading seed axis."""

    loop: LoopState
    model: Any
    prefs: PrefData
    key: jax.Array
    queries: jax.Array


def init_carry(keys: jax.Array, learner: Learner, env: Env, params, cfg, start=None) -> Carry:
    """Every seed's fresh carry (``keys [S]``); ``start``: see :func:`~mindgap.algorithms.sac_loop.loop_init`."""
    d, a = dims(env)

    def one(k):
        model, k_loop, k_run = learner.init(k, env, cfg)
        loop = loop_init(k_loop, env, params, learner.agent_sac(cfg), cfg.total_steps, start)
        prefs = prefs_init(max(cfg.queries, 1), cfg.segment, d, a, absorbing=learner.absorbing(cfg))
        return Carry(loop, model, prefs, k_run, jnp.zeros((), jnp.int32))

    return jax.vmap(one)(keys)


def _select_one(c: Carry, w: WorldArgs, learner: Learner, env: Env, cfg):
    model, seg_a, seg_b, (key, k_t, k_r) = learner.select(c.model, c.loop.replay, c.key, w, env, cfg)
    return c._replace(model=model, key=key), seg_a, seg_b, k_t, k_r


def _learn_one(c: Carry, seg_a, seg_b, labels, answered, k_r, w: WorldArgs, learner: Learner, env: Env, cfg):
    """Keep the answers within the budget, fit the learner, relabel the buffer, count what was shown."""
    left = cfg.queries - c.queries
    prefs = c.prefs
    if learner.asks(cfg):
        answered = answered & (jnp.arange(cfg.per_round) < left)  # never past the budget
        prefs = prefs_add(prefs, seg_a, seg_b, labels, answered)
    model, info = learner.learn(c.model, prefs, c.loop.replay, k_r, w, env, cfg)
    reward_fn, reward_params, absorbing_fn = learner.reward(model, w, env, cfg)
    gamma = learner.agent_sac(cfg).gamma
    replay = relabel(c.loop.replay, reward_fn, reward_params, absorbing_fn=absorbing_fn, gamma=gamma)
    shown = jnp.minimum(cfg.per_round, left)
    c = c._replace(loop=c.loop._replace(replay=replay), model=model, prefs=prefs, queries=c.queries + shown)
    return c, info


@partial(jax.jit, static_argnames=("learner", "env", "cfg"))
def feedback_round(carry: Carry, w: WorldArgs, teacher, learner: Learner, env: Env, cfg):
    """One feedback round of every seed with a jittable teacher, in one program."""

    def one(c):
        c, seg_a, seg_b, k_t, k_r = _select_one(c, w, learner, env, cfg)
        labels = answered = None
        if learner.asks(cfg):
            labels, answered = teacher.answer(k_t, seg_a, seg_b)
        return _learn_one(c, seg_a, seg_b, labels, answered, k_r, w, learner, env, cfg)

    return jax.vmap(one)(carry)


@partial(jax.jit, static_argnames=("learner", "env", "cfg"))
def select_round(carry: Carry, w: WorldArgs, learner: Learner, env: Env, cfg):
    """The first half of a round with a host teacher: every seed's queries."""
    return jax.vmap(lambda c: _select_one(c, w, learner, env, cfg))(carry)


@partial(jax.jit, static_argnames=("learner", "env", "cfg"))
def learn_round(carry: Carry, seg_a, seg_b, labels, answered, k_r, w: WorldArgs, learner: Learner, env: Env, cfg):
    """The second half of a round with a host teacher: learn from what people answered."""

    def one(c, *xs):
        return _learn_one(c, *xs, w, learner, env, cfg)

    return jax.vmap(one)(carry, seg_a, seg_b, labels, answered, k_r)


def host_answers(teacher, seg_a, seg_b, queries, per_round: int, budget: int):
    """Ask a host teacher every seed's queries ``[S, K, L, ·]`` in one call.

    Only the queries the budget still allows are shown (``queries [S]``: pairs shown so far);
    the rest come back unanswered.

    Returns:
        (labels [S, K] float32, answered [S, K] bool), as JAX arrays.
    """
    seeds = queries.shape[0]
    ask = int(min(per_round, budget - int(queries.min())))

    def flat(seg):
        return type(seg)(
            *(None if x is None else np.asarray(x)[:, :ask].reshape(seeds * ask, *x.shape[2:]) for x in seg)
        )

    got, ok = teacher(flat(seg_a), flat(seg_b))
    labels = np.zeros((seeds, per_round), np.float32)
    answered = np.zeros((seeds, per_round), bool)
    labels[:, :ask] = np.asarray(got, np.float32).reshape(seeds, ask)
    answered[:, :ask] = np.asarray(ok, bool).reshape(seeds, ask)
    return jnp.asarray(labels), jnp.asarray(answered)


@partial(jax.jit, static_argnames=("sac", "env"))
def reset_critic(carry: Carry, sac: SACConfig, env: Env) -> Carry:
    """Re-initialise every seed's critic (PEBBLE, after pre-training)."""

    def one(c):
        key, k = jax.random.split(c.key)
        fresh = agent_init(k, env, sac)
        state = c.loop.sac
        params = state.params._replace(critic=fresh.params.critic, target=fresh.params.critic)
        state = state._replace(params=params, critic_opt=fresh.critic_opt)
        return c._replace(loop=c.loop._replace(sac=state), key=key)

    return jax.vmap(one)(carry)


def run_chunk_all(carry: Carry, w: WorldArgs, learner: Learner, env: Env, cfg, phase: str) -> Carry:
    """``cfg.chunk`` environment steps of every seed, SAC on the learner's reward in the ``train`` phase."""

    def one(c):
        reward_fn, reward_params, absorbing_fn = learner.reward(c.model, w, env, cfg)
        learned = phase == "train" and reward_fn is not None
        return run_chunk(
            c.loop,
            env,
            w.params,
            reward_params,
            n_steps=cfg.chunk,
            cfg=learner.agent_sac(cfg),
            phase=phase,
            reward_fn=reward_fn if learned else None,
            knn=cfg.knn,
            absorbing_fn=absorbing_fn if learned else None,
        )

    return carry._replace(loop=jax.vmap(one)(carry))


def which_seeds(seeds: int, seed_ids=None) -> tuple[int, ...]:
    """The seeds a run of ``seeds`` seeds trains: all of them, or ``seed_ids`` alone (a seed slice).

    Raises:
        ValueError: ``seed_ids`` empty, repeated, or outside ``0 … seeds − 1``.
    """
    if seed_ids is None:
        return tuple(range(seeds))
    ids = tuple(int(i) for i in seed_ids)
    if not ids or len(set(ids)) != len(ids) or not all(0 <= i < seeds for i in ids):
        raise ValueError(f"seed_ids must be distinct seeds among 0..{seeds - 1}, got {list(ids)}")
    return ids


def seed_keys(seed: int, seeds: int, ids: tuple[int, ...] | None = None) -> jax.Array:
    """Keys ``[len(ids)]`` of seeds ``ids`` of a run of ``seeds``: rows of ``split(key(seed), seeds)``,
    so that a seed has the same key whether it trains beside the others or alone (a seed slice)."""
    keys = jax.random.split(rng.key(seed), seeds)
    return keys if ids is None or tuple(ids) == tuple(range(seeds)) else keys[np.asarray(ids)]


def _evaluate(carry: Carry, world, episodes: int, step: int, base_seed: int, seeds: int, ids: tuple[int, ...]):
    keys = seed_keys(10_000 + base_seed + step, seeds, ids)
    actors = carry.loop.sac.params.actor
    return jax.vmap(lambda k, a: evaluate(k, world.env, a, world.params, episodes, world.horizon))(keys, actors)


def run_record(world, seeds: int, **extra) -> dict:
    """What a run folder's config.json records of the world and seeds (checked; resuming compares it), plus ``extra``."""
    if seeds < 1:
        raise ValueError("seeds must be at least 1")
    meta = {"world": world.name, "source": world.source, "world_hash": fingerprint(world.fingerprint_tree())}
    return {**meta, "seeds": seeds, **extra}


TEACHERS = ("biased", "unbiased", "true")
"""The simulated people who compare segments: r_H + log T_H under a belief (``biased``), r_H + log T
under the true dynamics (``unbiased``: the same person without a bias), r_H alone (``true``: B-Pref's)."""


def preference_teacher(world, cfg, seeds: int, teacher, belief: str | None, *, who: str):
    """The person who compares segments, and the run record naming them.

    Args:
        teacher: one of :data:`TEACHERS` or a host teacher (a callable with a ``name``); ``belief``
            names the biased person's belief (default the world's first).

    Returns:
        (a :class:`~mindgap.teachers.preference.PreferenceTeacher` or the host teacher, run record).
    """
    host = callable(teacher)
    if not host and teacher not in TEACHERS:
        raise ValueError(f"teacher must be one of {', '.join(TEACHERS)} or a host teacher, got {teacher!r}")
    if not host and cfg.method != "sac":
        check_env(world.env, density=teacher != "true", who=f"{who}'s simulated person", discrete_actions=True)
        if world.env.reward is None and teacher != "true":
            raise ValueError(
                f"{who}'s simulated person needs the env's reward function; this env has none (--teacher true sums the rewards it returns)"
            )
    meta = run_record(world, seeds, teacher=teacher.name if host else teacher, belief=belief)
    meta["config"] = cfg.as_dict()
    if host:
        return teacher, meta
    belief_params = {"biased": lambda: world.belief(belief), "unbiased": lambda: world.params}.get(
        teacher, lambda: None
    )()
    tcfg = dataclasses.replace(cfg.teacher, use_belief=teacher != "true")
    return PreferenceTeacher(world.params, belief_params, world.env, tcfg), meta


def run(
    world,
    learner: Learner,
    cfg,
    teacher,
    meta: dict,
    seeds: int,
    *,
    out=None,
    progress=True,
    fresh=False,
    oracle=None,
    seed_ids=None,
) -> dict:
    """Train ``seeds`` seeds of ``learner`` on ``world`` with ``teacher``; checkpoint to ``out``.

    Args:
        teacher: a jittable simulated person (``teacher.answer``), a host teacher (callable), or
            None when the method asks nobody (the SAC oracle).
        meta: the run record (:func:`run_record` plus the method's own entries).
        oracle: :attr:`WorldArgs.oracle`.
        seed_ids: train only these of the ``seeds`` seeds (a seed slice, recorded in the run record):
            each with the keys, evaluation keys and curve rows it has in the whole run (:func:`seed_keys`).

    Returns:
        dict with ``curve`` (rows of seed, step, return, queries), ``final_returns`` [seeds,
        episodes], ``paths`` (per seed, greedy rollouts through ``world.trace``), ``config``
        (the run record) and the final ``carry``; with ``seed_ids``, ``seeds`` is theirs.
    """
    ids = which_seeds(seeds, seed_ids)
    if seed_ids is not None:
        meta = {**meta, "seed_ids": list(ids)}
    if isinstance(world, GymWorld):  # gymnasium envs step on the host
        from .host_loop import run_host

        return run_host(
            world, learner, cfg, teacher, meta, seeds, out=out, progress=progress, fresh=fresh, oracle=oracle, ids=ids
        )
    cfg.check()
    check_env(world.env, who=cfg.method, discrete_actions=True)
    env, w = world.env, WorldArgs(world.params, world.obs_units(), oracle)
    carry = init_carry(seed_keys(cfg.seed, seeds, ids), learner, env, world.params, cfg)

    def chunk(c, phase, step):
        return run_chunk_all(c, w, learner, env, cfg, phase)

    def evaluate_at(c, episodes, step):
        return _evaluate(c, world, episodes, step, cfg.seed, seeds, ids)

    parts = (world, learner, cfg, teacher, meta, carry, w, chunk, evaluate_at)
    return drive(*parts, out=out, progress=progress, fresh=fresh, ids=ids)


def drive(
    world,
    learner: Learner,
    cfg,
    teacher,
    meta: dict,
    carry: Carry,
    w: WorldArgs,
    chunk,
    evaluate_at,
    *,
    out=None,
    progress=True,
    fresh=False,
    ids: tuple[int, ...] | None = None,
) -> dict:
    """The schedule every run follows, whatever steps its world: phases, rounds, evaluations, checkpoints.

    Args:
        carry: every seed's fresh carry (replaced by the checkpoint's when ``out`` holds one).
        chunk: ``(carry, phase, step) → carry`` after ``cfg.chunk`` environment steps from ``step``.
        evaluate_at: ``(carry, episodes, step) → (returns [S, E], observations [S, E, T+1, d], alive [S, E, T])``
            of greedy episodes (their keys derived from ``step``).
        ids: each carried seed's index in the whole run, as curve rows name it (default ``0 … S − 1``).

    Returns:
        the result dict of :func:`run`.
    """
    env, seeds = world.env, carry.queries.shape[0]
    ids = tuple(range(seeds)) if ids is None else ids
    host = teacher is not None and not hasattr(teacher, "answer")

    def one_round(c):
        if not host:
            return feedback_round(c, w, teacher, learner, env, cfg)[0]
        c, seg_a, seg_b, _, k_r = select_round(c, w, learner, env, cfg)
        labels, answered = host_answers(teacher, seg_a, seg_b, c.queries, cfg.per_round, cfg.queries)
        return learn_round(c, seg_a, seg_b, labels, answered, k_r, w, learner, env, cfg)[0]

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
        phase = phase_at(step, cfg)
        if teacher is not None and phase == "train":
            due = (step - first_feedback) % cfg.feedback_every == 0
            if due and int(carry.queries.min()) < cfg.queries:
                carry = one_round(carry)
            if step == first_feedback and cfg.reset_critic:
                carry = reset_critic(carry, learner.agent_sac(cfg), env)
        carry = chunk(carry, phase, step)
        step += cfg.chunk
        if step % cfg.eval_every == 0 or step == cfg.total_steps:
            rets = np.asarray(evaluate_at(carry, cfg.eval_episodes, step)[0])
            q = np.asarray(carry.queries)
            rows += [(ids[s], step, float(rets[s].mean()), int(q[s])) for s in range(seeds)]
            if bar is not None:
                bar.set_postfix(ret=f"{rets.mean():.1f}", queries=int(q.mean()))
        if out is not None:
            save_pytree(out / "checkpoint.npz", carry, step=step, rows=np.asarray(rows, np.float64).reshape(-1, 4))
        if bar is not None:
            bar.update(cfg.chunk)
    if bar is not None:
        bar.close()
    final, obs, alive = evaluate_at(carry, max(cfg.eval_episodes, 20), cfg.total_steps + 1)
    pos = world.trace(obs)
    paths = []
    for s in range(seeds):
        seed_paths = []
        for e in range(min(3, pos.shape[1])):
            n = int(np.asarray(alive[s, e]).sum())
            seed_paths.append(np.asarray(pos[s, e, : n + 1]))
        paths.append(seed_paths)
    return {"curve": rows, "final_returns": np.asarray(final), "paths": paths, "config": meta, "carry": carry}


def phase_at(step: int, cfg) -> str:
    """The schedule's phase at environment step ``step``: ``random``, ``explore`` or ``train``."""
    if step < cfg.sac.learning_starts:
        return "random"
    return "explore" if step < cfg.learning_steps() else "train"
