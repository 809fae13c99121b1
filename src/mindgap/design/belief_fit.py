"""Is the person's belief *recovered* from their answers? A tabular maximum-likelihood fit.

:mod:`~.identifiability` measures how much a budget of answers *could* say about the belief
θ (its Fisher information). This module checks that it does. It simulates the answers as
the person gives them — Bradley–Terry with a finite β on the score difference of two
equal-length segments, S = Σ_t [r_H(s_t, a_t) + max(log T_H(s_{t+1} | s_t, a_t), floor)]
(dissertation Eqs. 3.4–3.5), log T_H the world's own exact ``log_prob_pos`` under the belief —
and fits by maximum likelihood a tabular learner whose families contain the person:

* a reward of one value per terrain of the current cell and a coefficient on its distance to
  the goal, r(s) = r[terrain(s)] − d·Φ(s) (the family of the state-form reward). Equal-length
  segments are answered alike when every reward shifts by a constant, so the floor's value
  (the start cells' terrain) is held at the person's;
* the belief θ (:func:`~.identifiability.parameter_slots`) in ``log_prob_pos``'s family, a stuck
  probability through its logit and the other parameters through their log, started at the
  truth's values (as PrefBias's dynamics prior starts), the rewards at 0.

L-BFGS finds the optimum, the inverse Hessian there the standard errors, and the profile
log-likelihood of one parameter (maximised over all the others on a grid of its values) shows
whether the answers pin it at all; :func:`verdict` reads them.

Written by hand: no library fits a Bradley–Terry likelihood around this world's density.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .. import rng
from ..data.stays import is_stay
from ..envs.terrain.dynamics import log_prob_pos, terrain_at
from ..envs.terrain.layout import FLOOR, GOAL, PIT, TERRAINS
from ..envs.terrain.params import TerrainState
from ..envs.terrain.world import potential, reward
from ..planning.identifiability import _episodes, _get, _put, parameter_slots
from .design_check import ACTIONS, DesignConfig, plan_policies

Z_MARGIN = 3.0
"""Recovered: θ̂ within this many standard errors of the belief and at least this many from the truth, on
the fit's scale (logit, log: nearer quadratic; a probability's own Wald interval is lopsided near 0 and 1)."""
FLAT_NATS = 2.0
"""Not identified: the profile log-likelihood varies by less than this over its grid (nats) …"""
SE_GAP = 1.0
"""… or the standard error is at least this share of the gap |θ_H − θ_T| (not even 1 SE apart)."""
START_CLIP = 0.01
"""A truth's value on a boundary (stuck 0, pit noise 0) starts the fit this far inside."""
GRAD_TOL = 1e-3
"""L-BFGS stops once the gradient in whitened coordinates (≈ √(2 × nats still to gain)) is this small …"""
VALUE_TOL = 1e-4
"""… or a step gains less than this (nats): float32 resolves no more, and its line search would thrash."""
ROUNDS, ROUND_TOL = 12, 1e-2
"""The fit ends after this many rounds (a fresh Hessian, then L-BFGS), or when one gains less than this (nats)."""
STUCK_TINY = 1e-30
"""The learner's stuck probabilities are at least this (log ≈ −69, far below the floor on log T_H):
a zero makes ``log_prob_pos``'s second derivatives NaN, and no floored score changes."""
NO_SCALE = "deterministic answers (β = None) fix no scale of the score: the belief is not identified"


class Queries(NamedTuple):
    """Answered queries: ``pos, act, nxt`` [Q, 2, L, 2], ``live`` [Q, 2, L], ``label`` [Q] (1: the first preferred)."""

    pos: jax.Array
    act: jax.Array
    nxt: jax.Array
    live: jax.Array
    label: jax.Array


class Estimate(NamedTuple):
    """A fitted quantity: the truth's value, the person's, the ML estimate, its standard error, and the
    estimate's distance from truth and belief in standard errors on the fit's scale (see :data:`Z_MARGIN`)."""

    name: str
    truth: float
    belief: float
    estimate: float
    stderr: float
    z_truth: float
    z_belief: float


class Profile(NamedTuple):
    """The profile log-likelihood of ``name`` on ``grid``, relative to the fit's maximum (nats)."""

    name: str
    grid: np.ndarray
    loglik: np.ndarray

    @property
    def span(self) -> float:
        return float(self.loglik.max() - self.loglik.min())


class BeliefFit(NamedTuple):
    """Result of :func:`fit_belief`: θ's estimates, the reward's (by terrain, the floor's held; then the
    distance coefficient) and one profile."""

    parameters: list[Estimate]
    rewards: list[Estimate]
    loglik: float
    profile: Profile | None


def simulate_queries(
    key, world_params, belief_params, behaviour, actions, index, n, *, beta, budget, segment, log_t_floor, episodes=64
) -> Queries:
    """``budget`` queries between segments of ``episodes`` ε-random episodes of each policy of ``behaviour``
    (:func:`~.identifiability.belief_information`'s arguments), answered as the person does."""
    if beta is None:
        raise ValueError(NO_SCALE)
    k_roll, k_pair = jax.random.split(key)
    trans = [
        _episodes(k, world_params, jnp.asarray(pol), jnp.asarray(actions), index, n, episodes)
        for k, pol in zip(jax.random.split(k_roll, len(behaviour)), behaviour, strict=True)
    ]
    trans = jax.tree.map(lambda *x: jnp.concatenate(x), *trans)
    return _answer(k_pair, world_params, belief_params, trans, float(beta), segment, budget, log_t_floor)


def person_step_score(world, belief, floor, s, a, s2) -> jax.Array:
    """The person's score of one step: r_H(s, a, s') + max(log T_H(s' | s, a), floor) (Eqs. 3.4–3.5)."""
    zero = jnp.zeros((), jnp.int32)
    r = reward(TerrainState(s, zero, False), a, TerrainState(s2, zero, False), world)
    return r + jnp.maximum(log_prob_pos(belief, s, a, s2), floor)


@partial(jax.jit, static_argnames=("segment", "budget"))
def _answer(key, world, belief, trans, beta, segment, budget, floor) -> Queries:
    def score(s, a, s2):
        return person_step_score(world, belief, floor, s, a, s2)

    cut = (trans[3].shape[1] // segment) * segment
    pos, act, nxt, live = (x[:, :cut].reshape(-1, segment, *x.shape[2:]) for x in trans)
    s_seg = jnp.sum(jnp.where(live, jax.vmap(jax.vmap(score))(pos, act, nxt), 0.0), 1)
    k_a, k_b, k_y = jax.random.split(key, 3)
    pair = jnp.stack([jax.random.randint(k, (budget,), 0, pos.shape[0]) for k in (k_a, k_b)], 1)  # [Q, 2]
    label = jax.random.bernoulli(k_y, jax.nn.sigmoid(beta * (s_seg[pair[:, 0]] - s_seg[pair[:, 1]])))
    return Queries(pos[pair], act[pair], nxt[pair], live[pair], label.astype(jnp.float32))


def log_likelihood(world_params, slots, theta, table, distance, q: Queries, beta: float, floor: float) -> jax.Array:
    """Σ log P(answer) for a learner with belief ``theta`` (values of ``slots``) and reward
    ``table`` [6] (by terrain) − ``distance`` · Φ (Φ = 0 in the goal and in pits, as the state form's)."""
    dyn = _put(world_params.dynamics, slots, theta)
    bel = world_params._replace(dynamics=dyn._replace(stuck=jnp.maximum(dyn.stuck, STUCK_TINY)))

    def step_score(s, a, s2):
        here = terrain_at(world_params, s)
        phi = jnp.where((here == GOAL) | (here == PIT), 0.0, potential(world_params, s))
        return table[here] - distance * phi + jnp.maximum(log_prob_pos(bel, s, a, s2), floor)

    score = jnp.sum(jnp.where(q.live, jax.vmap(jax.vmap(jax.vmap(step_score)))(q.pos, q.act, q.nxt), 0.0), -1)
    d = beta * (score[:, 0] - score[:, 1])
    return jnp.sum(q.label * jax.nn.log_sigmoid(d) + (1 - q.label) * jax.nn.log_sigmoid(-d))


def _to_theta(u, slots):
    return jnp.stack([jax.nn.sigmoid(u[i]) if f == "stuck" else jnp.exp(u[i]) for i, (_, f, _) in enumerate(slots)])


def _to_u(value: float, kind: str, clip: float = START_CLIP) -> float:
    """The fit's scale: a stuck probability's logit, a reward itself, another parameter's log (±inf on a boundary)."""
    with np.errstate(divide="ignore"):
        if kind == "stuck":
            v = float(np.clip(value, clip, 1 - clip))
            return float(np.log(v) - np.log1p(-v))
        return float(value) if kind == "reward" else float(np.log(max(value, clip)))


def _estimate(name, kind, truth, belief, u, se_u) -> Estimate:
    """One coordinate of the fit in its own units, the standard error through the slope dθ/du."""
    v = 1 / (1 + np.exp(-u)) if kind == "stuck" else (u if kind == "reward" else np.exp(u))
    slope = v * (1 - v) if kind == "stuck" else (1.0 if kind == "reward" else v)
    z = (abs(u - _to_u(a, kind, clip=0.0)) / se_u if np.isfinite(se_u) else 0.0 for a in (truth, belief))
    return Estimate(name, float(truth), float(belief), float(v), float(se_u * slope), *map(float, z))


_STATIC = ("slots", "codes", "beta", "floor")


def _nll(x, world, q, ref_value, slots, codes, beta, floor):
    """The negative log-likelihood at x = [u (θ on the fit's scale), r (the free rewards), d (distance)]."""
    table = jnp.full(len(TERRAINS) + 1, ref_value).at[jnp.asarray(codes, jnp.int32)].set(x[len(slots) : -1])
    return -log_likelihood(world, slots, _to_theta(x[: len(slots)], slots), table, x[-1], q, beta, floor)


_nll_traced_once = jax.jit(_nll, static_argnames=_STATIC)
"""``_nll`` as one call in the programs below: L-BFGS's line search evaluates it in several places, and
a jitted function is traced once per signature rather than at each (halves their tracing time)."""
_hessian = jax.jit(jax.hessian(_nll_traced_once), static_argnames=_STATIC)


@partial(jax.jit, static_argnames=_STATIC)
def _fit(x0, precond, steps, world, q, ref_value, slots, codes, beta, floor):
    """L-BFGS (at most ``steps``) on y, x = x0 + precond · y from y = 0; a zero row of ``precond`` holds that x."""

    def loss(y):
        return _nll_traced_once(x0 + precond @ y, world, q, ref_value, slots, codes, beta, floor)

    opt = optax.lbfgs(linesearch=optax.scale_by_zoom_linesearch(max_linesearch_steps=10))
    vg = optax.value_and_grad_from_state(loss)

    def body(carry):
        y, state, i, _, v_last = carry
        v, g = vg(y, state=state)
        upd, state = opt.update(g, state, y, value=v, grad=g, value_fn=loss)
        return optax.apply_updates(y, upd), state, i + 1, jnp.linalg.norm(g), jnp.stack([v_last[1], v])

    def going(carry):
        _, _, i, g_norm, (before, now) = carry
        return (i < steps) & (g_norm > GRAD_TOL) & ~(before - now < VALUE_TOL)

    y0 = jnp.zeros_like(x0)
    y, *_ = jax.lax.while_loop(going, body, (y0, opt.init(y0), 0, jnp.inf, jnp.full(2, jnp.inf)))
    return x0 + precond @ y, -loss(y)


def _whiten(hess: np.ndarray, hold: int | None = None) -> jax.Array:
    """|H|^(−1/2) over the free coordinates (all but ``hold``), zero in the held row and column."""
    keep = np.arange(len(hess)) != (-1 if hold is None else hold)
    w, v = np.linalg.eigh(hess[np.ix_(keep, keep)])
    w = np.maximum(np.abs(w), 1e-6 * np.abs(w).max() + 1e-12)
    out = np.zeros_like(hess)
    out[np.ix_(keep, keep)] = (v / np.sqrt(w)) @ v.T
    return jnp.asarray(out, jnp.float32)


def _stderr(hess: np.ndarray) -> np.ndarray:
    """sqrt(diag(H⁻¹)), H scaled to a unit diagonal first; infinite along directions where the likelihood is flat."""
    d = np.diag(hess)
    seen, se = d > 1e-12 * max(d.max(), 1e-12), np.full(len(d), np.inf)
    w, v = np.linalg.eigh(hess[np.ix_(seen, seen)] / np.sqrt(np.outer(d[seen], d[seen])))
    ok = w > 1e-6
    blind = (v[:, ~ok] ** 2).sum(1) > 1e-3  # float32 noise leaks ~1e-6 into every direction
    se[seen] = np.where(blind, np.inf, np.sqrt((v[:, ok] ** 2 / w[ok]).sum(1) / d[seen]))
    return se


def fit_belief(q: Queries, world_params, belief_params, *, beta, log_t_floor, steps=10, profile=None, grid=None):
    """The ML fit of θ and the reward to ``q`` (see the module docstring): rounds of at most ``steps``
    L-BFGS steps, each whitened by the Hessian where it starts. ``profile``: the parameter to profile
    (default: the first biased one; "" for none) on ``grid`` (default: 0.05 … 0.95 for a probability)."""
    if beta is None:
        raise ValueError(NO_SCALE)
    slots = tuple(parameter_slots(world_params, world_params.dynamics, belief_params.dynamics))
    theta_t = np.asarray(_get(world_params.dynamics, slots), np.float64)
    theta_h = np.asarray(_get(belief_params.dynamics, slots), np.float64)
    terr = np.asarray(jax.vmap(lambda s: terrain_at(world_params, s))(q.pos.reshape(-1, 2)))
    seen = sorted({int(c) for c in terr[np.asarray(q.live).reshape(-1)]})
    ref = FLOOR if FLOOR in seen else seen[0]
    codes = tuple(c for c in seen if c != ref)
    rw = world_params.rewards  # r_H by terrain, as the state form defines it
    r_h = {c: float(rw.step + rw.goal * (TERRAINS[c] == "goal") + rw.pit * (TERRAINS[c] == "pit")) for c in seen}
    p, args = len(slots), (world_params, q, r_h[ref])
    kw = dict(slots=slots, codes=codes, beta=float(beta), floor=float(log_t_floor))
    x = jnp.asarray([_to_u(t, f) for t, (_, f, _) in zip(theta_t, slots)] + [0.0] * (len(codes) + 1), jnp.float32)
    hess, ll = np.asarray(_hessian(x, *args, **kw), np.float64), -np.inf
    for _ in range(ROUNDS):  # L-BFGS whitened by the Hessian where each round starts: a quasi-Newton walk
        x, new = _fit(x, _whiten(hess), steps, *args, **kw)
        hess, gain, ll = np.asarray(_hessian(x, *args, **kw), np.float64), float(new) - ll, float(new)
        if gain < ROUND_TOL:
            break
    names = [n for n, _, _ in slots] + [TERRAINS[c] for c in codes] + ["distance"]
    kinds = [f for _, f, _ in slots] + ["reward"] * (len(codes) + 1)
    r_free = [r_h[c] for c in codes] + [float(rw.distance)]
    truth, belief = [*theta_t, *r_free], [*theta_h, *r_free]
    est = [_estimate(*e) for e in zip(names, kinds, truth, belief, np.asarray(x, np.float64), _stderr(hess))]
    held = Estimate(TERRAINS[ref], r_h[ref], r_h[ref], r_h[ref], 0.0, 0.0, 0.0)
    fit = BeliefFit(est[:p], [held, *est[p:]], float(ll), None)
    if profile is None:
        profile = next((e.name for e in fit.parameters if abs(e.belief - e.truth) > 1e-6), "")
    if not profile:
        return fit
    j = names.index(profile)
    if grid is None:
        lo, hi = min(theta_t[j], theta_h[j]), max(theta_t[j], theta_h[j])
        grid = np.linspace(0.05, 0.95, 10) if kinds[j] == "stuck" else np.linspace(0.5 * lo, 1.5 * hi, 10)
    grid = np.asarray(grid, np.float64)
    lls = _profile(x, hess, j, np.array([_to_u(g, kinds[j]) for g in grid]), 2 * steps, args, kw)
    return fit._replace(profile=Profile(profile, grid, lls - float(ll)))


def _profile(x, hess, j, u, steps, args, kw) -> np.ndarray:
    """The log-likelihood maximised over all but x[j], at each x[j] = u[k]: outward from the optimum x,
    each point started from its neighbour's optimum."""
    whiten, lls, order = _whiten(hess, hold=j), {}, np.argsort(u)
    k0 = int(np.argmin(np.abs(u[order] - float(x[j]))))
    for walk in (order[k0:], order[:k0][::-1]):
        at = x
        for k in walk:
            at, lls[k] = _fit(at.at[j].set(u[k]), whiten, steps, *args, **kw)
    return np.asarray([float(lls[k]) for k in range(len(u))])


def verdict(fit: BeliefFit, name: str) -> str:
    """ "recovered", "not identified", "not told from the truth", "away from the belief" or "unbiased"."""
    e = next(e for e in fit.parameters if e.name == name)
    if abs(e.belief - e.truth) <= 1e-6:
        return "unbiased"
    flat = fit.profile is not None and fit.profile.name == name and fit.profile.span < FLAT_NATS
    if flat or not e.stderr < SE_GAP * abs(e.belief - e.truth):
        return "not identified"
    if e.z_truth < Z_MARGIN:
        return "not told from the truth"
    return "recovered" if e.z_belief <= Z_MARGIN else "away from the belief"


FIELD_WAVES = 8
"""Plane waves summed into the smooth error field of :func:`imprecise_moves`."""
FIELD_WAVELENGTH = (3.0, 8.0)
"""Their wavelengths are drawn uniformly between these (cells): smooth on the scale of a step."""


def imprecise_moves(q: Queries, precision: float, key: jax.Array) -> Queries:
    """The queries as a learner sees them whose predicted move mean errs by a smooth field of RMS
    ``precision`` cells: every move's next position shifted by −δ(s) (so the learner's density of it
    is its own density at a mean shifted by +δ(s)); stays, the answers and the reward's inputs unchanged.

    δ(s) is a sum of :data:`FIELD_WAVES` plane waves of random direction, wavelength and phase per axis,
    scaled so that E|δ|² = precision² over uniformly spread positions. A learned dynamics model errs
    smoothly, not independently per step; this is the learner the design check's fit then assumes.
    """
    if precision <= 0:
        return q
    k_dir, k_len, k_phase = jax.random.split(key, 3)
    angle = jax.random.uniform(k_dir, (FIELD_WAVES,), minval=0.0, maxval=2 * jnp.pi)
    length = jax.random.uniform(k_len, (FIELD_WAVES,), minval=FIELD_WAVELENGTH[0], maxval=FIELD_WAVELENGTH[1])
    freq = (2 * jnp.pi / length)[:, None] * jnp.stack([jnp.cos(angle), jnp.sin(angle)], -1)  # [M, 2]
    phase = jax.random.uniform(k_phase, (FIELD_WAVES, 2), minval=0.0, maxval=2 * jnp.pi)
    # per axis a sum of M sines of RMS 1/√2 each, over √M: RMS precision/√2 per axis, precision in all
    arg = jnp.einsum("...i,mi->...m", q.pos, freq)[..., None] + phase  # [..., M, 2]
    delta = precision * jnp.sin(arg).sum(-2) / jnp.sqrt(FIELD_WAVES)
    stay = is_stay(q.pos, q.nxt)[..., None]
    return q._replace(nxt=jnp.where(stay, q.nxt, q.nxt - delta))


def fit_world(
    world, belief: str | None = None, cfg: DesignConfig = DesignConfig(), *, episodes=64, planned=None,
    precision: float = 0.0, **fit,
) -> BeliefFit:  # fmt: skip
    """:func:`fit_belief` on ``cfg.budget`` queries from the design check's behaviour (its optimal
    and unaware policies, ε-random) in a terrain world, answered by the person of ``belief``.
    ``planned``: :func:`~.design_check.plan_policies`'s result, when the caller has it. ``precision``:
    the learner's move mean errs by a smooth field of this RMS (cells; :func:`imprecise_moves`)."""
    if cfg.teacher.beta is None:
        raise ValueError(NO_SCALE)
    bparams, floor = world.belief(belief), cfg.teacher.log_t_floor
    d, _, policies = planned if planned is not None else plan_policies(world, bparams, cfg)  # the design check's own
    behaviour = [np.asarray(policies["optimal"]), np.asarray(policies["unaware"])]
    key, beta = jax.random.fold_in(rng.key(cfg.seed), 1), cfg.teacher.beta
    q = simulate_queries(key, world.params, bparams, behaviour, ACTIONS, d.index, cfg.n, beta=beta, budget=cfg.budget,
                         segment=cfg.segment, log_t_floor=floor, episodes=episodes)  # fmt: skip
    q = imprecise_moves(q, precision, jax.random.fold_in(key, 2))
    return fit_belief(q, world.params, bparams, beta=beta, log_t_floor=floor, **fit)
