"""An ensemble of reward networks learned from preferences (Eq. 3.1; Christiano et al. 2017, PEBBLE).

Each member maps (s, a) to a reward in (−B, B), ``B·tanh(x/B)`` with ``B =`` :data:`REWARD_BOUND`
(:func:`soft_bound`; PEBBLE's tanh output scaled); a segment's
return is the masked sum over its steps, and the members are trained with the
Bradley–Terry cross-entropy ``−[y log σ(R̂₁ − R̂₂) + (1 − y) log σ(R̂₂ − R̂₁)]`` (labels
y ∈ {0, ½, 1}), each on its own minibatches. The agent optimises the members' mean.

With absorbing states (``reward_init(..., absorbing=...)``; Kostrikov et al. 2019,
"Discriminator-Actor-Critic") each member also learns a reward ``r_abs`` (bounded alike)
for every step after a terminal transition, and a segment's return is
``Σ mask·r(s, a) + Σ absorbed·r_abs`` (:class:`~mindgap.data.segments.AbsorbingSegments`).
Why: when reaching the goal ends the episode, a segment that gets there is otherwise
shorter than one that hovers nearby, and with rewards bounded near the goal
the hovering segment can only score higher — the learned reward then teaches the agent
never to arrive (termination bias). With absorbing steps every segment has the same
length and the model learns what being done is worth; the agent's critic values the
absorbing state at ``r_abs / (1 − γ)`` (:func:`~mindgap.data.replay.terminal_bonus`).

DAC has one absorbing state (``single``: r_abs a learned constant). A world with both a
goal and pits needs more: with one shared state the pits, far more often reached by early
experience, pull r_abs below the step rewards and the goal becomes as unattractive as
without the treatment (measured on d1). So by default (``terminal``) each terminal state
has its own absorbing state, ``r_abs(s_T)`` a learned function of the state ``s_T`` the
episode ended in — the goal's absorbing state can then be good and a pit's bad. That
function is local, a linear layer on compactly supported radial basis features of
``s_T`` without a bias (:func:`absorbing_features`), so that it stays exactly 0 at
terminal states no segment has reached yet — a smooth head carries the pits' value over to a
goal not yet found, and the seeds that have not found it then avoid it (docs/experiments/pbrl.md,
"Absorbing states on d1").
Without absorbing states the parameters are the plain MLP stack, as before.

**The bound.** Every learned reward in mindgap, this ensemble's (PEBBLE, DRLHP, EPS's u_H) and
PrefBias's r_w (:mod:`~mindgap.models.prefbias_nets`), is soft-bounded by the same
:func:`soft_bound`, so that methods are compared on equal terms. B = 10 rather than PEBBLE's 1:
with a person who answers by Bradley–Terry with a finite β (Eq. 3.4) the score differences
are identified on their own scale, in nats, and a biased person's per-step score
r_H + log T_H ranges over several nats (a precise step under a belief with σ = 0.05 cells is
worth about +3); a bound of 1 cannot represent it, and where a learned reward sits at its
bound is then decided by the bound, not the answers (docs/experiments/identifiability.md).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax

from ..data.prefs import PrefData
from ..data.segments import Segments, absorbed_steps, terminal_obs
from .categorical import action_input
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
    params: Params  # members stacked along axis 0 (AbsorbingParams with an absorbing state)
    opt: optax.OptState


ABSORBING_STATES = ("terminal", "single")
"""How many absorbing states a learned reward has: one per terminal state (``terminal``) or one (``single``, DAC's)."""


class AbsorbingParams(NamedTuple):
    """Reward parameters with absorbing states: ``net`` the members' MLP stack, ``absorb`` their absorbing heads.

    ``absorb [E, M]`` are the weights of ``r_abs(s_T) = B·tanh(φ(s_T) · w / B)`` on the features
    φ of :func:`absorbing_features`: ``M = 1`` (``single``) is a constant feature, one learned
    constant per member; otherwise radial basis features of the terminal state.
    """

    net: Params
    absorb: jax.Array


REWARD_BOUND = 10.0
"""B, the soft bound of every learned reward per step (module docstring, "The bound")."""


def soft_bound(raw: jax.Array) -> jax.Array:
    """``B·tanh(raw / B)``, B = :data:`REWARD_BOUND`: linear near 0 (slope 1), bounded by ±B."""
    return REWARD_BOUND * jnp.tanh(raw / REWARD_BOUND)


RBF_PER_AXIS = 16
"""Radial basis centres per observation axis of the ``terminal`` absorbing head (on [−1, 1])."""
RBF_SUPPORT = 2.0
"""Radius of each radial basis feature, in widths (its value there is exp(−2) of its peak)."""
RBF_MAX_DIM = 3
"""The most observation dimensions a grid of radial basis centres is built for (16³ = 4096 features);
beyond it the grid grows past what a reward head should hold, and :func:`rbf_count` refuses."""
RBF_GAIN = 20.0
"""Height of each radial basis feature: a step of Adam then moves r_abs about as far as it
moves the output of a member's MLP (about lr × 60), so the head keeps pace with the members."""


def rbf_count(obs_dim: int) -> int:
    """Features of a ``terminal`` absorbing head over ``obs_dim`` dimensions: :data:`RBF_PER_AXIS`^d, for d ≤ :data:`RBF_MAX_DIM`."""
    if obs_dim > RBF_MAX_DIM:
        raise ValueError(
            f"absorbing states per terminal state need at most {RBF_MAX_DIM} observation dimensions "
            f"({RBF_PER_AXIS}^d radial features), this world has {obs_dim}: use absorbing_state='single' or no absorbing states"
        )
    return RBF_PER_AXIS**obs_dim


def absorbing_features(terminal_obs: jax.Array, m: int) -> jax.Array:
    """φ(s_T) ``[..., m]``: the constant 1 for ``m = 1``, else Gaussian bumps on a grid over [−1, 1]^d.

    The grid has :data:`RBF_PER_AXIS` centres per axis (``m = RBF_PER_AXIS^d``), the bumps'
    width is the grid's spacing and their height :data:`RBF_GAIN`, and each is cut to 0
    beyond :data:`RBF_SUPPORT` widths. The cut matters: Adam scales each weight's step by its
    own gradient history, so a Gaussian's far tail (a gradient of 1e-6) moves a weight as
    fast as its centre would; with a compact support a weight whose bump no terminal state
    reaches gets an exactly-zero gradient and never moves (measured on d1: uncut, the pits'
    −1 spread over the whole map, the goal included).
    """
    if m == 1:
        return jnp.ones((*terminal_obs.shape[:-1], 1))
    d = terminal_obs.shape[-1]
    axis = jnp.linspace(-1.0, 1.0, RBF_PER_AXIS)
    centres = jnp.stack(jnp.meshgrid(*([axis] * d), indexing="ij"), -1).reshape(-1, d)  # [m, d]
    width = 2.0 / (RBF_PER_AXIS - 1)
    sq = jnp.sum((terminal_obs[..., None, :] - centres) ** 2, -1)
    bump = jnp.exp(-0.5 * sq / width**2)
    return RBF_GAIN * jnp.where(sq < (RBF_SUPPORT * width) ** 2, bump, 0.0)


def reward_init(
    key: jax.Array, obs_dim: int, act_dim: int, cfg: RewardConfig, absorbing: str | None = None
) -> RewardState:
    """Fresh members; with ``absorbing`` (one of :data:`ABSORBING_STATES`) also their absorbing heads.

    A ``terminal`` head weighs radial basis features of the terminal state, a ``single`` one
    a constant. Either starts at r_abs = 0 everywhere (zero weights), and the members'
    networks are the same for the same key with or without one.
    """
    params = init_stack(key, cfg.members, (obs_dim + act_dim, *cfg.hidden, 1))
    if absorbing is not None:
        if absorbing not in ABSORBING_STATES:
            raise ValueError(f"absorbing must be one of {', '.join(ABSORBING_STATES)}, got {absorbing!r}")
        m = rbf_count(obs_dim) if absorbing == "terminal" else 1
        params = AbsorbingParams(params, jnp.zeros((cfg.members, m)))
    return RewardState(params, optax.adam(cfg.lr).init(params))


def _net(params) -> Params:
    return params.net if isinstance(params, AbsorbingParams) else params


def member_rewards(params: Params, obs: jax.Array, act: jax.Array) -> jax.Array:
    """Every member's reward. obs [..., d], act [..., a] → [E, ...].

    A discrete action (stored as its index) enters one-hot: the members were made for
    ``obs_dim + n`` inputs (:func:`~mindgap.models.categorical.action_input`)."""
    width = _net(params)[0][0].shape[-2] - obs.shape[-1]
    x = jnp.concatenate([obs, action_input(act, width)], axis=-1)
    return jax.vmap(lambda p: soft_bound(mlp(p, x)[..., 0]))(_net(params))


def member_absorbing_rewards(params, terminal_obs: jax.Array) -> jax.Array:
    """Every member's reward in the absorbing state entered at ``terminal_obs [..., d]``: [E, ...].

    Zeros for parameters without absorbing heads.
    """
    if not isinstance(params, AbsorbingParams):
        return jnp.zeros((jax.tree.leaves(params)[0].shape[0], *terminal_obs.shape[:-1]))
    phi = absorbing_features(terminal_obs, params.absorb.shape[-1])  # [..., M]
    return soft_bound(jnp.moveaxis(phi @ params.absorb.T, -1, 0))


def absorbing_reward(params, terminal_obs: jax.Array) -> jax.Array:
    """The absorbing-state reward of the members' mean (what the agent optimises): [B, d] → [B].

    The ``absorbing_fn`` of :func:`~mindgap.data.replay.relabel` and
    :func:`~mindgap.algorithms.sac_loop.run_chunk`, evaluated at the next observation of
    terminal transitions.
    """
    return member_absorbing_rewards(params, terminal_obs).mean(0)


def ensemble_reward(params: Params, obs: jax.Array, act: jax.Array, next_obs: jax.Array) -> jax.Array:
    """The reward the agent optimises: the members' mean. [B, ·] → [B]."""
    del next_obs
    return member_rewards(params, obs, act).mean(0)


def segment_returns(params: Params, seg: Segments) -> jax.Array:
    """Each member's return of each segment: [E, K] (absorbing steps count ``r_abs`` with :class:`AbsorbingParams`)."""
    r = member_rewards(params, seg.obs, seg.act)  # [E, K, L]
    ret = jnp.sum(jnp.where(seg.mask, r, 0.0), axis=-1)
    if isinstance(params, AbsorbingParams):  # Σ absorbed · r_abs(s_T), s_T where the last real step ended
        ret = ret + member_absorbing_rewards(params, terminal_obs(seg)) * absorbed_steps(seg).sum(-1)
    return ret


def preference_probs(params: Params, seg_a: Segments, seg_b: Segments) -> jax.Array:
    """Each member's P(a ≻ b) = σ(R̂_a − R̂_b): [E, K]."""
    return jax.nn.sigmoid(segment_returns(params, seg_a) - segment_returns(params, seg_b))


def bt_loss(params: Params, seg_a: Segments, seg_b: Segments, label: jax.Array, weight: jax.Array) -> jax.Array:
    """Bradley–Terry cross-entropy (Eq. 3.1) summed over members, averaged over weighted pairs."""
    logit = segment_returns(params, seg_a) - segment_returns(params, seg_b)  # [E, K]
    ce = -(label * jax.nn.log_sigmoid(logit) + (1 - label) * jax.nn.log_sigmoid(-logit))
    return jnp.sum(jnp.sum(ce * weight, axis=-1) / jnp.maximum(weight.sum(-1), 1.0))


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
