"""Soft actor-critic (Haarnoja et al. 2018) as pure functions: ``sac_init``, ``sac_update``, ``sample_action``.

Twin critics with Polyak-averaged targets, a tanh-squashed Gaussian actor, and a fixed or
automatically tuned entropy coefficient α (target entropy −dim(A)). One update:

* critic: ``y = c·r + γ(1 − terminal)(min_i Q̄_i(s', a') − α log π(a'|s'))``, ``a' ~ π(·|s')``;
  ``c`` the reward scale (1 by default); with n-step targets ``r`` is the discounted sum of
  up to n rewards of one episode, ``s'`` the state after the last of them and γ becomes γ^m;
  loss ``Σ_i mean (Q_i(s, a) − y)²``; a terminal transition does not bootstrap, and the value
  of a learned reward's absorbing state (Kostrikov et al. 2019) is already in its stored
  ``r`` (:func:`~mindgap.data.replay.terminal_bonus`), so the update needs nothing for it;
* actor: ``mean(α log π(ã|s) − min_i Q_i(s, ã))``, ``ã ~ π(·|s)`` reparameterised;
* α: ``mean(−log α · (log π(ã|s) + target_entropy))``;
* targets: ``Q̄ ← (1 − τ) Q̄ + τ Q``.

Every function is jittable and vmappable (seeds stack along a leading axis); the training
loops that step JAX worlds inside ``lax.scan`` are in :mod:`~mindgap.algorithms.sac_loop`,
and a host loop (gymnasium) calls :func:`sac_update` directly.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax

from ..data.batch import Batch
from ..models.actor import sample_action
from ..models.mlp import Params, init_mlp, init_stack, mlp


@dataclasses.dataclass(frozen=True)
class SACConfig:
    """Hyperparameters of SAC (defaults as in Stable-Baselines3 where it has one)."""

    hidden: tuple[int, ...] = (256, 256)
    """Hidden layer widths of the actor and of each critic."""
    lr: float = 3e-4
    """Adam step size for actor, critics and α."""
    gamma: float = 0.99
    """Discount."""
    tau: float = 0.005
    """Polyak factor of the target critics."""
    batch_size: int = 256
    """Transitions per update."""
    utd: int = 1
    """Updates per environment step (update-to-data ratio)."""
    train_every: int = 1
    """Environment steps between updates (Stable-Baselines3's ``train_freq``): the ``utd`` updates
    follow every ``train_every``-th step of a chunk, so 2 with ``utd`` 1 is half an update per step.
    Counted from each chunk's start, so a run's chunks are a multiple of it."""
    alpha: float | None = None
    """Fixed entropy coefficient; None tunes it automatically."""
    init_alpha: float = 1.0
    """Starting α when it is tuned."""
    learning_starts: int = 1000
    """Environment steps of uniformly random actions before the first update."""
    target_entropy: float | None = None
    """Entropy the tuned α aims for; None means −dim(A), the usual choice."""
    n_step: int = 1
    """Environment steps summed into each critic target (n-step returns, within one episode);
    1 is plain SAC. Longer targets carry a small per-step signal (the terrain worlds'
    progress term) past the critic's noise."""
    reward_scale: float = 1.0
    """Factor on the reward in the critic's target (Haarnoja et al. 2018a); the terrain worlds'
    ±100 terminal rewards make the critic's targets large and its greedy policy unstable."""
    noise_color: float = 0.0
    """Exponent β of the 1/f^β spectrum of the noise in the actions that collect data
    (:mod:`~mindgap.algorithms.colored_noise`): 0 is SAC's white noise, 1 pink noise
    (Eberhard et al. 2023), 2 red. The random phase then acts with ``tanh`` of the noise
    instead of uniformly. Updates are unaffected."""
    noise_length: int = 128
    """Steps of one coloured-noise sequence: one is drawn at each episode start (and every
    ``noise_length`` steps of a longer episode)."""
    entropy_bonus: float = 0.0
    """Weight β₀ of a state-entropy bonus added to the reward in training updates (JAX
    worlds' loop only): PEBBLE's k-nearest-neighbour reward, kept on with a weight that
    halves every ``entropy_bonus_halflife`` environment steps (as in RE3, Seo et al. 2021),
    centred on its batch mean.
    It draws the agent to states its buffer holds few of until the task's reward takes over;
    0 switches it off."""
    entropy_bonus_halflife: int = 10_000
    """Environment steps over which the state-entropy bonus's weight halves."""
    survival_entropy: str = "paid"
    """What the soft value pays per step for the policy's entropy. ``paid`` (standard SAC): α·H(π(·|s'))
    in every step the episode lasts, so an episode that terminates early forgoes the entropy of all
    its later steps — the entropy term is an alive bonus, worth about α·H̄ a step to any policy
    that avoids ending its episode. ``neutral``: α·(H − H̄), the entropy above the target H̄ of the
    tuned α (:func:`entropy_target`), so that surviving a step is worth nothing on average and
    *when* an episode ends is decided by the reward (docs/experiments/driving.md, "The learners
    follow the answers"). A constant per step: where episodes never terminate it changes nothing."""

    alpha_extra: float = 0.0
    """A fixed amount added to the entropy coefficient, tuned or fixed: α = α_SAC + ``alpha_extra``. EPS's
    ``policy_entropy = "sac"`` puts Eq. 4.6's λ/s_H here, on top of SAC's own tuned α, so that at λ = 0
    EPS is SAC on r_A (docs/experiments/eps.md, "What λ = 0 means"). 0 leaves SAC as it is."""

    def __post_init__(self):
        if self.alpha_extra < 0:
            raise ValueError(f"SAC alpha_extra must be non-negative, got {self.alpha_extra}")
        if self.noise_color < 0:
            raise ValueError(f"SAC noise_color must be non-negative, got {self.noise_color}")
        if self.entropy_bonus < 0 or self.entropy_bonus_halflife < 1:
            raise ValueError("SAC entropy_bonus must be non-negative and its half-life at least 1 step")
        if self.noise_length < 2:
            raise ValueError(f"SAC noise_length must be at least 2, got {self.noise_length}")
        if self.survival_entropy not in SURVIVAL_ENTROPY:
            raise ValueError(
                f"SAC survival_entropy must be one of {', '.join(SURVIVAL_ENTROPY)}, got {self.survival_entropy!r}"
            )
        for name in ("utd", "train_every", "batch_size", "n_step"):
            if getattr(self, name) < 1:
                raise ValueError(f"SAC {name} must be at least 1, got {getattr(self, name)}")


SURVIVAL_ENTROPY = ("paid", "neutral")
"""The values of :attr:`SACConfig.survival_entropy`."""


class SACParams(NamedTuple):
    actor: Params
    critic: Params  # two critics stacked along axis 0
    target: Params
    log_alpha: jax.Array


class SACState(NamedTuple):
    params: SACParams
    actor_opt: optax.OptState
    critic_opt: optax.OptState
    alpha_opt: optax.OptState
    updates: jax.Array


def _optimiser(cfg: SACConfig) -> optax.GradientTransformation:
    return optax.adam(cfg.lr)


def sac_init(key: jax.Array, obs_dim: int, act_dim: int, cfg: SACConfig) -> SACState:
    """Fresh networks and optimiser states."""
    k_actor, k_critic = jax.random.split(key)
    actor = init_mlp(k_actor, (obs_dim, *cfg.hidden, 2 * act_dim))
    critic = init_stack(k_critic, 2, (obs_dim + act_dim, *cfg.hidden, 1))
    log_alpha = jnp.log(jnp.asarray(cfg.alpha if cfg.alpha is not None else cfg.init_alpha, jnp.float32))
    params = SACParams(actor, critic, critic, log_alpha)
    opt = _optimiser(cfg)
    return SACState(params, opt.init(actor), opt.init(critic), opt.init(log_alpha), jnp.zeros((), jnp.int32))


def q_values(critic: Params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """Both critics' values. obs [B, d], act [B, a] → [2, B]."""
    x = jnp.concatenate([obs, act], axis=-1)
    return jax.vmap(lambda p: mlp(p, x)[..., 0])(critic)


def entropy_coefficient(log_alpha: jax.Array, cfg: SACConfig) -> jax.Array:
    """α: exp(log α), tuned or fixed, plus ``cfg.alpha_extra`` (left out at 0, so the program is SAC's own)."""
    alpha = jnp.exp(log_alpha)
    return alpha + cfg.alpha_extra if cfg.alpha_extra else alpha


def sac_losses(params: SACParams, batch: Batch, key: jax.Array, cfg: SACConfig):
    """The three losses of one update at ``params`` (used by :func:`sac_update` and its tests)."""
    k_next, k_pi = jax.random.split(key)
    alpha = entropy_coefficient(params.log_alpha, cfg)
    a_next, logp_next = sample_action(params.actor, batch.next_obs, k_next)
    q_next = jnp.min(q_values(params.target, batch.next_obs, a_next), axis=0) - alpha * logp_next
    q_next = q_next - survival_charge(alpha, entropy_target(cfg, batch.act.shape[-1]), cfg)
    discount = cfg.gamma if batch.discount is None else batch.discount
    y = jax.lax.stop_gradient(cfg.reward_scale * batch.reward + discount * (1.0 - batch.terminal) * q_next)

    def critic_loss(critic):
        q = q_values(critic, batch.obs, batch.act)
        return jnp.sum(jnp.mean((q - y) ** 2, axis=-1)), q

    def actor_loss(actor, critic):
        a, logp = sample_action(actor, batch.obs, k_pi)
        q = jnp.min(q_values(critic, batch.obs, a), axis=0)
        return jnp.mean(alpha * logp - q), logp

    return critic_loss, actor_loss, y


def sac_update(state: SACState, batch: Batch, key: jax.Array, cfg: SACConfig):
    """One SAC update (critics, then actor with the updated critics, then α, then targets).

    Returns:
        (new state, metrics dict of scalars).
    """
    critic_loss, actor_loss, _ = sac_losses(state.params, batch, key, cfg)
    return apply_update(state, critic_loss, actor_loss, entropy_target(cfg, batch.act.shape[-1]), cfg)


def entropy_target(cfg: SACConfig, act_dim: int) -> float:
    """H̄, the entropy the tuned α aims for: ``cfg.target_entropy``, or −dim(A) (the usual choice)."""
    return -act_dim if cfg.target_entropy is None else cfg.target_entropy


def survival_charge(alpha: jax.Array, target: float, cfg: SACConfig) -> jax.Array:
    """What the soft value subtracts per step for ``cfg.survival_entropy``: 0 (``paid``) or α·H̄ (``neutral``)."""
    return alpha * target if cfg.survival_entropy == "neutral" else jnp.zeros_like(alpha)


def apply_update(state: SACState, critic_loss, actor_loss, target_entropy: float, cfg: SACConfig):
    """Steps the critics on ``critic_loss``, the actor on ``actor_loss`` (with the updated critics),
    α towards ``target_entropy`` (unless fixed), and the targets by Polyak averaging.

    The losses return ``(loss, aux)``: the critics' Q values and the actor's (expected) log π.
    Shared by continuous and discrete SAC (:mod:`~mindgap.algorithms.sac_discrete`).
    """
    opt = _optimiser(cfg)
    p = state.params
    (lc, q), gc = jax.value_and_grad(critic_loss, has_aux=True)(p.critic)
    upd, critic_opt = opt.update(gc, state.critic_opt, p.critic)
    critic = optax.apply_updates(p.critic, upd)
    (la, logp), ga = jax.value_and_grad(actor_loss, has_aux=True)(p.actor, critic)
    upd, actor_opt = opt.update(ga, state.actor_opt, p.actor)
    actor = optax.apply_updates(p.actor, upd)
    log_alpha, alpha_opt = p.log_alpha, state.alpha_opt
    if cfg.alpha is None:
        entropy_gap = jax.lax.stop_gradient(jnp.mean(logp) + target_entropy)
        g_alpha = -entropy_gap  # d/d log α of mean(−log α · (log π + H̄))
        upd, alpha_opt = opt.update(g_alpha, state.alpha_opt, p.log_alpha)
        log_alpha = optax.apply_updates(p.log_alpha, upd)
    target = jax.tree.map(lambda t, o: (1.0 - cfg.tau) * t + cfg.tau * o, p.target, critic)
    new = SACState(SACParams(actor, critic, target, log_alpha), actor_opt, critic_opt, alpha_opt, state.updates + 1)
    metrics = {
        "critic_loss": lc,
        "actor_loss": la,
        "alpha": entropy_coefficient(log_alpha, cfg),
        "q": jnp.mean(q),
        "entropy": -jnp.mean(logp),
    }
    return new, metrics
