"""The agent's dynamics model f_ψ: a Gaussian one-step model learned from transitions (§3.3.3.4).

``f(s, a)`` is an MLP from the normalised input ``(s, a)`` to ``2d`` numbers: the mean and
a raw scale of the normalised *displacement* ``s' − s``. The distribution of the next
state is ``N(s + Δ̄ + σ_Δ m, (σ_Δ v)²)`` per coordinate, with ``v = floor + softplus(raw)``
and ``(Δ̄, σ_Δ)`` the displacement statistics of the data (:class:`Norm`). Predicting the
displacement rather than the state keeps the outputs of a small world's steps on a common
scale; the floor bounds the density where a step is deterministic (a bump into a wall).

The dissertation trains f_ψ with the L2 one-step loss; here it is the Gaussian negative
log-likelihood, whose mean head minimises the same squared error while the scale head
learns each place's noise — f_ψ then has exactly the two-headed architecture of the
belief f_φ, so it can be the centre of f_φ's prior (§3.3.3.1, "Prior"). Training holds out
a validation split, keeps the parameters of the best validation epoch and stops after
``patience`` epochs without improvement, all inside one jittable ``lax.while_loop``.

**Stay head** (optional, ``stay=True`` in :func:`dynamics_init`): one more output, the
logit of the probability that the agent does not move at all (s' = s exactly: stuck, or
bumped against a wall). The next state is then a mixture of a point mass at s and the
Gaussian above, the family of the terrain worlds' own transitions (:mod:`~mindgap.envs.terrain.dynamics`),
and :func:`next_state_log_prob` is the log of the point mass's probability for a stay and
``log(1 − p_stay)`` plus the Gaussian's log density for a move. A plain Gaussian has to
widen wherever stays are common to keep their density finite. Whether a model has the head
is read from its output width, so every function here takes either.

The belief network (:mod:`~mindgap.models.prefbias_nets`) reuses :class:`Norm`,
:func:`gaussian_head` and :func:`next_state_log_prob`, so f_ψ and f_φ read their outputs alike.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax

from ..data.stays import is_stay
from .categorical import action_input
from .mlp import Params, init_mlp, mlp


@dataclasses.dataclass(frozen=True)
class DynamicsConfig:
    """Training of f_ψ (hashable: a static argument of jitted code)."""

    hidden: tuple[int, ...] = (64, 64)
    """Hidden widths (the belief network f_φ uses the same)."""
    min_std: float = 0.01
    """Floor on the predicted standard deviation, in units of the displacement's spread."""
    lr: float = 1e-3
    """Adam step size."""
    batch_size: int = 256
    """Transitions per gradient step."""
    steps_per_epoch: int = 50
    """Gradient steps between two validation checks."""
    max_epochs: int = 40
    """Upper bound on epochs."""
    patience: int = 5
    """Stop after this many epochs without a better validation loss."""
    val_frac: float = 0.1
    """Share of the transitions held out for validation."""


class Norm(NamedTuple):
    """Input and output normalisation: x = (s, a) ↦ (x − in_mean) / in_std; Δ = out_mean + out_std · y."""

    in_mean: jax.Array
    in_std: jax.Array
    out_mean: jax.Array
    out_std: jax.Array


class DynamicsModel(NamedTuple):
    """A deterministic Gaussian dynamics model: MLP parameters and the normalisation they read."""

    params: Params
    norm: Norm


class DynamicsInfo(NamedTuple):
    """How a fit ended: best validation NLL (per transition, normalised units), epochs run."""

    val_nll: jax.Array
    epochs: jax.Array


def dynamics_sizes(obs_dim: int, act_dim: int, hidden: tuple[int, ...], stay: bool = False) -> tuple[int, ...]:
    """Layer widths of f_ψ and f_φ: (s, a) → (mean, raw scale) of the displacement, and with
    ``stay`` the logit of a stay."""
    return (obs_dim + act_dim, *hidden, 2 * obs_dim + int(stay))


def fit_norm(
    obs: jax.Array, act: jax.Array, next_obs: jax.Array, valid: jax.Array, act_width: int | None = None
) -> Norm:
    """Mean and spread of the inputs and of the displacement over the ``valid`` rows ([N, ·], [N]).

    ``act_width``: the number of actions of a discrete space whose stored indices ``act [N, 1]``
    enter one-hot (:func:`~mindgap.models.categorical.action_input`); None for continuous actions."""
    if act_width is not None:
        act = action_input(act, act_width)
    w = valid.astype(obs.dtype)[:, None]
    n = jnp.maximum(w.sum(), 1.0)

    def stats(x):
        mean = jnp.sum(x * w, 0) / n
        std = jnp.sqrt(jnp.sum(jnp.square(x - mean) * w, 0) / n)
        return mean, jnp.maximum(std, 1e-6)

    in_mean, in_std = stats(jnp.concatenate([obs, act], -1))
    out_mean, out_std = stats(next_obs - obs)
    return Norm(in_mean, in_std, out_mean, out_std)


def normalise_input(norm: Norm, obs: jax.Array, act: jax.Array) -> jax.Array:
    """The network's input: (s, a) standardised; a discrete action one-hot (``norm`` is that wide)."""
    act = action_input(act, norm.in_mean.shape[-1] - obs.shape[-1])
    return (jnp.concatenate([obs, act], -1) - norm.in_mean) / norm.in_std


def gaussian_head(raw: jax.Array, norm: Norm, obs: jax.Array, min_std: float) -> tuple[jax.Array, jax.Array]:
    """Network output ``raw [..., 2d (+1)]`` → mean and standard deviation of the next state (of a
    move, with a stay head), each [..., d]."""
    d = obs.shape[-1]
    mean = obs + norm.out_mean + norm.out_std * raw[..., :d]
    std = norm.out_std * (min_std + jax.nn.softplus(raw[..., d : 2 * d]))
    return mean, std


def log_density(mean: jax.Array, std: jax.Array, next_obs: jax.Array) -> jax.Array:
    """log N(next_obs; mean, diag std²) summed over coordinates: [..., d] → [...]."""
    z = (next_obs - mean) / std
    return jnp.sum(-0.5 * jnp.square(z) - jnp.log(std) - 0.5 * jnp.log(2 * jnp.pi), axis=-1)


def has_stay_head(raw: jax.Array, obs: jax.Array) -> bool:
    """Whether a network's output ``raw [..., 2d (+1)]`` has the stay logit (static: read from shapes)."""
    return raw.shape[-1] == 2 * obs.shape[-1] + 1


def with_stay(raw: jax.Array, obs: jax.Array, next_obs: jax.Array, log_move: jax.Array) -> jax.Array:
    """The mixture's log-probability from the Gaussian's log density ``log_move [...]``: unchanged
    without a stay head; with one, log p_stay where ``next_obs`` equals ``obs`` up to float rounding
    (:func:`~mindgap.data.stays.is_stay`) and ``log(1 − p_stay) + log_move`` elsewhere."""
    if not has_stay_head(raw, obs):
        return log_move
    logit = raw[..., -1]
    stay = is_stay(obs, next_obs)
    return jnp.where(stay, jax.nn.log_sigmoid(logit), jax.nn.log_sigmoid(-logit) + log_move)


def next_state_log_prob(
    raw: jax.Array, norm: Norm, obs: jax.Array, next_obs: jax.Array, min_std: float, log_unit=0.0
) -> jax.Array:
    """log f(s' | s, a) from a network's output ``raw``: [..., ·] → [...]; the Gaussian's log
    density of :func:`log_density`, through :func:`with_stay`.

    ``log_unit`` = Σ_i log c_i, with ``c_i`` the world's units per observation unit along
    axis i (:meth:`~mindgap.envs.interface.World.obs_units`): a density per observation
    unit^d is ``Π c_i`` times the density per world unit^d, so subtracting ``log_unit`` from
    a move's log density states it in the world's units, those of the person's log T_H. A
    stay is a probability and has no unit. 0 keeps observation units.
    """
    log_move = log_density(*gaussian_head(raw, norm, obs, min_std), next_obs) - log_unit
    return with_stay(raw, obs, next_obs, log_move)


def predict(model: DynamicsModel, obs: jax.Array, act: jax.Array, min_std: float) -> tuple[jax.Array, jax.Array]:
    """Mean and standard deviation of the next state under f_ψ: [..., d] each."""
    return gaussian_head(mlp(model.params, normalise_input(model.norm, obs, act)), model.norm, obs, min_std)


def dynamics_log_prob(model: DynamicsModel, obs, act, next_obs, min_std: float, log_unit=0.0) -> jax.Array:
    """log f_ψ(s' | s, a) (:func:`next_state_log_prob`, in the units ``log_unit`` says): [..., d] → [...]."""
    raw = mlp(model.params, normalise_input(model.norm, obs, act))
    return next_state_log_prob(raw, model.norm, obs, next_obs, min_std, log_unit)


def dynamics_init(
    key: jax.Array, obs_dim: int, act_dim: int, cfg: DynamicsConfig, norm: Norm, stay: bool = False
) -> DynamicsModel:
    """A fresh model; ``stay`` adds the stay head."""
    return DynamicsModel(init_mlp(key, dynamics_sizes(obs_dim, act_dim, cfg.hidden, stay)), norm)


def train_dynamics(
    key: jax.Array,
    obs: jax.Array,
    act: jax.Array,
    next_obs: jax.Array,
    valid: jax.Array,
    cfg: DynamicsConfig,
    init: DynamicsModel | None = None,
) -> tuple[DynamicsModel, DynamicsInfo]:
    """Fit f_ψ to the ``valid`` transitions by one-step Gaussian NLL with early stopping (§3.3.3.4).

    Jittable and vmappable (``cfg`` static). Rows of ``obs, act, next_obs [N, ·]`` with
    ``valid [N]`` False are ignored (an unfilled replay buffer). A share ``val_frac`` of the
    valid rows, drawn with ``key``, is held out; with none held out the training rows serve
    for validation.

    Args:
        init: warm start (its normalisation is kept); None starts from a fresh
            initialisation with the normalisation of these transitions.

    Returns:
        (the model of the best validation epoch, :class:`DynamicsInfo`).
    """
    k_split, k_init, k_loop = jax.random.split(key, 3)
    if init is None:
        init = dynamics_init(k_init, obs.shape[-1], act.shape[-1], cfg, fit_norm(obs, act, next_obs, valid))
    norm = init.norm
    held = valid & (jax.random.uniform(k_split, valid.shape) < cfg.val_frac)
    train = valid & ~held
    held = jnp.where(held.any(), held, train)
    n_train = jnp.maximum(train.sum(), 1)
    order = jnp.argsort(~train)  # the training rows first (stable)
    opt = optax.adam(cfg.lr)

    def nll(params, rows):
        raw = mlp(params, normalise_input(norm, obs[rows], act[rows]))
        mean, std = gaussian_head(raw, norm, obs[rows], cfg.min_std)
        # in normalised units, so that the loss does not depend on the size of the world (a
        # constant shift of the log density, which leaves the stay head's fit unchanged)
        log_move = log_density(mean / norm.out_std, std / norm.out_std, next_obs[rows] / norm.out_std)
        return -with_stay(raw, obs[rows], next_obs[rows], log_move)

    def val_loss(params):
        per = nll(params, jnp.arange(obs.shape[0]))
        return jnp.sum(jnp.where(held, per, 0.0)) / jnp.maximum(held.sum(), 1)

    def sgd_step(carry, k):
        params, opt_state = carry
        rows = order[jax.random.randint(k, (cfg.batch_size,), 0, n_train)]
        grads = jax.grad(lambda p: nll(p, rows).mean())(params)
        upd, opt_state = opt.update(grads, opt_state, params)
        return (optax.apply_updates(params, upd), opt_state), None

    def epoch(state):
        params, opt_state, best, best_val, bad, n, k = state
        k, k_epoch = jax.random.split(k)
        (params, opt_state), _ = jax.lax.scan(
            sgd_step, (params, opt_state), jax.random.split(k_epoch, cfg.steps_per_epoch)
        )
        v = val_loss(params)
        better = v < best_val
        best = jax.tree.map(lambda new, old: jnp.where(better, new, old), params, best)
        return params, opt_state, best, jnp.minimum(v, best_val), jnp.where(better, 0, bad + 1), n + 1, k

    def going(state):
        return (state[5] < cfg.max_epochs) & (state[4] < cfg.patience)

    p0 = init.params
    state = (p0, opt.init(p0), p0, val_loss(p0), jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32), k_loop)
    _, _, best, best_val, _, epochs, _ = jax.lax.while_loop(going, epoch, state)
    return DynamicsModel(best, norm), DynamicsInfo(best_val, epochs)
