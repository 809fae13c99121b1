"""PrefBias's two Bayesian networks: the reward r_w(s, a) and the person's belief f_φ(s' | s, a) (§3.3.3.1).

* **Reward** r_w: a Bayesian MLP (s, a) → ℝ, soft-bounded as ``B · tanh(x / B)`` with
  ``B =`` :data:`~mindgap.models.reward_ensemble.REWARD_BOUND`, the bound of PEBBLE's
  ensemble too (:func:`~mindgap.models.reward_ensemble.soft_bound`), so the two methods
  are compared on equal terms.
* **Absorbing states** (Kostrikov et al. 2019, as the engine's reward ensemble,
  :mod:`~mindgap.models.reward_ensemble`): r_w also holds a reward ``r_abs(s_T)`` for the
  absorbing state an episode enters at its terminal state s_T, a Bayesian linear head on
  the ensemble's radial basis features of s_T (:func:`~mindgap.models.reward_ensemble.absorbing_features`)
  bounded like the step reward. Without it a segment that ends in a pit early is a
  *shorter* sum of step rewards and looks cheap to the learner whenever those are negative.
  The weights are then :class:`RewardWeights`; without absorbing states they are the MLP's
  parameters alone (the structure of run folders from before absorbing states), and every
  function here takes either.
* **Belief** f_φ: a Bayesian MLP of the architecture of the agent's dynamics model f_ψ
  (:mod:`~mindgap.models.gaussian_dynamics`): two heads, the mean and the standard
  deviation of a Gaussian on the next state's displacement, read through f_ψ's
  normalisation. Because the architectures match, ψ can be the centre of the prior p(φ).

**Local disturbances** (``PrefBiasConfig.stay_local``, worlds of at most three observation
dimensions): f_φ's weights are then :class:`BeliefWeights`, the MLP and the weights of radial
basis bumps over the observation (:func:`stay_features`) added to the stay logit and to the raw
scale of a move. The belief is f_ψ's network plus a disturbance of how often the robot fails to
move and of how noisy a move is, place by place; their prior is centred on 0, so f_φ starts at
f_ψ exactly.

A Gaussian cannot hold the point mass of a stuck or bumped step that the terrain worlds
have; the scale floor (``min_std``) keeps the density of such steps finite. With
``PrefBiasConfig.stay_head`` both f_ψ and f_φ have a third head, the probability of not
moving at all (:func:`~mindgap.models.gaussian_dynamics.with_stay`), and such steps are
scored by it instead.

Each network is evaluated with fixed parameters: the posterior mean, or one draw of all
weights from :func:`~mindgap.models.bayes.sample_params` — for the ELBO, one draw per
preference, shared by all 2×L steps of its two segments (:func:`draw_per_pair`), so that
the Monte Carlo estimate is of E_q log p(d | w, φ) as Eq. 3.3 writes it. (The local
reparameterisation trick, a fresh draw per transition, estimates a different objective:
each step of one segment would see another reward function.)

**Units.** f_φ reads and writes observations; the person's log T_H is a density in the world's
own units (cells on the terrain worlds). ``log_unit`` (Σ log of the world's units per
observation unit, :meth:`~mindgap.envs.interface.World.obs_units`) states f_φ's density of a
move in the world's units (:func:`~mindgap.models.gaussian_dynamics.next_state_log_prob`), so
that the person's own belief is a member of f_φ's family with the same score. Without it a
move is scored Σ log c_i nats higher against a stay than the person scores it (3.2 nats on
the 14×7-cell nav1-v1).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .bayes import Gaussian, sample_params
from .gaussian_dynamics import Norm, gaussian_head, has_stay_head, next_state_log_prob, normalise_input
from .mlp import Params, init_mlp, mlp
from .reward_ensemble import RBF_GAIN, absorbing_features, rbf_count, soft_bound


def reward_sizes(obs_dim: int, act_dim: int, hidden: tuple[int, ...]) -> tuple[int, ...]:
    return (obs_dim + act_dim, *hidden, 1)


class RewardWeights(NamedTuple):
    """The weights of r_w with absorbing states: ``net`` the MLP's layers, ``absorb [M]`` the absorbing head."""

    net: Params
    absorb: jax.Array


def reward_weights_init(
    key: jax.Array, obs_dim: int, act_dim: int, hidden: tuple[int, ...], absorbing: bool, single: bool = False
):
    """A random MLP; with ``absorbing`` as :class:`RewardWeights` with a head of zeros on :data:`RBF_PER_AXIS`^d
    features (one absorbing state per terminal state), or with ``single`` on the constant feature (one for all).

    The MLP is the same for the same key either way; r_abs starts at 0 everywhere.
    """
    net = init_mlp(key, reward_sizes(obs_dim, act_dim, hidden))
    return RewardWeights(net, jnp.zeros(1 if single else rbf_count(obs_dim))) if absorbing else net


def _net(params) -> Params:
    return params.net if isinstance(params, RewardWeights) else params


def reward_value(params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """r_w(s, a) for fixed weights (:class:`RewardWeights` or the MLP's alone): [..., d], [..., a] → [...]."""
    return soft_bound(mlp(_net(params), jnp.concatenate([obs, act], -1))[..., 0])


def _head_size(params) -> int:
    return params.absorb.shape[-1] if isinstance(params, RewardWeights) else 0


def absorbing_value(params, terminal_obs: jax.Array) -> jax.Array:
    """r_abs(s_T) for fixed weights: [..., d] → [...]; zeros without an absorbing head.

    At the posterior mean it is the engine's ``absorbing_fn`` (:func:`~mindgap.data.replay.relabel`,
    :func:`~mindgap.algorithms.sac_loop.run_chunk`), read at the state a terminal transition enters.
    """
    m = _head_size(params)
    if m == 0:
        return jnp.zeros(terminal_obs.shape[:-1])
    return soft_bound(absorbing_features(terminal_obs, m) @ params.absorb)


def posterior_reward(params, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """The reward the agent optimises: r_w at the posterior mean ``params = q(w).mean``. [B, ·] → [B].

    Has the signature of the engine's ``reward_fn`` (:func:`~mindgap.data.replay.relabel`,
    :func:`~mindgap.algorithms.sac_loop.run_chunk`).
    """
    del next_obs
    return reward_value(params, obs, act)


class BeliefWeights(NamedTuple):
    """The weights of f_φ with local disturbances: ``net`` the MLP's layers (f_ψ's architecture),
    ``stay [M]`` the weights of :func:`stay_features` added to the stay logit, ``noise [M]`` those
    added to the raw scale of every axis (how noisy a move looks, place by place; [0]: none)."""

    net: Params
    stay: jax.Array
    noise: jax.Array


def belief_weights_init(net: Params, obs_dim: int, local: bool, noise: bool = False):
    """f_φ's weights from an MLP of f_ψ's architecture; with ``local`` a stay disturbance of zeros, and
    with ``noise`` also a noise disturbance of zeros (empty without: f_φ = the MLP exactly either way);
    without ``local`` the MLP's parameters alone."""
    if not local:  # a world of more dimensions than RBF_MAX_DIM has no bumps to count
        return net
    m = rbf_count(obs_dim)
    return BeliefWeights(net, jnp.zeros(m), jnp.zeros(m if noise else 0))


def belief_net(params) -> Params:
    """The MLP part of f_φ's weights (all of them without a local stay disturbance)."""
    return params.net if isinstance(params, BeliefWeights) else params


STAY_GAIN = RBF_GAIN
"""Height of each bump of :func:`stay_features` (the absorbing heads' gain): a step of Adam then moves the
stay logit about as far as it moves the MLP's outputs; with unit-height bumps the fit is held back by its
step size, not by the answers (docs/experiments/identifiability.md, "The belief posterior"). The prior is stated per unit of height
(:func:`~mindgap.algorithms.prefbias_inference.belief_prior_scales` divides by the gain), so the gain
changes the pace of the fit and not the model."""


def stay_features(obs: jax.Array, m: int) -> jax.Array:
    """Gaussian bumps of height :data:`STAY_GAIN` on a grid over the observation (the radial basis grid of
    the absorbing heads, :func:`~mindgap.models.reward_ensemble.absorbing_features`): ``[..., m]``.

    Their weights are the local disturbance of f_φ's stay logit: each moves it near one place only,
    so a person's belief that the robot gets stuck *here* (nav1's ice) is not spread to places where
    the answers say little (the floor beside it, on which r_w absorbs any per-step constant).
    """
    return absorbing_features(obs, m) * (STAY_GAIN / RBF_GAIN)


def _raw(params, norm: Norm, obs, act) -> jax.Array:
    """f_φ's output: the MLP's, its stay logit and raw scales moved by the local disturbances when it has them."""
    raw = mlp(belief_net(params), normalise_input(norm, obs, act))
    if isinstance(params, BeliefWeights):
        d, phi = obs.shape[-1], stay_features(obs, params.stay.shape[-1])
        if params.noise.shape[-1]:  # static: an empty noise disturbance is none
            raw = raw.at[..., d : 2 * d].add((phi @ params.noise)[..., None])
        raw = raw.at[..., -1].add(phi @ params.stay)
    return raw


def belief_predict(params, norm: Norm, obs: jax.Array, act: jax.Array, min_std: float):
    """Mean and standard deviation of the next state (of a move) under f_φ with fixed weights: ([..., d], [..., d])."""
    return gaussian_head(_raw(params, norm, obs, act), norm, obs, min_std)


def belief_log_prob(params, norm: Norm, obs, act, next_obs, min_std: float, log_unit=0.0) -> jax.Array:
    """log f_φ(s' | s, a) with fixed weights (with a stay head, the mixture's), a move's density
    in the units ``log_unit`` says (module docstring, "Units"): [...]."""
    return next_state_log_prob(_raw(params, norm, obs, act), norm, obs, next_obs, min_std, log_unit)


def belief_stay_prob(params, norm: Norm, obs, act) -> jax.Array:
    """f_φ's probability of not moving at all (the stay head; NaN for a network without one): [...]."""
    raw = _raw(params, norm, obs, act)
    if not has_stay_head(raw, obs):
        return jnp.full(raw.shape[:-1], jnp.nan)
    return jax.nn.sigmoid(raw[..., -1])


def draw_per_pair(post: Gaussian, key: jax.Array, pairs: int):
    """``pairs`` independent draws of all weights from q (:func:`~mindgap.models.bayes.sample_params`),
    stacked along a leading axis: one function per preference."""
    return jax.vmap(lambda k: sample_params(post, k))(jax.random.split(key, pairs))
