"""The reshaped reward of EPS (Eq. 4.6) as a learned ``reward_fn`` for :func:`~mindgap.algorithms.sac_loop.run_chunk`.

Eq. 4.6 maximises ``E Σ_t γ^t [r_A + λ (u_H + H_T[s'|s,a] + H_π[a|s])]``. Its parts:

* **r_A + λ(u_H + H_T)** is a reward of the transition, :func:`eps_reward`, stored in the
  replay buffer and recomputed by :func:`~mindgap.data.replay.relabel` whenever u_H
  or T_A changes (§4.3.3: "we relabel the data samples every time u_H is updated").
* **λ H_π** is SAC's own entropy bonus: SAC maximises ``E Σ_t γ^t [c·r_t + α H_π(·|s_t)]``
  (its critic target subtracts ``α log π(a'|s')`` and its actor minimises
  ``α log π − Q``), so a fixed ``α`` gives Eq. 4.6's policy-entropy term with the reward
  scaled by ``c`` (``SACConfig.reward_scale``): :func:`eps_sac_config`. Both entropies, and
  the log π_H inside u_H, are densities over the squashed actions, so the tanh Jacobian of
  H_π and that of log π_H cancel as they do in the KL of Eq. 4.4. ``λ = 0`` means
  ``α = 0``: no entropy bonus at all, as Eq. 4.6 says.

Scale of H_π. In Eq. 4.2, u_H (= log T_H + log π_H) and H_π are two parts of one −KL, both
in nats, and the policy that maximises ``E log π_H + H_π`` is π_H itself. Standardising u_H
(below) divides its log π_H by the spread ``s_H`` of the person's per-step log-likelihood,
which preferences cannot reveal (Bradley–Terry answers fix no scale, and the ensemble's
rewards are bounded). Weighting H_π by λ would then make the KL-optimal policy π_H tempered
by ``s_H`` (each action dimension ``√s_H`` times wider), so H_π is weighted ``λ / s_H``:
``α = λ·c / s_H`` with one fixed ``s_H`` for every world (``EPSConfig.nats_per_unit``,
7 nats; how it was chosen: docs/methods/eps.md).

Scale of H_T. The same argument holds for the dynamics part of the KL: u_H's E log T_H and
H_T together are −KL(T_A ‖ T_H) (Eq. 4.4), so H_T is weighted ``λ / s_H`` as well
(``h_weight``): the reward's λ-term is ``λ (u_H + H_T / s_H)``, one scale for both halves of
one KL. Weighting H_T by λ while u_H's log T_H is divided by its spread counted the entropy
about seven times as much as the belief it is the other half of (docs/methods/eps.md).

Normalisation of u_H (§4.3.3: "we simply normalize the learned rewards"): Bradley–Terry
fixes u_H only up to an additive constant per step and a scale tied to the person's β,
so u_H is standardised — ``(û − m)/s`` with ``m, s`` the mean and standard deviation of
the ensemble's reward over the agent's filled replay buffer (:func:`u_norm_from_replay`),
recomputed after each fit of u_H, before relabelling. λ then weighs a signal of unit
spread against r_A, the same for every world. An :class:`ExactSurrogate` (the person's own
per-step score, an oracle ablation) is standardised over the buffer the same way.

Units of H_T: a differential entropy depends on the units of s'. Here it is measured in
the world's own units, those of its exact densities log T_A, log T_H
(:meth:`~mindgap.envs.interface.World.obs_units` converts from observation units; for the
terrain worlds, cells: T_A models the observation in [−1, 1]², ``size/2`` cells per unit).

The λ-term is a cost (``EPSConfig.offset = "cost"``, the default). Eq. 4.6's λ-term,
E[log T_H + log π_H] + H_T + H_π, is −KL(agent ‖ person) (Eqs. 4.2–4.4): at most 0, 0 only
where the agent does exactly what the person expects. Standardising u_H loses its constant,
and a constant per step decides, in a world whose episodes end, whether ending them pays:
centred over the buffer (``"centred"``), the term is zero-mean, a *bonus* wherever the person's
model rates a step above the buffer's average, and holding still in a well-predicted place
can beat finishing (docs/methods/eps.md). The cost form keeps the standardised scale and sets
the constant so that the term is ≤ 0 on every step of the buffer, as the KL it stands for:
u_H's offset makes the largest ``u_H + H_T / s_H`` over the buffer 0
(:func:`cost_offsets`), and the policy entropy's part, ``(H_π − H_π,max) / s_H`` with
H_π,max the entropy of a uniform policy (:func:`policy_entropy_max`), goes into the stored
reward as ``h_shift`` — SAC adds λ H_π / s_H itself (``α``), so the whole λ-term
``λ [u_H + (H_T + H_π − H_π,max) / s_H]`` is ≤ 0 on the buffer. ``"centred"`` is the
previous default, kept for comparison: u_H standardised to mean 0 and ``h_shift`` H_T's mean
over the buffer (:func:`entropy_mean_from_replay`); ``"none"`` centres u_H alone.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..data.replay import Replay, relabel
from ..envs.interface import Discrete, Env, World
from ..models.agent_dynamics import dynamics_entropy
from ..models.gaussian_dynamics import DynamicsModel
from ..models.mlp import Params
from ..models.reward_ensemble import absorbing_reward, ensemble_reward
from ..teachers.expectation import ExpectationTeacher, step_log_likelihood
from .sac import SACConfig


@partial(
    jax.tree_util.register_dataclass,
    data_fields=["world", "u_params", "u_mean", "u_std", "dynamics", "min_std", "h_shift", "h_weight", "lam", "units"],
    meta_fields=["env"],
)
@dataclasses.dataclass(frozen=True)
class EPSRewardParams:
    """What :func:`eps_reward` reads (a pytree: it is ``reward_params`` of ``run_chunk`` and ``relabel``).

    Attributes:
        world: the true world's params (r_A).
        u_params: the reward ensemble's members (u_H before normalisation), or an
            :class:`ExactSurrogate`.
        u_mean, u_std: normalisation of u_H (:func:`u_norm_from_replay`).
        dynamics: T_A.
        min_std: T_A's standard-deviation floor (``DynamicsConfig.min_std``).
        h_shift: subtracted from H_T (0: Eq. 4.6 as written).
        h_weight: the weight of H_T relative to u_H, 1/s_H (module docstring, "Scale of H_T").
        lam: λ, the reconciliation factor.
        units: [d] the world's units per observation unit, the units H_T is measured in
            (:meth:`~mindgap.envs.interface.World.obs_units`).
        env: the world's functions (static; ``env.reward`` is r_A).
    """

    world: Any
    u_params: Params  # or an ExactSurrogate
    u_mean: jax.Array
    u_std: jax.Array
    dynamics: DynamicsModel | None
    min_std: jax.Array
    h_shift: jax.Array
    h_weight: jax.Array
    lam: jax.Array
    units: jax.Array
    env: Env


def eps_reward_params(
    world: World,
    u_params: Params,
    dynamics: DynamicsModel,
    lam: float,
    *,
    min_std: float,
    u_norm: tuple = (0.0, 1.0),
    h_shift: float = 0.0,
    h_weight: float = 1.0,
) -> EPSRewardParams:
    """Assemble :class:`EPSRewardParams` for ``world`` (scalars become float32 leaves)."""

    def f(x):
        return jnp.asarray(x, jnp.float32)

    return EPSRewardParams(
        world.params,
        u_params,
        f(u_norm[0]),
        f(u_norm[1]),
        dynamics,
        f(min_std),
        f(h_shift),
        f(h_weight),
        f(lam),
        world.obs_units(),
        world.env,
    )


def world_reward(params: EPSRewardParams, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """r_A of transitions given as observations: [B, ·] → [B]."""
    return jax.vmap(params.env.reward, (0, 0, 0, None))(obs, act, next_obs, params.world)


class ExactSurrogate(NamedTuple):
    """u_H as the simulated person's own per-step ``log T_H + log π_H`` (each term floored at
    ``floor``), in place of the ensemble learned from answers: the oracle ablation of EPS
    (``EPSConfig.surrogate = "exact"``). It is what the answers are generated from (Eq. 4.2), so a
    run with it separates what learning u_H from preferences loses from what the objective does."""

    person: ExpectationTeacher
    floor: jax.Array


def raw_u(u_params, obs, act, next_obs) -> jax.Array:
    """u_H before standardisation: the ensemble's reward, or the person's own score
    (:class:`ExactSurrogate`). [B, ·] → [B]."""
    if isinstance(u_params, ExactSurrogate):
        return step_log_likelihood(u_params.person, obs, act, next_obs, u_params.floor)
    return ensemble_reward(u_params, obs, act, next_obs)


def normalised_u(params: EPSRewardParams, obs, act, next_obs) -> jax.Array:
    """u_H standardised (§4.3.3): [B, ·] → [B]."""
    return (raw_u(params.u_params, obs, act, next_obs) - params.u_mean) / params.u_std


def environment_entropy(params: EPSRewardParams, obs, act) -> jax.Array:
    """H_T[s'|s,a] of T_A in cells, less ``h_shift``: [B, ·] → [B]. Without T_A (``dynamics`` None: the
    person judges decisions alone, ``EPSConfig.judged``) the dynamics half of the KL is not in the
    objective and H_T counts 0."""
    if params.dynamics is None:
        return jnp.zeros(obs.shape[:-1], jnp.float32) - params.h_shift
    h = dynamics_entropy(params.dynamics, obs, act, params.min_std, params.units)
    return h - params.h_shift


def reshape(r_a: jax.Array, u_h: jax.Array, h_t: jax.Array, lam, h_weight=1.0) -> jax.Array:
    """r_A + λ (u_H + w·H_T): the part of Eq. 4.6 that is a reward (λ H_π is SAC's, see module docstring),
    with H_T on u_H's scale (``h_weight`` = 1/s_H, module docstring, "Scale of H_T")."""
    return r_a + lam * (u_h + h_weight * h_t)


def eps_reward(params: EPSRewardParams, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """The reward EPS stores for SAC: ``r_A + λ (u_H + H_T / s_H)`` (Eq. 4.6). obs, act, next_obs [B, ·] → [B].

    A module-level function, so that ``run_chunk(..., reward_fn=eps_reward)`` compiles once.
    """
    r_a = world_reward(params, obs, act, next_obs)
    u_h, h_t = normalised_u(params, obs, act, next_obs), environment_entropy(params, obs, act)
    return reshape(r_a, u_h, h_t, params.lam, params.h_weight)


def absorbing_u(params: EPSRewardParams, terminal_obs: jax.Array) -> jax.Array:
    """u_H of the absorbing state an ended episode enters, standardised as every step's: [B, d] → [B].

    The ensemble's learned ``r_abs`` (``EPSConfig.absorbing``); for an :class:`ExactSurrogate`, 0 — the
    person's own score counts nothing after a clip's end (its steps are masked)."""
    if isinstance(params.u_params, ExactSurrogate):
        raw = jnp.zeros(terminal_obs.shape[:-1], jnp.float32)
    else:
        raw = absorbing_reward(params.u_params, terminal_obs)
    return (raw - params.u_mean) / params.u_std


def eps_absorbing(params: EPSRewardParams, terminal_obs: jax.Array) -> jax.Array:
    """The λ-term of one absorbing step, ``λ [u_H,abs − H_shift / s_H]``: Eq. 4.6's with u_H its absorbing
    value and both entropies 0 (nothing is uncertain after the end), under the same constants as a lived
    step's. The ``absorbing_fn`` of :func:`~mindgap.data.replay.relabel`: a terminal transition gains
    ``γ x_abs / (1 − γ)``, so every constant of the λ-term is paid on the steps after an end as on the
    steps before it, and the offset (``EPSConfig.offset``) cannot make ending early pay or cost. r_A is 0
    there. [B, d] → [B]."""
    return params.lam * (absorbing_u(params, terminal_obs) - params.h_weight * params.h_shift)


def eps_sac_config(base: SACConfig, lam: float, nats_per_unit: float, policy_entropy: str = "lambda") -> SACConfig:
    """``base`` with Eq. 4.6's policy-entropy term λ·H_π as SAC's entropy coefficient, on the scale of the
    standardised u_H: λ · reward_scale / s_H (``s_H`` = ``nats_per_unit``; module docstring, "Scale of H_π").

    ``policy_entropy``: ``lambda`` — α is that alone, fixed (Eq. 4.6 as written: at λ = 0 no entropy
    term is left); ``sac`` — it is added to SAC's own α, tuned as ``base`` says (``alpha_extra``), so
    that at λ = 0 EPS is SAC on r_A. The term's per-step constant is the λ-term's (``h_shift``, the
    cost form), so SAC's ``survival_entropy`` stays ``paid``: ``neutral`` would charge α·H̄ a second time.
    """
    if lam < 0:
        raise ValueError(f"λ must be non-negative, got {lam}")
    if not nats_per_unit > 0:
        raise ValueError(f"nats_per_unit must be positive, got {nats_per_unit}")
    alpha = float(lam) * base.reward_scale / float(nats_per_unit)
    if policy_entropy == "sac":
        return dataclasses.replace(base, alpha_extra=alpha, survival_entropy="paid")
    return dataclasses.replace(base, alpha=alpha, survival_entropy="paid")


def _filled_stats(values: jax.Array, buf: Replay) -> tuple[jax.Array, jax.Array]:
    filled = jnp.arange(buf.capacity) < buf.size
    n = jnp.maximum(buf.size, 1)
    mean = jnp.sum(jnp.where(filled, values, 0.0)) / n
    var = jnp.sum(jnp.where(filled, (values - mean) ** 2, 0.0)) / n
    return mean, jnp.sqrt(var)


def u_norm_from_replay(u_params, buf: Replay, eps: float = 1e-6) -> tuple[jax.Array, jax.Array]:
    """(mean, std) of u_H (the ensemble's, or an :class:`ExactSurrogate`'s) over the filled part
    of the buffer; std at least ``eps``."""
    u = relabel(buf, raw_u, u_params).reward
    mean, std = _filled_stats(u, buf)
    return mean, jnp.maximum(std, eps)


def policy_entropy_max(env: Env) -> float:
    """H_π,max: the entropy of the uniform policy, the largest any policy has — ``a·log 2`` nats for
    SAC's squashed actions in [−1, 1]^a (the densities H_π is measured in), ``log n`` for n
    discrete actions."""
    space = env.action_space
    return float(np.log(space.n)) if isinstance(space, Discrete) else float(space.dim * np.log(2.0))


def cost_offsets(params: EPSRewardParams, buf: Replay, pi_max: float) -> tuple[jax.Array, jax.Array]:
    """``(u_mean, h_shift)`` that make the λ-term a cost over the filled buffer (module docstring).

    With ``params.u_mean, u_std`` the buffer's mean and spread of u_H and ``h_shift = 0``: the
    largest ``u_H + h_weight·H_T`` over the buffer, ``c``, moves u_H's offset to ``u_mean + u_std·c``
    (so that the largest is 0), and ``h_shift = pi_max`` (:func:`policy_entropy_max`) charges the
    policy entropy's ceiling, so that ``λ h_weight (H_π − pi_max) ≤ 0`` joins it.
    """
    base = dataclasses.replace(params, h_shift=jnp.zeros_like(params.h_shift))

    def term(p, obs, act, next_obs):
        return normalised_u(p, obs, act, next_obs) + p.h_weight * environment_entropy(p, obs, act)

    values = relabel(buf, term, base).reward
    filled = jnp.arange(buf.capacity) < buf.size
    top = jnp.max(jnp.where(filled, values, -jnp.inf))
    top = jnp.where(buf.size > 0, top, 0.0)
    return params.u_mean + params.u_std * top, jnp.asarray(pi_max, jnp.float32)


def entropy_mean_from_replay(params: EPSRewardParams, buf: Replay) -> jax.Array:
    """Mean H_T (cells, before ``h_shift``) over the filled part of the buffer: a value for ``h_shift``."""

    def h(p, obs, act, next_obs):
        del next_obs
        return environment_entropy(dataclasses.replace(p, h_shift=jnp.zeros_like(p.h_shift)), obs, act)

    return _filled_stats(relabel(buf, h, params).reward, buf)[0]
