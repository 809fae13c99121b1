"""PrefBias inference: the reward and the person's belief from preferences by variational Bayes (§3.3.3.1–2).

The person is modelled as preferring segment τ₁ over τ₂ with Bradley–Terry probability
(Eqs. 3.4–3.5)::

    p̂(τ₁ ≻ τ₂ | w, φ) = σ(S(τ₁) − S(τ₂)),    S(τ) = Σ_t [r_w(s_t, a_t) + log f_φ(s_{t+1} | s_t, a_t)],

the log of ``p̂(τ) ∝ Π_t f_φ(s_{t+1}|s_t, a_t) · exp Σ_t r_w(s_t, a_t)`` over a segment's
unmasked steps. With absorbing states (``absorbing``; off by default) the steps of a segment
after a terminal transition count too, each as ``r_abs(s_T)``, the learned reward of the
absorbing state entered at s_T (:mod:`~mindgap.models.prefbias_nets`); they add no
log f_φ term, since nothing moves there (log-density 0 under any belief). (The start-state
factor ρ(s₀) of Eq. 3.5 is dropped: segments start mid-episode, and the simulated person
ignores it too.) The posteriors
q(w) q(φ) are factorised Gaussians (:mod:`~mindgap.models.bayes`) fitted by minimising the
negative ELBO of Eq. 3.3, per answered pair::

    L(Ω) = E_q[CE(label, p̂)] + (KL[q(w) ‖ p(w)] + KL[q(φ) ‖ p(φ)]) · kl_scale / N,

N the number of answered pairs: dividing Eq. 3.3 by N makes ``kl_scale = 1`` the exact
ELBO, and smaller values temper the prior. The expectation is a Monte Carlo average over
``mc_samples`` draws, each one draw of (w, φ) per answered pair shared by all the steps of
its two segments (:func:`~mindgap.models.prefbias_nets.draw_per_pair`): the likelihood of
one answer is p(d | w, φ) for one reward function and one belief.

Units: f_φ's density of a move is stated in the world's units (``PrefBiasState.log_unit``,
:mod:`~mindgap.models.prefbias_nets`, "Units"), those of the person's log T_H, so that the
person's own belief scores segments as the person does.
Priors: p(w) = N(w₀, s_w²) centred on a random initialisation w₀; p(φ) = N(ψ, s_φ²)
centred on the agent's dynamics model f_ψ (``belief_prior="dynamics"``, the default) or on
a random initialisation (``"random"``), §3.3.3.1 "Prior". The dissertation leaves s_φ open;
here it has two values (:func:`belief_prior_scales`): narrow on every weight of the MLP
(``belief_prior_std``), so that the posterior's draws of the predicted move stay within the
world's noise, and wide on a disturbance of the stay logit (``stay_prior_std``), the part of a
belief a person gets wrong by a lot. With ``stay_local`` the disturbance is local: radial basis
bumps over the observation added to f_ψ's stay logit (:class:`~mindgap.models.prefbias_nets.BeliefWeights`),
so a belief about one place does not spread to the places beside it. One narrow scale for all
pins the stay probability at f_ψ's; one wide scale for all lets the draws of the predicted move
spread by twice the world's noise, and the likelihood then prefers a wide Gaussian to a stuck
robot; a wide prior on the MLP's stay column moves the floor with the ice
(docs/experiments/identifiability.md, "The belief posterior").

Held-out answers (``holdout_every``): every k-th answered pair is kept out of the gradient steps,
and :func:`fit` keeps the posterior whose mean predicts them best (early stopping), so that r_w
does not fit the answers' noise.

Ω_w and Ω_φ are updated alternately (the two gradients of §3.3.3.1), each with its own
Adam state: every round takes one step on Ω_w with φ held fixed, then one on Ω_φ with w
held fixed, each on a fresh minibatch and fresh noise. :func:`fit` runs ``updates`` rounds
inside one ``lax.scan``; it is jittable with the config static and vmaps over seeds.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax
from jax.flatten_util import ravel_pytree

from ..data.prefs import PrefData
from ..data.segments import Segments, absorbed_steps, terminal_obs
from ..models.bayes import Gaussian, init_gaussian, kl_divergence
from ..models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_sizes
from ..models.mlp import Params, init_mlp
from ..models.prefbias_nets import (
    STAY_GAIN,
    BeliefWeights,
    absorbing_value,
    belief_log_prob,
    belief_net,
    belief_weights_init,
    draw_per_pair,
    reward_value,
    reward_weights_init,
)
from ..models.reward_ensemble import ABSORBING_STATES, RBF_MAX_DIM

BELIEF_PRIORS = ("dynamics", "random")


@dataclasses.dataclass(frozen=True)
class PrefBiasConfig:
    """Hyperparameters of the joint inference of r_w and f_φ (hashable: a static jit argument)."""

    reward_hidden: tuple[int, ...] = (64, 64)
    """Hidden widths of the reward network r_w."""
    absorbing: bool = True
    """Give r_w absorbing states (a learned r_abs per terminal state; Kostrikov et al. 2019), so that a
    segment that ends early (in a pit, at the goal) is not compared with longer segments as a shorter
    sum (docs/methods/prefbias.md)."""
    absorbing_state: str = "terminal"
    """With ``absorbing``: one absorbing state per terminal state (``terminal``, radial basis features of s_T;
    worlds of at most three observation dimensions) or one for all (``single``, DAC's; any world)."""
    dynamics: DynamicsConfig = DynamicsConfig()
    """Architecture (and training) of f_ψ; the belief f_φ shares its architecture and scale floor."""
    stay_head: bool = True
    """Give f_ψ and f_φ a third head, the probability of not moving at all (s' = s: stuck or
    bumped), so that such steps are a point mass rather than a far tail of the Gaussian
    (:mod:`~mindgap.models.gaussian_dynamics`; docs/methods/prefbias.md)."""
    belief_prior: str = "dynamics"
    """Centre of p(φ): 'dynamics' (f_ψ's parameters) or 'random' (a random initialisation)."""
    reward_prior_std: float = 1.0
    """Standard deviation s_w of p(w) around its random centre (wide: nothing is known about the reward)."""
    belief_prior_std: float = 0.01
    """Standard deviation s_φ of p(φ) around its centre on every weight but the stay logit's (narrow: a
    belief is a disturbance of f_ψ). It sets how far apart the posterior's draws of the predicted move
    are: 0.1 on every weight spreads them by 0.11 cells on nav1's ice, twice the world's noise, and the
    likelihood then prefers a wide Gaussian to a stuck robot; 0.01 spreads them by about 0.02 cells
    (``mindgap design recovery``; docs/experiments/identifiability.md, "The belief posterior")."""
    stay_prior_std: float | None = 3.0
    """s_φ on the disturbance of the stay logit, the part of the belief a person may get wrong by a lot
    (P(stuck) 0.9 against the truth's 0.1 is a logit change of 4.4), so its prior is wide where the
    move's is narrow (§3.3.3.1, "Prior": the prior states what is known of the belief beforehand).
    With ``stay_local``: the standard deviation of each bump's height, in logit units (nav1's person
    is 1.5 of them from f_ψ); otherwise on the stay logit's output column, its weights and bias.
    None: ``belief_prior_std`` (one scale for all). Measured by ``mindgap design recovery nav1``
    (docs/experiments/identifiability.md, "The belief posterior")."""
    stay_local: bool = True
    """Disturb the stay logit place by place (:class:`~mindgap.models.prefbias_nets.BeliefWeights`:
    radial basis bumps over the observation, worlds of at most three observation dimensions with the
    stay head; elsewhere the output column's wide prior stands in). Through the column, a change
    the answers ask for on nav1's ice spreads to the floor and goal beside it, where the answers
    cannot hold it back (docs/experiments/identifiability.md, "The belief posterior")."""
    noise_local: bool = False
    """With ``stay_local``: also disturb the raw scale of a move place by place (off by default; measured
    in docs/experiments/identifiability.md, "The belief posterior")."""
    noise_prior_std: float = 1.0
    """With ``noise_local``: the prior's standard deviation of each bump's height in the local disturbance
    of the move's raw scale (σ = floor + softplus(raw), in units of the displacement's spread), so that a
    belief that moves are noisier in one place (nav1-v1's ice: 0.2 cells against the truth's 0.05) can be
    learned while the network's own scale stays pinned by ``belief_prior_std``."""
    scale_prior_std: float | None = None
    """s_φ on the biases of the raw-scale output columns of f_φ's MLP (σ = floor + softplus(raw), per
    axis; dynamics prior only): how reliable the person may believe every move to be, everywhere.
    §3.4.2.3's person believes the noisy robot "is operating reliably": her belief differs from f_ψ in
    the spread of a move, not in where it goes, and with ``belief_prior_std`` on every weight f_φ's
    spread cannot leave f_ψ's. A wide scale here states that (the global counterpart of
    ``noise_local``'s bumps, which exist on worlds of at most three observation dimensions). None (the
    default): ``belief_prior_std`` like every other weight (measured in docs/experiments/gym.md,
    "What the answers carry")."""
    random_prior_std: float = 1.0
    """s_φ on every weight with ``belief_prior="random"``: a prior centred on a random network knows
    nothing of the belief, so it is as wide as the reward's (``reward_prior_std``); the narrow scales
    above state what f_ψ knows and apply to the dynamics prior only."""
    init_std: float = 0.01
    """Posterior standard deviation of every parameter at initialisation."""
    kl_scale: float = 1.0
    """Weight of the KL terms per answered pair is kl_scale / N; 1 is the ELBO of Eq. 3.3."""
    mc_samples: int = 1
    """Monte Carlo draws per likelihood estimate (each a draw of (w, φ) per answered pair)."""
    lr: float = 1e-3
    """Adam step size of both posteriors."""
    batch_size: int = 64
    """Answered pairs per gradient step."""
    updates: int = 300
    """Alternating rounds per fit (a step on Ω_w, then a step on Ω_φ)."""
    holdout_every: int = 8
    """Hold out every k-th answered pair (k = 8: 12.5%) from the gradient steps and keep the posterior
    of the check with the lowest negative log-likelihood of the held-out answers (early stopping): r_w
    fits 800 answers more closely than the person who gave them does. 0 trains on every answer."""
    check_every: int = 25
    """Rounds between two held-out checks (``updates`` is a multiple of it when ``holdout_every`` is set)."""
    refit: bool = True
    """Each fit starts q(w) q(φ) afresh at their priors' centres (Alg. 2, line 7: fit to all answers so
    far); False starts from the last fit's posterior. Warm-started, the first rounds fit r_w to 80, 160, …
    answers and every later fit starts there: on nav1 the loop's ten fits left the ice's P(not moving) at
    0.73 (held-out NLL 0.460), against 0.89 (0.277) for one fit on all 800 answers, which 300 rounds from
    the priors reach (``mindgap design recovery nav1 --rounds 10``; docs/experiments/identifiability.md)."""
    log_f_floor: float | None = None
    """A floor on f_φ's log density in the segment score, r_w + max(log f_φ, floor): the form of the
    simulated person's own score, r_H + max(log T_H, ``TeacherConfig.log_t_floor``), so that f_φ cannot
    take more of an answer than the person's belief gave it. None (the default): no floor, Eq. 3.5 as
    written; the dissertation floors neither. On the lander, the unfloored f_φ takes thousands of nats
    from high segments the person scored at the floor, and r_w, balancing the pairs, pays height
    (docs/experiments/gym.md, "The runs so far")."""

    def check(self) -> None:
        for f in dataclasses.fields(self):  # a switch given as a string ("false") would be on
            if isinstance(f.default, bool) and not isinstance(getattr(self, f.name), bool):
                raise ValueError(f"{f.name} must be True or False, got {getattr(self, f.name)!r}")
        if self.absorbing_state not in ABSORBING_STATES:
            raise ValueError(
                f"absorbing_state must be one of {', '.join(ABSORBING_STATES)}, got {self.absorbing_state!r}"
            )
        if self.belief_prior not in BELIEF_PRIORS:
            raise ValueError(f"unknown belief_prior {self.belief_prior!r}: choose from {', '.join(BELIEF_PRIORS)}")
        for name in ("reward_prior_std", "belief_prior_std", "noise_prior_std", "random_prior_std", "init_std", "lr"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("stay_prior_std", "scale_prior_std"):
            if getattr(self, name) is not None and not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive or None, got {getattr(self, name)}")
        if self.kl_scale < 0 or self.mc_samples < 1 or self.batch_size < 1 or self.updates < 1:
            raise ValueError("kl_scale must be ≥ 0; mc_samples, batch_size and updates at least 1")
        floor = self.log_f_floor
        if floor is not None and (not isinstance(floor, (int, float)) or not math.isfinite(floor)):
            raise ValueError(f"log_f_floor must be a finite number or None, got {self.log_f_floor}")
        if self.holdout_every < 0 or self.holdout_every == 1:
            raise ValueError(f"holdout_every must be 0 (none) or at least 2, got {self.holdout_every}")
        if self.holdout_every and (self.check_every < 1 or self.updates % self.check_every):
            raise ValueError(f"updates ({self.updates}) must be a multiple of check_every ({self.check_every})")


class PrefBiasState(NamedTuple):
    """Posteriors, the centres of their priors, the normalisation f_φ reads, optimiser states, and
    Σ log of the world's units per observation unit (0: densities per observation unit)."""

    reward: Gaussian
    belief: Gaussian
    reward_prior: Params
    belief_prior: Params
    norm: Norm
    opt_w: optax.OptState
    opt_phi: optax.OptState
    log_unit: jax.Array | float = 0.0


class FitInfo(NamedTuple):
    """Last round's negative ELBO per pair (w step), accuracy of the kept posterior mean on the answered
    pairs it trained on, and its negative log-likelihood per held-out pair (NaN without held-out answers)."""

    loss: jax.Array
    accuracy: jax.Array
    held_nll: jax.Array


def prefbias_init(
    key: jax.Array, obs_dim: int, act_dim: int, cfg: PrefBiasConfig, dynamics: DynamicsModel, units=None
) -> PrefBiasState:
    """Priors and posteriors before any preference (Alg. 2, line 1).

    q(w) starts at the centre of p(w), a random initialisation (with ``cfg.absorbing`` also
    an absorbing head of zeros: r_abs = 0 a priori); q(φ) at the centre of p(φ):
    f_ψ's parameters (``"dynamics"``) or a random initialisation (``"random"``). f_φ reads
    ``dynamics.norm`` in both cases. All posterior σ start at ``cfg.init_std``. ``units [d]``:
    the world's units per observation unit (:meth:`~mindgap.envs.interface.World.obs_units`),
    the units f_φ's densities are stated in; None keeps observation units.
    """
    cfg.check()
    k_w, k_phi = jax.random.split(key)
    w0 = reward_weights_init(k_w, obs_dim, act_dim, cfg.reward_hidden, cfg.absorbing, cfg.absorbing_state == "single")
    if cfg.belief_prior == "dynamics":
        net0 = dynamics.params
    else:
        net0 = init_mlp(k_phi, dynamics_sizes(obs_dim, act_dim, cfg.dynamics.hidden, cfg.stay_head))
    phi0 = belief_weights_init(net0, obs_dim, local_stay(cfg, obs_dim), cfg.noise_local)
    reward, belief = init_gaussian(w0, cfg.init_std), init_gaussian(phi0, cfg.init_std)
    opt = optax.adam(cfg.lr)
    opt_w, opt_phi = opt.init(ravel_pytree(reward)[0]), opt.init(ravel_pytree(belief)[0])  # see fit
    log_unit = jnp.zeros(()) if units is None else jnp.sum(jnp.log(jnp.asarray(units, jnp.float32)))
    return PrefBiasState(reward, belief, w0, phi0, dynamics.norm, opt_w, opt_phi, log_unit)


def with_dynamics(state: PrefBiasState, dynamics: DynamicsModel, cfg: PrefBiasConfig) -> PrefBiasState:
    """Re-centre p(φ) on a retrained f_ψ (Alg. 2, lines 4 and 7); the posteriors are kept.

    Retrain f_ψ with ``init=`` the previous model so its normalisation, which f_φ reads,
    stays the same. With ``belief_prior="random"`` only the normalisation is taken.
    """
    if cfg.belief_prior != "dynamics":
        return state._replace(norm=dynamics.norm)
    prior = state.belief_prior
    prior = prior._replace(net=dynamics.params) if isinstance(prior, BeliefWeights) else dynamics.params
    return state._replace(belief_prior=prior, norm=dynamics.norm)


def local_stay(cfg: PrefBiasConfig, obs_dim: int) -> bool:
    """Whether f_φ gets a local stay disturbance: ``stay_local`` with the stay head, on a world of at
    most :data:`~mindgap.models.reward_ensemble.RBF_MAX_DIM` observation dimensions."""
    return cfg.stay_local and cfg.stay_head and obs_dim <= RBF_MAX_DIM


def segment_scores(rewards: jax.Array, log_f: jax.Array, mask: jax.Array) -> jax.Array:
    """S(τ) = Σ_t [r(s_t, a_t) + log f(s_{t+1} | s_t, a_t)] over unmasked steps (log of Eq. 3.5): [..., L] → [...]."""
    return jnp.sum(jnp.where(mask, rewards + log_f, 0.0), axis=-1)


def absorbed_scores(r_abs: jax.Array, seg) -> jax.Array:
    """What a segment's absorbing steps add to S(τ): ``r_abs(s_T)`` times their count: [...]."""
    return r_abs * absorbed_steps(seg).sum(-1)


def bt_cross_entropy(logit: jax.Array, label: jax.Array) -> jax.Array:
    """−[y log σ(S₁ − S₂) + (1 − y) log σ(S₂ − S₁)] (Eq. 3.4 and the loss below it), elementwise."""
    return -(label * jax.nn.log_sigmoid(logit) + (1 - label) * jax.nn.log_sigmoid(-logit))


def _pair(seg_a: Segments, seg_b: Segments) -> Segments:
    # both sides of every pair in one batch [2, K, L, ·]: one network evaluation instead of two
    return jax.tree.map(lambda x, y: jnp.stack([x, y]), seg_a, seg_b)


def _logits_drawn(reward: Gaussian, belief: Gaussian, norm: Norm, log_unit, seg_a, seg_b, keys, cfg: PrefBiasConfig):
    """S(a) − S(b) of each pair, each pair under its own draw (w, φ) ~ q(w) q(φ) (keys [2]): [K]."""
    per_pair = jax.tree.map(lambda a, b: jnp.stack([a, b], 1), seg_a, seg_b)  # [K, 2, L, ·]
    k = per_pair.mask.shape[0]
    ws, phis = draw_per_pair(reward, keys[0], k), draw_per_pair(belief, keys[1], k)
    s = jax.vmap(lambda w, phi, seg: scores_fixed(w, phi, norm, seg, cfg, log_unit))(ws, phis, per_pair)
    return s[:, 0] - s[:, 1]


def scored_log_f(phi: Params, norm: Norm, seg: Segments, cfg: PrefBiasConfig, log_unit=0.0) -> jax.Array:
    """log f_φ(s' | s, a) of every step as the segment score counts it: floored at ``cfg.log_f_floor`` when set
    (the person's form of the score), else as Eq. 3.5 writes it: [..., L]."""
    lf = belief_log_prob(phi, norm, seg.obs, seg.act, seg.next_obs, cfg.dynamics.min_std, log_unit)
    return lf if cfg.log_f_floor is None else jnp.maximum(lf, cfg.log_f_floor)


def scores_fixed(w: Params, phi: Params, norm: Norm, seg: Segments, cfg: PrefBiasConfig, log_unit=0.0) -> jax.Array:
    """S(τ) of each segment for fixed weights of r_w and f_φ (posterior means or one draw): [K].

    ``log_unit``: the state's (:class:`PrefBiasState`), so that f_φ scores in the world's units.
    """
    lf = scored_log_f(phi, norm, seg, cfg, log_unit)
    s = segment_scores(reward_value(w, seg.obs, seg.act), lf, seg.mask)
    return s + absorbed_scores(absorbing_value(w, terminal_obs(seg)), seg)


def preference_prob(
    w: Params, phi: Params, norm: Norm, seg_a: Segments, seg_b: Segments, cfg: PrefBiasConfig, log_unit=0.0
):
    """p̂(a ≻ b | w, φ) of Eq. 3.4 for fixed weights: [K]."""
    s = scores_fixed(w, phi, norm, _pair(seg_a, seg_b), cfg, log_unit)
    return jax.nn.sigmoid(s[0] - s[1])


def expected_nll(
    reward: Gaussian, belief: Gaussian, norm: Norm, seg_a, seg_b, label, keys, cfg: PrefBiasConfig, log_unit=0.0
):
    """Monte Carlo estimate of E_q[CE] per pair (the likelihood term of Eq. 3.3 divided by N): scalar.

    ``keys [M, 2]``: one pair of keys (reward, belief) per draw; split them with
    ``jax.random.split(key, (cfg.mc_samples, 2))``. Each draw gives every pair its own (w, φ).
    """

    def draw(k):
        logit = _logits_drawn(reward, belief, norm, log_unit, seg_a, seg_b, k, cfg)
        return bt_cross_entropy(logit, label).mean()

    return jax.vmap(draw)(keys).mean()


def negative_elbo(state: PrefBiasState, data: PrefData, key: jax.Array, cfg: PrefBiasConfig) -> jax.Array:
    """Eq. 3.3 per answered pair over all of ``data``'s answered pairs (for monitoring and tests): scalar."""
    n = jnp.maximum(data.count, 1)
    seen = jnp.arange(data.label.shape[0]) < data.count

    def draw(k):
        logit = _logits_drawn(state.reward, state.belief, state.norm, state.log_unit, data.seg_a, data.seg_b, k, cfg)
        return jnp.sum(jnp.where(seen, bt_cross_entropy(logit, data.label), 0.0)) / n

    nll = jax.vmap(draw)(jax.random.split(key, (cfg.mc_samples, 2))).mean()
    scales = belief_prior_scales(state.belief.mean, state.norm.out_mean.shape[-1], cfg)
    kl = kl_divergence(state.reward, state.reward_prior, cfg.reward_prior_std) + kl_divergence(
        state.belief, state.belief_prior, scales
    )
    return nll + kl * cfg.kl_scale / n


def belief_prior_scales(belief_mean: Params, obs_dim: int, cfg: PrefBiasConfig) -> jax.Array:
    """s_φ of every parameter of f_φ, flat in ``ravel_pytree`` order: ``belief_prior_std`` on the MLP
    (``random_prior_std`` with ``belief_prior="random"``) and ``stay_prior_std`` on the stay disturbance:
    the local one's weights, or without one (and with the dynamics prior) the stay logit's output column;
    with the dynamics prior and ``scale_prior_std``, that on the biases of the raw-scale columns."""
    base = cfg.random_prior_std if cfg.belief_prior == "random" else cfg.belief_prior_std
    stay = base if cfg.stay_prior_std is None else cfg.stay_prior_std
    net = belief_net(belief_mean)
    scales = jax.tree.map(lambda x: jnp.full_like(x, base), net)
    if cfg.belief_prior == "dynamics" and cfg.scale_prior_std is not None:
        sw, sb = scales[-1]
        scales = (*scales[:-1], (sw, sb.at[..., obs_dim : 2 * obs_dim].set(cfg.scale_prior_std)))
    if isinstance(belief_mean, BeliefWeights):  # the disturbances' priors are per unit of a bump's height
        local = BeliefWeights(
            scales,
            jnp.full_like(belief_mean.stay, stay / STAY_GAIN),
            jnp.full_like(belief_mean.noise, cfg.noise_prior_std / STAY_GAIN),
        )
        return ravel_pytree(local)[0]
    w, _ = net[-1]
    if cfg.belief_prior == "dynamics" and w.shape[-1] == 2 * obs_dim + 1:
        sw, sb = scales[-1]
        scales = (*scales[:-1], (sw.at[..., -1].set(stay), sb.at[..., -1].set(stay)))
    return ravel_pytree(scales)[0]


def held_out(count: jax.Array, capacity: int, every: int) -> jax.Array:
    """Which of ``capacity`` answer slots are held out: every ``every``-th of the first ``count`` ([capacity] bool)."""
    i = jnp.arange(capacity)
    if not every:
        return jnp.zeros(capacity, bool)
    return (i < count) & (i % every == every - 1)


def _train_index(i: jax.Array, every: int) -> jax.Array:
    """The i-th answer slot that is not held out (``every``-th slots skipped)."""
    return i if not every else i + i // (every - 1)


def fit(state: PrefBiasState, data: PrefData, key: jax.Array, cfg: PrefBiasConfig) -> tuple[PrefBiasState, FitInfo]:
    """Alternating Adam steps on q(w) and q(φ) over the answered pairs of ``data`` (Alg. 2, line 7).

    With ``cfg.refit`` (the default) the fit starts at the priors' centres, else at ``state``'s posterior.
    ``cfg.updates`` rounds; in each, a minibatch of ``cfg.batch_size`` training pairs drawn
    with replacement and a step on Ω_w of ``E_q[CE] + kl_scale · KL[q(w)‖p(w)] / N``, then
    a fresh minibatch and a step on Ω_φ of ``E_q[CE] + kl_scale · KL[q(φ)‖p(φ)] / N``; N the
    training pairs. p(φ) has one scale per parameter (:func:`belief_prior_scales`).

    With ``cfg.holdout_every`` every k-th answered pair is held out (:func:`held_out`); every
    ``cfg.check_every`` rounds the posterior mean's negative log-likelihood of the held-out
    answers is measured, and the posterior of the best check (the start included) is kept, with
    its optimiser states. While no answer is held out yet, the last one is kept.

    Returns:
        (new state, :class:`FitInfo`).
    """
    opt = optax.adam(cfg.lr)
    if cfg.refit:  # afresh at the priors' centres, with fresh Adam states
        reward, belief = init_gaussian(state.reward_prior, cfg.init_std), init_gaussian(state.belief_prior, cfg.init_std)
        state = state._replace(
            reward=reward, belief=belief, opt_w=opt.init(ravel_pytree(reward)[0]), opt_phi=opt.init(ravel_pytree(belief)[0])
        )
    capacity, every = data.label.shape[0], cfg.holdout_every
    held = held_out(data.count, capacity, every)
    n_held = held.sum()
    n = jnp.maximum(data.count - n_held, 1)
    kl_weight = cfg.kl_scale / n
    d = state.norm.out_mean.shape[-1]
    phi_scales = belief_prior_scales(state.belief.mean, d, cfg)
    # Flat parameter vectors keep the compiled program small (one Adam update per posterior).
    flat_w, unravel_w = ravel_pytree(state.reward)
    flat_phi, unravel_phi = ravel_pytree(state.belief)

    # Every minibatch and noise key drawn up front: random-number ops inside the scan body
    # cost far more compile time than their share of the work.
    k_idx, k_mc = jax.random.split(key)
    all_idx = _train_index(jax.random.randint(k_idx, (2 * cfg.updates, cfg.batch_size), 0, n), every)
    all_keys = jax.random.split(k_mc, (2 * cfg.updates, cfg.mc_samples, 2))

    def loss_fn(w, phi, idx, keys):
        reward, belief = unravel_w(w), unravel_phi(phi)
        seg_a, seg_b = jax.tree.map(lambda x: x[idx], data.seg_a), jax.tree.map(lambda x: x[idx], data.seg_b)
        nll = expected_nll(reward, belief, state.norm, seg_a, seg_b, data.label[idx], keys, cfg, state.log_unit)
        kl_w = kl_divergence(reward, state.reward_prior, cfg.reward_prior_std)
        kl_phi = kl_divergence(belief, state.belief_prior, phi_scales)
        return nll + kl_weight * (kl_w + kl_phi)

    def step(carry, xs):
        # The gradient of the joint loss with respect to Ω_w is that of §3.3.3.1
        # (KL[q(φ)‖p(φ)] does not depend on Ω_w), and vice versa. Each half differentiates
        # only its own posterior: the other network's backward pass is never computed.
        (w, phi), (opt_w, opt_phi) = carry
        idx, keys = xs
        loss_w, g_w = jax.value_and_grad(loss_fn, argnums=0)(w, phi, idx[0], keys[0])
        upd, opt_w = opt.update(g_w, opt_w, w)
        w = w + upd
        loss_phi, g_phi = jax.value_and_grad(loss_fn, argnums=1)(w, phi, idx[1], keys[1])
        upd, opt_phi = opt.update(g_phi, opt_phi, phi)
        return ((w, phi + upd), (opt_w, opt_phi)), (loss_w, loss_phi)

    def held_nll(carry):
        (w, phi), _ = carry
        p = preference_prob(unravel_w(w).mean, unravel_phi(phi).mean, state.norm, data.seg_a, data.seg_b, cfg,
                            state.log_unit)  # fmt: skip
        logit = jnp.log(jnp.clip(p, 1e-6, 1 - 1e-6)) - jnp.log1p(-jnp.clip(p, 1e-6, 1 - 1e-6))
        return jnp.sum(jnp.where(held, bt_cross_entropy(logit, data.label), 0.0)) / jnp.maximum(n_held, 1)

    # round i: a step on Ω_w with minibatch 2i, then one on Ω_φ with minibatch 2i + 1
    pairs = (all_idx.reshape(cfg.updates, 2, cfg.batch_size), all_keys.reshape(cfg.updates, 2, *all_keys.shape[1:]))
    carry = ((flat_w, flat_phi), (state.opt_w, state.opt_phi))
    if every:
        checks = cfg.updates // cfg.check_every
        blocks = jax.tree.map(lambda x: x.reshape(checks, cfg.check_every, *x.shape[1:]), pairs)

        def block(c, xs):
            run, best, best_nll = c
            run, losses = jax.lax.scan(step, run, xs)
            nll = held_nll(run)
            better = (nll <= best_nll) | (n_held == 0)
            best = jax.tree.map(lambda a, b: jnp.where(better, a, b), run, best)
            return (run, best, jnp.where(better, nll, best_nll)), losses[0][-1]

        (_, carry, best_nll), losses_w = jax.lax.scan(block, (carry, carry, held_nll(carry)), blocks)
    else:
        carry, (losses_w, _) = jax.lax.scan(step, carry, pairs)
        best_nll = jnp.nan
    ((flat_w, flat_phi), (opt_w, opt_phi)) = carry
    state = state._replace(reward=unravel_w(flat_w), belief=unravel_phi(flat_phi), opt_w=opt_w, opt_phi=opt_phi)
    p = preference_prob(state.reward.mean, state.belief.mean, state.norm, data.seg_a, data.seg_b, cfg, state.log_unit)
    trained = (jnp.arange(capacity) < data.count) & ~held
    hit = ((p > 0.5) == (data.label > 0.5)) | (data.label == 0.5)
    held_nll_out = jnp.where(n_held > 0, best_nll, jnp.nan)
    return state, FitInfo(losses_w[-1], jnp.sum(hit & trained) / n, held_nll_out)
