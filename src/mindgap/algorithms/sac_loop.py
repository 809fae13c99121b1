"""SAC on a JAX world in one jitted program: ``lax.scan`` over environment steps and updates.

A chunk of training is :func:`run_chunk`: per step it acts (uniformly at random in the
``"random"`` phase, from the policy otherwise; with ``SACConfig.noise_color`` > 0 both draw
on one coloured-noise sequence per episode, :mod:`~mindgap.algorithms.colored_noise`),
steps the world, stores the transition with the reward the agent optimises (the world's,
or a learned model's), restarts finished episodes, and performs ``utd`` SAC updates (after every
``train_every``-th step of the chunk; none
in the ``"random"`` phase; with a k-nearest-neighbour state-entropy reward in the
``"explore"`` phase of PEBBLE, and added with a decaying weight to the reward in
``"train"`` when ``SACConfig.entropy_bonus`` > 0). The phase is static, so vmapping a
chunk over seeds never executes branches it does not need.

A learned reward with an absorbing state (Kostrikov et al. 2019; PEBBLE/DRLHP with
``absorbing``) passes ``absorbing_fn``: terminal transitions are then stored with the
bonus ``γ r_abs / (1 − γ)`` (:func:`~mindgap.data.replay.terminal_bonus`), the value of
the state the episode ends in, so arriving at the goal is not worth less than hovering
next to it. Other reward functions keep their own signature and need nothing new.

A world whose action space is :class:`~mindgap.envs.interface.Discrete` runs discrete SAC
(:mod:`~mindgap.algorithms.sac_discrete`, Christodoulou 2019) in the same loop: the env's
declared space picks the networks, the draw of an action and the update; actions are stored
as float indices ``[1]``, so the buffer, relabelling and evaluation are shared.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..data.batch import Batch
from ..data.replay import Replay, replay_add, replay_init, replay_sample, terminal_bonus
from ..envs.interface import Discrete, Env
from ..models.actor import greedy_action, sample_action
from ..models.categorical import greedy_categorical, sample_categorical
from .colored_noise import colored_noise
from .sac import SACConfig, SACState, sac_init, sac_update
from .sac_discrete import discrete_sac_init, discrete_sac_update

PHASES = ("random", "explore", "train")
BONUS_POOL = 256  # buffer states the training-time state-entropy bonus measures distances to


class LoopState(NamedTuple):
    """Everything a run carries between chunks (one seed; stack along axis 0 for many)."""

    sac: SACState
    replay: Replay
    env: object  # the world's state
    t: jax.Array  # steps taken in the current episode
    key: jax.Array
    steps: jax.Array
    noise: jax.Array  # [noise_length, a]: this episode's coloured noise ([0, a] with white noise)


def dims(env: Env) -> tuple[int, int]:
    """(observation, action) dimensions of ``env``, from its spaces."""
    return env.observation_space.dim, env.action_space.dim


def n_actions(env: Env) -> int:
    """The number of actions of a :class:`~mindgap.envs.interface.Discrete` action space; 0 for a Box."""
    return env.action_space.n if isinstance(env.action_space, Discrete) else 0


def agent_init(key: jax.Array, env: Env, cfg: SACConfig) -> SACState:
    """Fresh SAC networks for ``env``'s spaces: discrete SAC on a Discrete action space."""
    obs_dim, act_dim = dims(env)
    n = n_actions(env)
    return discrete_sac_init(key, obs_dim, n, cfg) if n else sac_init(key, obs_dim, act_dim, cfg)


def loop_init(key: jax.Array, env: Env, world_params, cfg: SACConfig, capacity: int, start=None) -> LoopState:
    """A seed's fresh loop; its world state ``env.reset``'s, or ``start(key)``'s for a world stepped elsewhere."""
    k_sac, k_env, k_run = jax.random.split(key, 3)
    obs_dim, act_dim = dims(env)
    coloured = cfg.noise_color > 0 and not n_actions(env)
    return LoopState(
        agent_init(k_sac, env, cfg),
        replay_init(capacity, obs_dim, act_dim),
        env.reset(k_env, world_params) if start is None else start(k_env),
        jnp.zeros((), jnp.int32),
        k_run,
        jnp.zeros((), jnp.int32),
        jnp.zeros((cfg.noise_length if coloured else 0, act_dim), jnp.float32),
    )


def state_entropy_reward(batch: Batch, pool: jax.Array, k: int) -> jax.Array:
    """PEBBLE's intrinsic reward: log(1 + distance to the k-th nearest neighbour) of each next state.

    Distances are to ``pool [M, d]`` (states drawn from the buffer); the reward is divided by
    its standard deviation over the batch so its scale does not depend on the world's size.
    """
    d = jnp.linalg.norm(batch.next_obs[:, None, :] - pool[None, :, :], axis=-1)
    r = jnp.log1p(kth_smallest(d, k + 1))  # k+1: a state can meet itself in the pool
    return r / (jnp.std(r) + 1e-6)


def bonus_weight(cfg: SACConfig, steps: jax.Array) -> jax.Array:
    """Weight of the training-time state-entropy bonus after ``steps`` environment steps: β₀ 2^(−steps/half-life)."""
    return cfg.entropy_bonus * 0.5 ** (steps / cfg.entropy_bonus_halflife)


def novelty_bonus(batch: Batch, pool: jax.Array, k: int, weight) -> jax.Array:
    """``weight`` × :func:`state_entropy_reward`, centred on its batch mean.

    Centred because a bonus that is positive on average pays for staying alive, and so for
    not ending the episode at the goal (the termination bias of Kostrikov et al. 2019).
    """
    novelty = state_entropy_reward(batch, pool, k)
    return weight * (novelty - novelty.mean())


def kth_smallest(d: jax.Array, k: int) -> jax.Array:
    """The k-th smallest distinct value of each row of ``d [B, M]``.

    k rounds of "take the minimum, mask it": O(k·M) per row. XLA's sort and top_k on CPU
    cost about 100× more at PEBBLE's sizes (256 × 1024), which made them dominate a step.
    """

    def body(_, carry):
        d, _ = carry
        m = d.min(-1)
        return jnp.where(d <= m[:, None], jnp.inf, d), m

    return jax.lax.fori_loop(0, k, body, (d, jnp.zeros(d.shape[0], d.dtype)))[1]


@partial(jax.jit, static_argnames=("env", "n_steps", "cfg", "phase", "reward_fn", "knn", "absorbing_fn"))
def run_chunk(
    ls: LoopState,
    env: Env,
    world_params,
    reward_params,
    *,
    n_steps: int,
    cfg: SACConfig,
    phase: str,
    reward_fn=None,
    knn: int = 5,
    absorbing_fn=None,
) -> LoopState:
    """``n_steps`` environment steps (and their updates) of one seed; vmap for many.

    Args:
        reward_params: parameters of ``reward_fn`` (ignored without one).
        reward_fn: ``reward_fn(reward_params, obs [B, d], act [B, a], next_obs [B, d]) → [B]``
            stored as the reward to optimise; None stores the world's own reward.
        absorbing_fn: ``absorbing_fn(reward_params, next_obs [B, d]) → r_abs [B]`` of a learned
            reward with absorbing states; terminal transitions then get ``γ r_abs / (1 − γ)``
            on top (``cfg.gamma``). Only with a ``reward_fn``.
    """
    if phase not in PHASES:
        raise ValueError(f"phase must be one of {PHASES}, got {phase!r}")
    n = n_actions(env)

    def body(ls: LoopState, i):
        key, k_act, k_env, k_reset, k_upd = jax.random.split(ls.key, 5)
        obs = env.observe(ls.env, world_params)
        noise, eps = ls.noise, None  # eps None: white noise
        if cfg.noise_color > 0 and not n:  # a fresh sequence at each episode start (and every noise_length steps)
            i = ls.t % cfg.noise_length
            fresh = colored_noise(jax.random.fold_in(k_act, 1), cfg.noise_color, cfg.noise_length, noise.shape[1])
            noise = jnp.where(i == 0, fresh, noise)
            eps = noise[i]
        if n:  # discrete: a draw of the categorical policy, or a uniform index
            if phase != "random":
                act = sample_categorical(ls.sac.params.actor, obs, k_act)[0]
            else:
                act = jax.random.randint(k_act, (1,), 0, n).astype(jnp.float32)
        elif phase != "random":
            act = sample_action(ls.sac.params.actor, obs, k_act, eps)[0]
        elif eps is None:
            act = jax.random.uniform(k_act, (noise.shape[1],), minval=-1.0, maxval=1.0)
        else:
            act = jnp.tanh(eps)
        out = env.step(k_env, ls.env, act, world_params)
        next_obs = env.observe(out.state, world_params)
        if reward_fn is None:
            r = out.reward
        else:
            r = reward_fn(reward_params, obs[None], act[None], next_obs[None])[0]
            if absorbing_fn is not None:
                r_abs = absorbing_fn(reward_params, next_obs[None])[0]
                r = r + jnp.where(out.terminated, terminal_bonus(r_abs, cfg.gamma), 0.0)
        replay = replay_add(ls.replay, obs, act, next_obs, out.reward, r, out.terminated, ls.t)
        done = out.terminated | out.truncated
        state = jax.tree.map(lambda a, b: jnp.where(done, a, b), env.reset(k_reset, world_params), out.state)
        sac = ls.sac
        if phase != "random":
            sac = _maybe_update(sac, i, cfg, lambda s: sac_updates(s, replay, k_upd, ls.steps, cfg, phase, knn, bool(n)))
        t = jnp.where(done, 0, ls.t + 1)
        return LoopState(sac, replay, state, t, key, ls.steps + 1, noise), None

    # the step's index within the chunk: the same for every seed, so under vmap the update's cond stays a branch
    steps = jnp.arange(n_steps) if cfg.train_every > 1 else None
    ls, _ = jax.lax.scan(body, ls, steps, length=n_steps)
    return ls


def _maybe_update(sac: SACState, i, cfg: SACConfig, update) -> SACState:
    """``update(sac)`` after every ``cfg.train_every``-th step of a chunk (``i``: the step's index in it)."""
    if cfg.train_every == 1:
        return update(sac)
    return jax.lax.cond((i + 1) % cfg.train_every == 0, update, lambda s: s, sac)


def sac_updates(
    sac: SACState, replay: Replay, key: jax.Array, steps, cfg: SACConfig, phase: str, knn: int, discrete: bool = False
) -> SACState:
    """``cfg.utd`` SAC updates on minibatches of ``replay`` (a ``lax.scan``), after ``steps`` environment steps;
    discrete SAC's updates with ``discrete``.

    In the ``explore`` phase on PEBBLE's state-entropy reward (one step, no n-step sums); in
    ``train`` on the stored reward with n-step targets and, with ``cfg.entropy_bonus``, the
    decaying novelty bonus on the first step of each target.
    """

    def update(sac, k):
        k_batch, k_pool, k_sac = jax.random.split(k, 3)
        if phase == "explore":  # the intrinsic reward belongs to one step: no n-step sums
            batch = replay_sample(replay, k_batch, cfg.batch_size)
            pool = replay_sample(replay, k_pool, 1024).next_obs
            batch = batch._replace(reward=state_entropy_reward(batch, pool, knn))
        else:
            batch = replay_sample(replay, k_batch, cfg.batch_size, cfg.n_step, cfg.gamma)
            if cfg.entropy_bonus > 0:  # on the first step of an n-step target
                pool = replay_sample(replay, k_pool, BONUS_POOL).next_obs
                batch = batch._replace(reward=batch.reward + novelty_bonus(batch, pool, knn, bonus_weight(cfg, steps)))
        return (discrete_sac_update if discrete else sac_update)(sac, batch, k_sac, cfg)[0], None

    return jax.lax.scan(update, sac, jax.random.split(key, cfg.utd))[0]


def _greedy(actor, obs):
    return greedy_action(actor, obs)


def greedy_policy(env: Env):
    """The deterministic policy ``(actor, obs) → action`` evaluation uses on ``env``: tanh of the
    Gaussian's mean, or the most probable of a discrete space's actions."""
    return greedy_categorical if n_actions(env) else _greedy


def evaluate(key: jax.Array, env: Env, actor, world_params, episodes: int, horizon: int):
    """Greedy-policy rollouts under the world's true reward.

    Returns:
        (returns [episodes], observations [episodes, T+1, d], alive [episodes, T]).
    """
    obs, rew, alive = rollouts(key, env, world_params, greedy_policy(env), actor, episodes, horizon)
    return rew.sum(-1), obs, alive


@partial(jax.jit, static_argnames=("env", "policy", "count", "horizon"))
def rollouts(key: jax.Array, env: Env, params, policy, policy_params, count: int, horizon: int):
    """``count`` episodes of ``horizon`` steps of ``policy(policy_params, obs) → action``.

    An episode that ends early stays where it ended, earning nothing more.

    Returns:
        (observations [count, T+1, d], rewards [count, T], alive [count, T] — the step happened).
    """

    def one(k):
        k0, k1 = jax.random.split(k)
        s0 = env.reset(k0, params)

        def body(carry, kk):
            s, done = carry
            out = env.step(kk, s, policy(policy_params, env.observe(s, params)), params)
            nxt = jax.tree.map(lambda a, b: jnp.where(done, a, b), s, out.state)
            r = jnp.where(done, 0.0, out.reward)
            return (nxt, done | out.terminated | out.truncated), (env.observe(nxt, params), r, ~done)

        _, (obs, rew, alive) = jax.lax.scan(body, (s0, jnp.zeros((), bool)), jax.random.split(k1, horizon))
        return jnp.concatenate([env.observe(s0, params)[None], obs]), rew, alive

    return jax.vmap(one)(jax.random.split(key, count))
