"""PrefBias's two Bayesian networks: the reward r_w(s, a) and the person's belief f_φ(s' | s, a) (§3.3.3.1).

* **Reward** r_w: a Bayesian MLP (s, a) → ℝ, soft-bounded as ``B · tanh(x / B)`` with
  ``B =`` :data:`REWARD_BOUND` — linear over the range a step's reward and log-density
  differences take, but never so large that one unexplored corner dominates the agent's
  returns.
* **Belief** f_φ: a Bayesian MLP of the architecture of the agent's dynamics model f_ψ
  (:mod:`~mindgap.models.gaussian_dynamics`): two heads, the mean and the standard
  deviation of a Gaussian on the next state's displacement, read through f_ψ's
  normalisation. Because the architectures match, ψ can be the centre of the prior p(φ).

A Gaussian cannot hold the point mass of a stuck or bumped step that the terrain worlds
have; the scale floor (``min_std``) keeps the density of such steps finite.

Each network is evaluated either with the local reparameterisation trick (a sample per
transition, for the ELBO) or with fixed parameters (the posterior mean, or one draw of all
weights from :func:`~mindgap.models.bayes.sample_params`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..envs.terrain.dynamics import is_wall, move_model
from .bayes import Gaussian, bnn_local
from .gaussian_dynamics import Norm, gaussian_head, log_density, normalise_input
from .mlp import Params, mlp

REWARD_BOUND = 10.0
"""Soft bound B of the learned reward per step."""


def reward_sizes(obs_dim: int, act_dim: int, hidden: tuple[int, ...]) -> tuple[int, ...]:
    return (obs_dim + act_dim, *hidden, 1)


def _bound(raw: jax.Array) -> jax.Array:
    return REWARD_BOUND * jnp.tanh(raw[..., 0] / REWARD_BOUND)


def reward_value(params: Params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """r_w(s, a) for fixed weights ``params``: [..., d], [..., a] → [...]."""
    return _bound(mlp(params, jnp.concatenate([obs, act], -1)))


def reward_local(post: Gaussian, obs: jax.Array, act: jax.Array, key: jax.Array) -> jax.Array:
    """A draw of r_w(s, a), w ~ q(w), by local reparameterisation (one draw per row): [...]."""
    return _bound(bnn_local(post, jnp.concatenate([obs, act], -1), key))


def posterior_reward(params: Params, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """The reward the agent optimises: r_w at the posterior mean ``params = q(w).mean``. [B, ·] → [B].

    Has the signature of the engine's ``reward_fn`` (:func:`~mindgap.feedback.replay.relabel`,
    :func:`~mindgap.algorithms.sac_loop.run_chunk`).
    """
    del next_obs
    return reward_value(params, obs, act)


def belief_predict(params: Params, norm: Norm, obs: jax.Array, act: jax.Array, min_std: float):
    """Mean and standard deviation of the next state under f_φ with fixed weights: ([..., d], [..., d])."""
    return gaussian_head(mlp(params, normalise_input(norm, obs, act)), norm, obs, min_std)


def belief_log_prob(params: Params, norm: Norm, obs, act, next_obs, min_std: float) -> jax.Array:
    """log f_φ(s' | s, a) with fixed weights: [...]."""
    return log_density(*belief_predict(params, norm, obs, act, min_std), next_obs)


def belief_log_prob_local(post: Gaussian, norm: Norm, obs, act, next_obs, key: jax.Array, min_std: float):
    """A draw of log f_φ(s' | s, a), φ ~ q(φ), by local reparameterisation (one draw per row): [...]."""
    raw = bnn_local(post, normalise_input(norm, obs, act), key)
    return log_density(*gaussian_head(raw, norm, obs, min_std), next_obs)


CROSS_ACTIONS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))
"""The actions :func:`belief_noise_map` averages over: full pushes along each axis."""


def _cell_centres(world_params):
    h, w = world_params.grid.shape
    rows, cols = jnp.meshgrid(jnp.arange(h), jnp.arange(w), indexing="ij")
    return rows, cols, jnp.stack([cols, rows], -1).astype(jnp.float32) + 0.5  # [H, W, 2] (x, y)


def belief_noise_map(
    params: Params, norm: Norm, world_params, min_std: float, actions: jax.Array | None = None
) -> jax.Array:
    """The belief's predicted noise at each cell of a terrain world, for drawing it on the map.

    At every cell centre, the standard deviation f_φ predicts for the next position,
    converted from observation units to cells and averaged over the two axes and over
    ``actions`` [n, 2] (default :data:`CROSS_ACTIONS`). Comparable with the ``noise``
    column of a :class:`~mindgap.envs.terrain.Dynamics` table.

    Returns:
        [H, W] float, NaN on walls.
    """
    h, w = world_params.grid.shape
    actions = jnp.asarray(CROSS_ACTIONS if actions is None else actions, jnp.float32)
    rows, cols, pos = _cell_centres(world_params)
    scale = jnp.array([w, h], jnp.float32)
    obs = 2.0 * pos / scale - 1.0  # as envs.terrain.observe
    obs = jnp.broadcast_to(obs[:, :, None], (h, w, actions.shape[0], 2))
    act = jnp.broadcast_to(actions, obs.shape)
    _, std = belief_predict(params, norm, obs, act, min_std)  # [H, W, n, 2], observation units
    cells = (std * 0.5 * scale).mean((-1, -2))
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, cells)


def table_noise_map(world_params) -> jax.Array:
    """The noise scale σ(s) a dynamics table gives each cell centre (terrain noise plus the pit term).

    Pass a world's parameters under a person's belief (``world.belief(name)``) to draw that
    belief's noise next to :func:`belief_noise_map`, or to measure how far a learned belief is
    from it. Returns [H, W] in cells, NaN on walls.
    """
    rows, cols, pos = _cell_centres(world_params)
    sigma = jax.vmap(jax.vmap(lambda p: move_model(world_params, p, jnp.zeros(2))[1]))(pos)
    return jnp.where(is_wall(world_params, rows, cols), jnp.nan, sigma)
