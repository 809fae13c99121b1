"""An ensemble of reward networks learned from preferences (Eq. 3.1; Christiano et al. 2017, PEBBLE).

Each member maps (s, a) to a reward in (−1, 1) (tanh output, as in PEBBLE); a segment's
return is the masked sum over its steps, and the members are trained with the
Bradley–Terry cross-entropy ``−[y log σ(R̂₁ − R̂₂) + (1 − y) log σ(R̂₂ − R̂₁)]`` (labels
y ∈ {0, ½, 1}), each on its own minibatches. The agent optimises the members' mean.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax

from ..feedback.segments import Segments
from .mlp import Params, init_stack, mlp


@dataclasses.dataclass(frozen=True)
class RewardConfig:
    """Hyperparameters of the reward ensemble."""

    members: int = 3
    """Ensemble size."""
    hidden: tuple[int, ...] = (64, 64)
    """Hidden widths of each member."""
    lr: float = 3e-4
    """Adam step size."""
    batch_size: int = 64
    """Labelled pairs per gradient step (per member)."""
    updates: int = 200
    """Gradient steps after each round of queries."""


class RewardState(NamedTuple):
    params: Params  # members stacked along axis 0
    opt: optax.OptState


class PrefData(NamedTuple):
    """Answered queries, fixed capacity: seg_a, seg_b [Q, L, ·]; label [Q]; count."""

    seg_a: Segments
    seg_b: Segments
    label: jax.Array
    count: jax.Array


def reward_init(key: jax.Array, obs_dim: int, act_dim: int, cfg: RewardConfig) -> RewardState:
    params = init_stack(key, cfg.members, (obs_dim + act_dim, *cfg.hidden, 1))
    return RewardState(params, optax.adam(cfg.lr).init(params))


def member_rewards(params: Params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """Every member's reward. obs [..., d], act [..., a] → [E, ...]."""
    x = jnp.concatenate([obs, act], axis=-1)
    return jax.vmap(lambda p: jnp.tanh(mlp(p, x)[..., 0]))(params)


def ensemble_reward(params: Params, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """The reward the agent optimises: the members' mean. [B, ·] → [B]."""
    del next_obs
    return member_rewards(params, obs, act).mean(0)


def segment_returns(params: Params, seg: Segments) -> jax.Array:
    """Each member's return of each segment: [E, K]."""
    r = member_rewards(params, seg.obs, seg.act)  # [E, K, L]
    return jnp.sum(jnp.where(seg.mask, r, 0.0), axis=-1)


def preference_probs(params: Params, seg_a: Segments, seg_b: Segments) -> jax.Array:
    """Each member's P(a ≻ b) = σ(R̂_a − R̂_b): [E, K]."""
    return jax.nn.sigmoid(segment_returns(params, seg_a) - segment_returns(params, seg_b))


def bt_loss(params: Params, seg_a: Segments, seg_b: Segments, label: jax.Array, weight: jax.Array) -> jax.Array:
    """Bradley–Terry cross-entropy (Eq. 3.1) summed over members, averaged over weighted pairs."""
    logit = segment_returns(params, seg_a) - segment_returns(params, seg_b)  # [E, K]
    ce = -(label * jax.nn.log_sigmoid(logit) + (1 - label) * jax.nn.log_sigmoid(-logit))
    return jnp.sum(jnp.sum(ce * weight, axis=-1) / jnp.maximum(weight.sum(-1), 1.0))


def prefs_init(capacity: int, length: int, obs_dim: int, act_dim: int) -> PrefData:
    seg = Segments(
        jnp.zeros((capacity, length, obs_dim)),
        jnp.zeros((capacity, length, act_dim)),
        jnp.zeros((capacity, length, obs_dim)),
        jnp.zeros((capacity, length), bool),
    )
    return PrefData(seg, seg, jnp.zeros(capacity), jnp.zeros((), jnp.int32))


def prefs_add(data: PrefData, seg_a: Segments, seg_b: Segments, label: jax.Array, answered: jax.Array) -> PrefData:
    """Append the answered queries (skipped ones are dropped)."""
    cap = data.label.shape[0]
    slot = data.count + jnp.cumsum(answered) - 1
    slot = jnp.where(answered & (slot < cap), slot, cap)  # cap: out of range, dropped by the scatter
    def put(store, new):
        return jax.tree.map(lambda s, n: s.at[slot].set(n, mode="drop"), store, new)
    return PrefData(
        put(data.seg_a, seg_a),
        put(data.seg_b, seg_b),
        data.label.at[slot].set(label, mode="drop"),
        jnp.minimum(data.count + answered.sum(), cap),
    )


def train_reward(state: RewardState, data: PrefData, key: jax.Array, cfg: RewardConfig):
    """``cfg.updates`` Adam steps of every member on its own minibatches of the answered queries.

    Returns:
        (new state, final loss, accuracy of the ensemble mean on all answered queries).
    """
    opt = optax.adam(cfg.lr)
    n = jnp.maximum(data.count, 1)

    def one(st, k):
        idx = jax.random.randint(k, (cfg.members, cfg.batch_size), 0, n)  # per member
        def sel(tree):
            return jax.tree.map(lambda x: x[idx], tree)  # [E, B, ...]

        def loss(params):
            def member(p, a, b, y):
                return bt_loss(jax.tree.map(lambda x: x[None], p), a, b, y[None], jnp.ones((1, y.shape[0])))

            return jnp.sum(jax.vmap(member)(params, sel(data.seg_a), sel(data.seg_b), data.label[idx]))

        value, grads = jax.value_and_grad(loss)(st.params)
        upd, o = opt.update(grads, st.opt, st.params)
        return RewardState(optax.apply_updates(st.params, upd), o), value

    state, losses = jax.lax.scan(one, state, jax.random.split(key, cfg.updates))
    p = preference_probs(state.params, data.seg_a, data.seg_b).mean(0)
    seen = jnp.arange(data.label.shape[0]) < data.count
    hit = ((p > 0.5) == (data.label > 0.5)) | (data.label == 0.5)
    acc = jnp.sum(hit & seen) / n
    return state, losses[-1] / cfg.members, acc
