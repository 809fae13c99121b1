"""The categorical policy network of discrete SAC (Christodoulou 2019): logits, draws, density, greedy action.

A model, not an algorithm: discrete SAC trains it (:mod:`~mindgap.algorithms.sac_discrete`),
the simulated person's expected policy π_H on a world with a discrete action space is one, and
the person's score reads its log-probabilities.

Actions are stored as the learners store every action, a float vector ``[1]`` holding the
index (the width :class:`~mindgap.envs.interface.Discrete` declares), so that replay buffers,
segments and the world's own functions take them unchanged; a network that takes an action
as input sees it one-hot (:func:`action_input`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .mlp import Params, mlp


def logits(actor: Params, obs: jax.Array) -> jax.Array:
    """Log-probabilities of every action. obs [..., d] → [..., n] (normalised: they log-sum-exp to 0)."""
    return jax.nn.log_softmax(mlp(actor, obs), axis=-1)


def sample_categorical(actor: Params, obs: jax.Array, key: jax.Array):
    """A draw of π(·|s) and its log-probability. obs [..., d] → (action [..., 1] float index, log π [...])."""
    lp = logits(actor, obs)
    a = jax.random.categorical(key, lp, axis=-1)
    return a[..., None].astype(jnp.float32), jnp.take_along_axis(lp, a[..., None], -1)[..., 0]


def greedy_categorical(actor: Params, obs: jax.Array) -> jax.Array:
    """The most probable action, as a float index [..., 1] (evaluation's deterministic policy)."""
    return jnp.argmax(mlp(actor, obs), axis=-1)[..., None].astype(jnp.float32)


def categorical_log_prob(actor: Params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """log π(a|s) of stored actions ``act [..., 1]`` (float indices): [...]."""
    idx = jnp.round(act[..., 0]).astype(jnp.int32)
    return jnp.take_along_axis(logits(actor, obs), idx[..., None], -1)[..., 0]


def action_input(act: jax.Array, width: int) -> jax.Array:
    """An action as a network's input of ``width`` numbers: ``act [..., a]`` itself when ``a == width``
    (continuous actions, unchanged), else the one-hot vector of the index ``act[..., 0]`` (a discrete
    action space, whose actions are stored as their index; ``width`` is the number of actions)."""
    if act.shape[-1] == width:
        return act
    return jax.nn.one_hot(jnp.round(act[..., 0]).astype(jnp.int32), width, dtype=act.dtype)
