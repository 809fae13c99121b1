"""The engine's schedule on gymnasium worlds: the envs step on the host, everything else is jitted.

:func:`run_host` is :func:`~mindgap.algorithms.engine.run` for a
:class:`~mindgap.envs.gym_world.GymWorld`: the same phases (``random`` → ``explore`` →
``train``), feedback rounds (the engine's own jitted :func:`~mindgap.algorithms.engine.feedback_round`,
or :func:`~mindgap.algorithms.engine.select_round` / :func:`~mindgap.algorithms.engine.learn_round`
with a host teacher), evaluations, curve rows, run record, checkpoints and result dict. Only
the environment differs: one gymnasium env per seed, stepped in numpy.

Per environment step there is one compiled dispatch, vmapped over seeds (:func:`advance`): it
stores the transition in the seed's replay buffer (a :class:`~mindgap.data.replay.Replay`
pytree kept on the device and donated, so feedback rounds relabel it in place), performs
``utd`` SAC updates (a ``lax.scan``; after every ``train_every``-th step of a chunk, a second
compiled program without them in between), and draws the action of the next step with the updated
actor. That is the order of Stable-Baselines3/sbx with ``train_freq=1, gradient_steps=utd``
(act, step, store, update; the next action sees every update so far), and the update itself
is :mod:`~mindgap.algorithms.sac_loop`'s, including its explore-phase k-NN state-entropy
reward, n-step targets, training-time entropy bonus and coloured action noise. On an update step
with a large buffer (:data:`STORE_APART_BYTES`) the transition is stored by a dispatch of its own
(:func:`store`) first: in one program XLA fuses the store into the minibatch's gathers and then
copies the buffer's columns to keep the old rows for them, every update step.

Checkpoints hold every seed's learner state and replay buffer; gymnasium's env states cannot
be saved, so a resumed run starts fresh episodes (seeded by the step it resumes at).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..data.replay import replay_add, terminal_bonus
from ..envs.interface import Env, check_env
from ..models.actor import greedy_action, sample_action
from .colored_noise import colored_noise
from .engine import Carry, Learner, WorldArgs, drive, init_carry, phase_at, seed_keys, which_seeds
from .sac import SACConfig
from .sac_loop import LoopState, sac_updates


def _act(ls: LoopState, cfg: SACConfig, phase: str):
    """The action at ``ls.env`` (a seed's observation), as :func:`~mindgap.algorithms.sac_loop.run_chunk` draws it."""
    key, k_act = jax.random.split(ls.key)
    noise, eps = ls.noise, None
    if cfg.noise_color > 0:
        i = ls.t % cfg.noise_length
        fresh = colored_noise(jax.random.fold_in(k_act, 1), cfg.noise_color, cfg.noise_length, noise.shape[1])
        noise = jnp.where(i == 0, fresh, noise)
        eps = noise[i]
    if phase != "random":
        act = sample_action(ls.sac.params.actor, ls.env, k_act, eps)[0]
    elif eps is None:
        act = jax.random.uniform(k_act, (noise.shape[1],), minval=-1.0, maxval=1.0)
    else:
        act = jnp.tanh(eps)
    return ls._replace(key=key, noise=noise), act


@partial(jax.jit, static_argnames=("cfg", "phase"))
def first_action(loop: LoopState, cfg: SACConfig, phase: str):
    """Every seed's action at its current observation (a run's or a resumed run's first step)."""
    return jax.vmap(lambda ls: _act(ls, cfg, phase))(loop)


STORE_APART_BYTES = 4 << 20
"""From this many bytes of replay buffer (all seeds' columns together), an update step stores its
transition by a dispatch of its own (:func:`store`) before :func:`advance` updates and acts.

Why: in one program XLA's CPU compiler fuses the buffer's write into the gathers of the update's
minibatch and then copies the columns those gathers read (the next observations, the rewards, the
terminal flags) so that the fused gathers can read the rows the write replaced: two copies of
each, every update step, whatever the batch. On the gym preset's hopper (300,000 transitions, 34.6 MiB,
128 × 128, an update every second step) that is 2.7 ms a step against 1.5 ms stored apart, the same
networks bit for bit; with 20,000 and 60,000 transitions (2.3 and 6.9 MiB) the two are within 1%
(``benchmarks/host_loop_store.py``; docs/benchmarks.md, "The replay buffer's copies"). The results do
not depend on it: the same stores, gathers and updates in the same order."""


def _store_one(ls: LoopState, model, w: WorldArgs, a, o2, r_env, term, *, learner: Learner, env: Env, cfg, phase):
    """One seed's replay buffer with the step's transition stored (its reward the learned one in ``train``)."""
    reward_fn, reward_params, absorbing_fn = learner.reward(model, w, env, cfg)
    r = r_env
    if phase == "train" and reward_fn is not None:
        r = reward_fn(reward_params, ls.env[None], a[None], o2[None])[0]
        if absorbing_fn is not None:
            gamma = learner.agent_sac(cfg).gamma
            r = r + jnp.where(term, terminal_bonus(absorbing_fn(reward_params, o2[None])[0], gamma), 0.0)
    return replay_add(ls.replay, ls.env, a, o2, r_env, r, term, ls.t)


@partial(jax.jit, static_argnames=("learner", "env", "cfg", "phase"), donate_argnames=("loop",))
def store(loop: LoopState, model, w: WorldArgs, act, next_obs, env_reward, terminated, *, learner, env, cfg, phase):
    """Every seed's transition stored in its buffer, nothing else (:data:`STORE_APART_BYTES`); then
    :func:`advance` with ``stored=True``."""

    def one(ls, model, a, o2, r_env, term):
        return _store_one(ls, model, w, a, o2, r_env, term, learner=learner, env=env, cfg=cfg, phase=phase)

    return loop._replace(replay=jax.vmap(one)(loop, model, act, next_obs, env_reward, terminated))


def store_apart(loop: LoopState) -> bool:
    """Whether update steps store their transition by a dispatch of their own (:data:`STORE_APART_BYTES`)."""
    return sum(x.nbytes for x in jax.tree.leaves(loop.replay)) >= STORE_APART_BYTES


@partial(
    jax.jit,
    static_argnames=("learner", "env", "cfg", "phase", "next_phase", "update", "stored"),
    donate_argnames=("loop",),
)
def advance(
    loop: LoopState,
    model,
    w: WorldArgs,
    act,
    next_obs,
    env_reward,
    terminated,
    truncated,
    reset_obs,
    *,
    learner: Learner,
    env: Env,
    cfg,
    phase: str,
    next_phase: str,
    update: bool = True,
    stored: bool = False,
):
    """Store every seed's transition (unless ``stored``: :func:`store` did), update its SAC (unless
    ``update`` is off: the steps between updates of ``SACConfig.train_every``), and draw its next
    action (all ``[S, ·]``).

    ``reset_obs``: the observation the next step starts from (a fresh episode's where the
    step ended one, else ``next_obs``).
    """
    sac_cfg = learner.agent_sac(cfg)

    def one(ls: LoopState, model, a, o2, r_env, term, trunc, o_reset):
        kw = dict(learner=learner, env=env, cfg=cfg, phase=phase)
        replay = ls.replay if stored else _store_one(ls, model, w, a, o2, r_env, term, **kw)
        key, k_upd = jax.random.split(ls.key)
        sac = ls.sac
        if phase != "random" and update:
            sac = sac_updates(sac, replay, k_upd, ls.steps, sac_cfg, phase, cfg.knn)
        done = term | trunc
        t = jnp.where(done, 0, ls.t + 1)
        ls = LoopState(sac, replay, o_reset, t, key, ls.steps + 1, ls.noise)
        return _act(ls, sac_cfg, next_phase)

    return jax.vmap(one)(loop, model, act, next_obs, env_reward, terminated, truncated, reset_obs)


@jax.jit
def _greedy(actors, obs):
    return jax.vmap(greedy_action)(actors, obs)


def evaluate_host(world, actors, episodes: int, seed: int, ids: tuple[int, ...] | None = None):
    """Greedy rollouts of every seed's actor on fresh gymnasium envs, ``horizon`` steps at most.

    Episode ``e`` of the seed whose index in the whole run is ``i`` (``ids``, default ``0 … S − 1``)
    starts from ``world.make(seed + i · episodes + e)``, however many seeds are evaluated.

    Returns:
        (returns [S, E], observations [S, E, T+1, d], alive [S, E, T]); an ended episode stays put.
    """
    seeds = jax.tree.leaves(actors)[0].shape[0]
    ids = range(seeds) if ids is None else ids
    made = (world.make(seed + i * episodes + e) for i in ids for e in range(episodes))
    envs, first = zip(*made, strict=True)
    obs = np.stack(first).reshape(seeds, episodes, -1)
    path, rews, alive = [obs], [], []
    done = np.zeros(seeds * episodes, bool)
    for _ in range(world.horizon):
        act = np.asarray(_greedy(actors, jnp.asarray(obs))).reshape(seeds * episodes, -1)
        nxt, rew = obs.reshape(seeds * episodes, -1).copy(), np.zeros(seeds * episodes)
        alive.append(~done)
        for i in np.flatnonzero(~done):
            o, r, term, trunc, _ = envs[i].step(world.to_env(act[i]))
            nxt[i], rew[i], done[i] = np.asarray(o, np.float32).reshape(-1), r, term or trunc
        obs = nxt.reshape(seeds, episodes, -1)
        path.append(obs)
        rews.append(rew.reshape(seeds, episodes))
    for e in envs:
        e.close()
    alive = np.stack(alive, -1).reshape(seeds, episodes, -1)
    return np.sum(rews, 0), np.stack(path, 2), alive


class _Envs:
    """One gymnasium env per seed (``ids``: the seeds' indices in the whole run, each env made with
    ``seed + index``), with its current observation; every env restarts when its episode ends."""

    def __init__(self, world, ids: tuple[int, ...], seed: int):
        self.world = world
        self.envs, first = zip(*(world.make(seed + i) for i in ids), strict=True)
        self.obs = np.stack(first)

    def step(self, act: np.ndarray):
        """Step every env with the agent's ``act [S, a]``: (next_obs, reward, terminated, truncated, reset_obs)."""
        n = len(self.envs)
        nxt, start = np.empty_like(self.obs), np.empty_like(self.obs)
        rew, term, trunc = np.zeros(n, np.float32), np.zeros(n, bool), np.zeros(n, bool)
        for i, e in enumerate(self.envs):
            o, rew[i], term[i], trunc[i], _ = e.step(self.world.to_env(act[i]))
            nxt[i] = start[i] = np.asarray(o, np.float32).reshape(-1)
            if term[i] or trunc[i]:
                start[i] = np.asarray(e.reset()[0], np.float32).reshape(-1)
        self.obs = start
        return nxt, rew, term, trunc, start

    def close(self):
        for e in self.envs:
            e.close()


def run_host(
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
    ids: tuple[int, ...] | None = None,
) -> dict:
    """:func:`~mindgap.algorithms.engine.run` on a gym world (same arguments, same result dict; ``ids``:
    the seeds of the ``seeds`` that train, :func:`~mindgap.algorithms.engine.which_seeds`).

    The schedule is the engine's (:func:`~mindgap.algorithms.engine.drive`); only the steps and
    the evaluations differ. A run resumed from ``out`` continues every seed's learner and buffer
    but starts fresh episodes: gymnasium env states are not saved.
    """
    cfg.check()
    check_env(world.env, who=cfg.method)
    env, w = world.env, WorldArgs(world.params, world.obs_units(), oracle)
    sac_cfg = learner.agent_sac(cfg)
    d = env.observation_space.dim
    ids = which_seeds(seeds) if ids is None else ids
    keys = seed_keys(cfg.seed, seeds, ids)
    carry = init_carry(keys, learner, env, None, cfg, start=lambda k: jnp.zeros(d))  # loop.env: the observation
    live = {}  # the envs and the next action, made at the first chunk (after any checkpoint is read)

    def chunk(c: Carry, phase: str, step: int) -> Carry:
        if "envs" not in live:
            live["envs"] = _Envs(world, ids, cfg.seed * 1000 + 7919 * step)  # fresh episodes, also on resuming
            zero = jnp.zeros(len(ids), jnp.int32)
            loop = c.loop._replace(env=jnp.asarray(live["envs"].obs), t=zero)
            loop, live["act"] = first_action(loop, sac_cfg, phase)
            c = c._replace(loop=loop)
        envs, act, loop = live["envs"], live["act"], c.loop
        apart = phase != "random" and store_apart(loop)
        kw = dict(learner=learner, env=env, cfg=cfg, phase=phase)
        for i in range(cfg.chunk):
            nxt, rew, term, trunc, start = envs.step(np.asarray(act))
            update = (i + 1) % sac_cfg.train_every == 0
            if stored := apart and update:
                loop = store(loop, c.model, w, act, nxt, rew, term, **kw)
            loop, act = advance(
                loop, c.model, w, act, nxt, rew, term, trunc, start,
                next_phase=phase_at(step + i + 1, cfg), update=update, stored=stored, **kw,
            )  # fmt: skip
        live["act"] = act
        return c._replace(loop=loop)

    def evaluate_at(c: Carry, episodes: int, step: int):
        return evaluate_host(world, c.loop.sac.params.actor, episodes, 10_000 + cfg.seed + step, ids)

    try:
        parts = (world, learner, cfg, teacher, meta, carry, w, chunk, evaluate_at)
        return drive(*parts, out=out, progress=progress, fresh=fresh, ids=ids)
    finally:
        if "envs" in live:
            live["envs"].close()
