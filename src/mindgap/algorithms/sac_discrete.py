"""Soft actor-critic for a discrete action space (Christodoulou 2019, "Soft Actor-Critic for Discrete Action Settings").

The same update as :mod:`~mindgap.algorithms.sac` with the expectations over actions taken
exactly instead of by a reparameterised draw. The actor outputs the logits of a categorical
π(·|s) over the ``n`` actions; each critic outputs the ``n`` values Q_i(s, ·) at once:

* critic: ``y = c·r + γ(1 − terminal) Σ_a' π(a'|s') [min_i Q̄_i(s', a') − α log π(a'|s')]``,
  loss ``Σ_i mean (Q_i(s, a) − y)²`` (n-step targets and the absorbing-state bonus as in
  continuous SAC: both live in the batch's ``reward`` and ``discount``);
* actor: ``mean_s Σ_a π(a|s) [α log π(a|s) − min_i Q_i(s, a)]``;
* α: ``mean(−log α · (Σ_a π(a|s) log π(a|s) + H̄))``, H̄ the target entropy;
* targets: ``Q̄ ← (1 − τ) Q̄ + τ Q``.

Target entropy. Christodoulou sets H̄ = 0.98 log n, 98% of the uniform policy's entropy;
the tuned α then holds the policy close to uniform, which over-explores and learns slowly
(Zhou et al. 2022, "Revisiting Discrete Soft Actor-Critic", and cleanrl's Atari SAC, which
lowers the factor to 0.89). Here ``SACConfig.target_entropy = None`` means
:data:`TARGET_ENTROPY_SHARE` · log n, half the uniform entropy: on five actions a policy that
keeps about 0.8 nats, e.g. 75% on its preferred action. A fixed α (EPS's λ/s_H) ignores it.

Exploration. Actions are drawn from π (white noise): ``SACConfig.noise_color`` shapes the
noise of a continuous action and does not apply; the random phase draws actions uniformly.

Stored actions are float indices ``[1]`` (:mod:`~mindgap.models.categorical`), so replay
buffers, n-step sums, relabelling and the world's functions are those of continuous SAC.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import optax

from ..data.batch import Batch
from ..models.categorical import logits
from ..models.mlp import Params, init_mlp, init_stack, mlp
from .sac import SACConfig, SACParams, SACState, apply_update, entropy_coefficient, survival_charge

TARGET_ENTROPY_SHARE = 0.5
"""H̄ = this · log n when ``SACConfig.target_entropy`` is None (module docstring)."""


def target_entropy(cfg: SACConfig, n: int) -> float:
    """The entropy the tuned α aims for on ``n`` actions."""
    return TARGET_ENTROPY_SHARE * math.log(n) if cfg.target_entropy is None else float(cfg.target_entropy)


def discrete_sac_init(key: jax.Array, obs_dim: int, n: int, cfg: SACConfig) -> SACState:
    """Fresh networks (actor obs → n logits, two critics obs → n values) and optimiser states."""
    k_actor, k_critic = jax.random.split(key)
    actor = init_mlp(k_actor, (obs_dim, *cfg.hidden, n))
    critic = init_stack(k_critic, 2, (obs_dim, *cfg.hidden, n))
    log_alpha = jnp.log(jnp.asarray(cfg.alpha if cfg.alpha is not None else cfg.init_alpha, jnp.float32))
    opt = optax.adam(cfg.lr)
    params = SACParams(actor, critic, critic, log_alpha)
    return SACState(params, opt.init(actor), opt.init(critic), opt.init(log_alpha), jnp.zeros((), jnp.int32))


def all_q(critic: Params, obs: jax.Array) -> jax.Array:
    """Both critics' values of every action. obs [B, d] → [2, B, n]."""
    return jax.vmap(lambda p: mlp(p, obs))(critic)


def _taken(q: jax.Array, act: jax.Array) -> jax.Array:
    """Q of the stored actions ``act [B, 1]`` (float indices): [2, B, n] → [2, B]."""
    idx = jnp.round(act[:, 0]).astype(jnp.int32)
    return jnp.take_along_axis(q, idx[None, :, None], -1)[..., 0]


def discrete_sac_losses(params: SACParams, batch: Batch, cfg: SACConfig):
    """The critic and actor losses of one update at ``params``, and the critic's target ``y``."""
    alpha = entropy_coefficient(params.log_alpha, cfg)
    lp_next = logits(params.actor, batch.next_obs)
    v_next = jnp.sum(jnp.exp(lp_next) * (jnp.min(all_q(params.target, batch.next_obs), 0) - alpha * lp_next), -1)
    v_next = v_next - survival_charge(alpha, target_entropy(cfg, lp_next.shape[-1]), cfg)
    discount = cfg.gamma if batch.discount is None else batch.discount
    y = jax.lax.stop_gradient(cfg.reward_scale * batch.reward + discount * (1.0 - batch.terminal) * v_next)

    def critic_loss(critic):
        q = _taken(all_q(critic, batch.obs), batch.act)
        return jnp.sum(jnp.mean((q - y) ** 2, axis=-1)), q

    def actor_loss(actor, critic):
        lp = logits(actor, batch.obs)
        q = jax.lax.stop_gradient(jnp.min(all_q(critic, batch.obs), 0))
        expected_logp = jnp.sum(jnp.exp(lp) * lp, -1)  # −H(π(·|s))
        return jnp.mean(jnp.sum(jnp.exp(lp) * (alpha * lp - q), -1)), expected_logp

    return critic_loss, actor_loss, y


def discrete_sac_update(state: SACState, batch: Batch, key: jax.Array, cfg: SACConfig):
    """One update (critics, actor with the updated critics, α, targets); ``key`` is unused (the
    expectations over actions are exact). Returns (new state, metrics)."""
    del key
    n = state.params.actor[-1][1].shape[-1]
    critic_loss, actor_loss, _ = discrete_sac_losses(state.params, batch, cfg)
    return apply_update(state, critic_loss, actor_loss, target_entropy(cfg, n), cfg)
