"""A replay buffer as a pytree: fixed capacity, ring-ordered, relabelled in place.

Each transition keeps the observations and action that any learned reward needs, the
environment's own reward, the reward the agent currently optimises (``reward``:
the environment's for an oracle, a learned model's otherwise — :func:`relabel` rewrites
it), whether it ended the episode in a terminal state, and its step index within the
episode (segments for preference queries must not cross episodes).

Terminal transitions (goal, pit) and horizon truncations differ: ``terminal`` is set only
for the former, whose targets do not bootstrap. A learned reward with an absorbing state
(Kostrikov et al. 2019; :mod:`~mindgap.data.segments`) values the state after a
terminal transition at ``r_abs / (1 − γ)``, not 0; :func:`relabel` and the training loop
store that value in the reward of terminal transitions (:func:`terminal_bonus`), so the
critic's target ``r + γ (1 − terminal) V(s')`` becomes exactly ``r + γ r_abs / (1 − γ)``
there, n-step sums included, without a change to SAC.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .batch import Batch


class Replay(NamedTuple):
    """obs, next_obs [N, d]; act [N, a]; env_reward, reward [N]; terminal [N]; ep_step [N] (−1 when empty)."""

    obs: jax.Array
    act: jax.Array
    next_obs: jax.Array
    env_reward: jax.Array
    reward: jax.Array
    terminal: jax.Array
    ep_step: jax.Array
    ptr: jax.Array
    size: jax.Array

    @property
    def capacity(self) -> int:
        return self.obs.shape[-2]


def replay_init(capacity: int, obs_dim: int, act_dim: int) -> Replay:
    f = jnp.float32
    return Replay(
        obs=jnp.zeros((capacity, obs_dim), f),
        act=jnp.zeros((capacity, act_dim), f),
        next_obs=jnp.zeros((capacity, obs_dim), f),
        env_reward=jnp.zeros(capacity, f),
        reward=jnp.zeros(capacity, f),
        terminal=jnp.zeros(capacity, bool),
        ep_step=jnp.full(capacity, -1, jnp.int32),
        ptr=jnp.zeros((), jnp.int32),
        size=jnp.zeros((), jnp.int32),
    )


def replay_add(buf: Replay, obs, act, next_obs, env_reward, reward, terminal, ep_step) -> Replay:
    """Write one transition at the ring pointer (overwriting the oldest when full)."""
    i = buf.ptr
    return Replay(
        obs=buf.obs.at[i].set(obs),
        act=buf.act.at[i].set(act),
        next_obs=buf.next_obs.at[i].set(next_obs),
        env_reward=buf.env_reward.at[i].set(env_reward),
        reward=buf.reward.at[i].set(reward),
        terminal=buf.terminal.at[i].set(terminal),
        ep_step=buf.ep_step.at[i].set(ep_step),
        ptr=(i + 1) % buf.capacity,
        size=jnp.minimum(buf.size + 1, buf.capacity),
    )


def replay_sample(buf: Replay, key: jax.Array, batch_size: int, n_step: int = 1, gamma: float = 0.99) -> Batch:
    """Uniform minibatch (with replacement) of the stored transitions, with the ``reward`` column.

    With ``n_step > 1`` each sampled transition i is extended by the steps i+1, …, i+n−1 that
    follow it in the same episode and have already been stored (the episode may end, by
    termination or by the horizon, before that): the reward becomes Σ_k γ^k r_{i+k} over the
    m steps taken, the next observation and terminal flag those of the last one, and
    ``discount`` γ^m (n-step returns, Sutton & Barto 2018 §7.1; off-policy without correction,
    as in Rainbow and SB3).
    """
    idx = jax.random.randint(key, (batch_size,), 0, jnp.maximum(buf.size, 1))
    terminal = buf.terminal[idx].astype(jnp.float32)
    if n_step == 1:
        return Batch(buf.obs[idx], buf.act[idx], buf.reward[idx], buf.next_obs[idx], terminal)
    cap = buf.capacity
    newer = (buf.ptr - 1 - idx) % cap  # transitions stored after idx
    reward, last, going = buf.reward[idx], idx, ~buf.terminal[idx]
    steps = jnp.ones(batch_size, jnp.int32)
    for k in range(1, n_step):
        j = (idx + k) % cap
        going = going & (newer >= k) & (buf.ep_step[j] == buf.ep_step[idx] + k)
        reward = reward + jnp.where(going, gamma**k * buf.reward[j], 0.0)
        last = jnp.where(going, j, last)
        steps = steps + going
        going = going & ~buf.terminal[j]
    return Batch(
        buf.obs[idx],
        buf.act[idx],
        reward,
        buf.next_obs[last],
        buf.terminal[last].astype(jnp.float32),
        jnp.asarray(gamma, jnp.float32) ** steps,
    )


def terminal_bonus(r_abs: jax.Array, gamma: float) -> jax.Array:
    """What a terminal transition's reward gains under an absorbing-state reward ``r_abs``: ``γ r_abs / (1 − γ)``.

    The absorbing state earns ``r_abs`` at every step for ever, so its value is
    ``r_abs / (1 − γ)``, discounted once for the step into it (Kostrikov et al. 2019).
    """
    return gamma * r_abs / (1.0 - gamma)


def relabel(
    buf: Replay, reward_fn, reward_params, chunk: int = 4096, *, absorbing_fn=None, gamma: float | None = None
) -> Replay:
    """Recompute the ``reward`` column with ``reward_fn(reward_params, obs, act, next_obs)``.

    Only the reward column changes; everything else, the environment's reward included,
    stays as it was. Work goes in chunks so that large buffers do not need one huge batch.

    Args:
        absorbing_fn: ``absorbing_fn(reward_params, next_obs [B, d]) → r_abs [B]``, the learned
            reward of the absorbing state a terminal transition enters; terminal transitions
            then also get :func:`terminal_bonus` ``(r_abs, gamma)``. None (the default): no
            absorbing state.
        gamma: the agent's discount; required with ``absorbing_fn``.
    """
    n = buf.capacity
    pad = (-n) % chunk

    def split(x):
        return jnp.pad(x, [(0, pad)] + [(0, 0)] * (x.ndim - 1)).reshape(-1, chunk, *x.shape[1:])

    if absorbing_fn is not None and gamma is None:
        raise ValueError("relabel: an absorbing_fn needs the agent's gamma")

    def one(xs):
        r = reward_fn(reward_params, *xs[:3])
        if absorbing_fn is None:
            return r
        return r + jnp.where(xs[3], terminal_bonus(absorbing_fn(reward_params, xs[2]), gamma), 0.0)

    r = jax.lax.map(one, (split(buf.obs), split(buf.act), split(buf.next_obs), split(buf.terminal)))
    r = r.reshape(-1)[:n]
    filled = jnp.arange(n) < buf.size
    return buf._replace(reward=jnp.where(filled, r, buf.reward))
