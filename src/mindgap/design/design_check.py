"""Is a terrain world a valid test of PrefBias? The design check behind ``mindgap design check WORLD``.

By exact finite-horizon planning on the discretised world (:mod:`~.finite_horizon`) it
compares the policies of three rewards, each run in the true world and scored by r_H:

* **optimal** — r_H itself: what PrefBias should recover;
* **unaware** — r_H + E_T[log T_H]: what a learner that ignores the person's belief (PEBBLE)
  converges to, since the person's answers rank segments by Σ [r_H + log T_H] (Eq. 3.2);
* **unbiased** — r_H + E_T[log T]: the same learner taught by a person without bias.

Scores are normalised between a uniformly random policy (0) and the optimal one (1). It also
reports the per-step bias E_T[log T_H − log T] = −KL(T ‖ T_H) on each terrain, whether the
belief is identifiable from preferences at the budget (:mod:`~.identifiability`), and the
conditions of docs/experiments/identifiability.md that the world and person meet.

The verdict: a world is a valid test of PrefBias when the unaware learner loses a clear
share of the optimal return (normalised ≤ :data:`UNAWARE_AT_MOST`) and every biased belief
parameter is identified. Worlds that fail stay usable (the dissertation's own are kept by
name); the check says why they fail.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..envs.terrain.dynamics import log_prob_pos, sample_next, terrain_at
from ..envs.terrain.layout import GOAL, PIT, TERRAINS
from ..planning.finite_horizon import Outcome, backward, forward
from ..planning.identifiability import Parameter, belief_information
from ..planning.terrain import Discretised, compass_actions, discretise
from ..teachers.preference import TeacherConfig

UNAWARE_AT_MOST = 0.8
"""A valid world: the unaware learner's policy earns at most this share of the optimal-vs-random gap."""
UNBIASED_AT_LEAST = 0.9
"""A sound world: the learner taught by an unbiased person earns at least this share (else a warning)."""
ACTIONS = np.concatenate([compass_actions(16), np.zeros((1, 2), np.float32)])
"""The planner's actions: 16 full pushes and standing still (a fixed horizon rewards staying in the goal)."""


@dataclasses.dataclass(frozen=True)
class DesignConfig:
    """What the check assumes of the study."""

    n: int = 4
    """Sub-cells per cell side of the discretisation."""
    budget: int = 800
    """Answered queries (pairs of segments)."""
    segment: int = 10
    """Steps per segment."""
    draws: int = 32
    """True next states drawn per (sub-cell, action) for E_T[log T_H]."""
    teacher: TeacherConfig = TeacherConfig()
    """The person (β, the floor on log T_H)."""
    seed: int = 0


class Condition(NamedTuple):
    """One identifiability condition: what it says and whether the world and person meet it."""

    text: str
    met: bool
    why: str


class DesignCheck(NamedTuple):
    """Result of :func:`design_check`."""

    world: str
    belief: str
    outcomes: dict[str, Outcome]
    """optimal, unaware, unbiased and random."""
    normalised: dict[str, float]
    bias: dict[str, float]
    """Per terrain: the mean per-step E_T[log T_H − log T] (−KL; 0 without bias)."""
    parameters: list[Parameter]
    conditions: list[Condition]

    @property
    def routes_differ(self) -> bool:
        return self.normalised["unaware"] <= UNAWARE_AT_MOST

    @property
    def identifiable(self) -> bool:
        biased = [p for p in self.parameters if p.biased]
        return bool(biased) and all(p.identified for p in biased)

    @property
    def valid(self) -> bool:
        return self.routes_differ and self.identifiable

    def as_dict(self) -> dict:
        """The check as plain JSON values (an infinite standard error as null)."""
        return _finite(self._as_dict())

    def _as_dict(self) -> dict:
        return {
            "world": self.world,
            "belief": self.belief,
            "valid": self.valid,
            "routes_differ": self.routes_differ,
            "identifiable": self.identifiable,
            "outcomes": {k: v._asdict() for k, v in self.outcomes.items()},
            "normalised": self.normalised,
            "bias_per_step": self.bias,
            "parameters": [{**p._asdict(), "z": p.z, "identified": p.identified} for p in self.parameters],
            "conditions": [c._asdict() for c in self.conditions],
        }


def _finite(x):
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


@partial(jax.jit, static_argnames=("draws", "floor"))
def expected_log_t(key, world_params, scored_params, positions, actions, draws: int, floor: float):
    """[N, K] E_{s' ~ T}[max(log T'(s' | s, a), floor)]: the true dynamics drawn, ``scored_params``' density scored.

    The person's own per-step term (the teacher floors log T_H the same way), at each
    sub-cell centre and action.
    """

    def one(s, a, k):
        nxt = jax.vmap(lambda kk: sample_next(kk, world_params, s, a))(jax.random.split(k, draws))
        lp = jax.vmap(lambda q: log_prob_pos(scored_params, s, a, q))(nxt)
        return jnp.maximum(lp, floor).mean()

    keys = jax.random.split(key, positions.shape[0] * actions.shape[0]).reshape(positions.shape[0], actions.shape[0])
    return jax.vmap(lambda s, ks: jax.vmap(lambda a, k: one(s, a, k))(actions, ks))(positions, keys)


def conditions(world, cfg: DesignConfig, parameters: list[Parameter]) -> list[Condition]:
    """The conditions of docs/experiments/identifiability.md, as this world and person meet them."""
    rw = world.params.rewards
    state_form = float(rw.state_form) > 0.5
    s_prime_free = state_form or (float(rw.progress) == 0 and float(rw.goal) == 0 and float(rw.pit) == 0)
    fixed = float(world.params.fixed_horizon) > 0.5
    beta = cfg.teacher.beta
    biased = [p for p in parameters if p.biased]
    blind = [p.name for p in biased if not np.isfinite(p.stderr)]
    return [
        Condition(
            "the person answers by Bradley–Terry with a finite β (Eq. 3.4)",
            beta is not None,
            f"β = {beta}" if beta is not None else "deterministic answers fix no scale of the score",
        ),
        Condition(
            "r_H depends on (s, a) only, as the learner's r_w does",
            s_prime_free,
            "state-form reward" if state_form else "the reward's progress, goal or pit terms depend on the next state",
        ),
        Condition(
            "segments have equal length (a fixed horizon)",
            fixed,
            "fixed horizon" if fixed else "episodes end at the goal or a pit, so segments that reach one are shorter",
        ),
        Condition(
            "the truth has more than one outcome wherever the belief is biased",
            bool(biased) and not blind,
            "no biased parameter" if not biased else ("no information on " + ", ".join(blind) if blind else "yes"),
        ),
    ]


def _expected_log_t(key, world, scored_params, d: Discretised, cfg: DesignConfig) -> jax.Array:
    """[N, K] :func:`expected_log_t` on the discretised world, 0 at terminal states."""
    log = expected_log_t(
        key, world.params, scored_params, d.positions, jnp.asarray(ACTIONS), cfg.draws, cfg.teacher.log_t_floor
    )
    return jnp.where(~d.terminal[:, None], log, 0.0)


def plan_policies(world, bparams, cfg: DesignConfig) -> tuple[Discretised, jax.Array, dict]:
    """The discretised world, E_T[log T_H] ``[N, K]`` and the time-dependent policies optimal under r_H
    (``optimal``) and under r_H + E_T[log T_H] (``unaware``), each ``[H, N]``.

    These two policies, ε-random, also supply the segments of the identifiability measures
    (:func:`~.identifiability.belief_information`, :func:`~.belief_fit.fit_world`).
    """
    d = discretise(world.params, cfg.n, ACTIONS)
    k_h, _ = jax.random.split(rng.key(cfg.seed))
    log_h = _expected_log_t(k_h, world, bparams, d, cfg)
    policies = {
        "optimal": backward(d, d.rewards, world.horizon)[1],
        "unaware": backward(d, d.rewards + log_h, world.horizon)[1],
    }
    return d, log_h, policies


def design_check(world, belief: str | None = None, cfg: DesignConfig = DesignConfig(), planned=None) -> DesignCheck:
    """Plan, compare and measure (see the module docstring) for ``world`` and its ``belief`` (default: the first).

    ``planned``: :func:`plan_policies`'s result for this world, belief and ``cfg``, when the caller has it.
    """
    name = belief or next(iter(world.beliefs))
    bparams = world.belief(name)
    d, log_h, policies = planned if planned is not None else plan_policies(world, bparams, cfg)
    policies = dict(policies)
    _, k_t = jax.random.split(rng.key(cfg.seed))
    log_t = _expected_log_t(k_t, world, world.params, d, cfg)
    policies["unbiased"] = backward(d, d.rewards + log_t, world.horizon)[1]
    outcomes = {k: forward(d, world.params, p, d.rewards) for k, p in policies.items()}
    outcomes["random"] = forward(d, world.params, "uniform", d.rewards)
    gap = outcomes["optimal"].ret - outcomes["random"].ret
    normalised = {
        k: (o.ret - outcomes["random"].ret) / gap if gap > 1e-6 else float("nan") for k, o in outcomes.items()
    }
    parameters = belief_information(
        world.params,
        bparams,
        [np.asarray(policies["optimal"]), np.asarray(policies["unaware"])],
        ACTIONS,
        d.index,
        cfg.n,
        beta=cfg.teacher.beta,
        budget=cfg.budget,
        segment=cfg.segment,
        log_t_floor=cfg.teacher.log_t_floor,
        seed=cfg.seed,
    )
    return DesignCheck(
        world.name,
        name,
        outcomes,
        normalised,
        _bias_by_terrain(world.params, d, np.asarray(log_h - log_t)),
        parameters,
        conditions(world, cfg, parameters),
    )


def _bias_by_terrain(params, d, diff: np.ndarray) -> dict[str, float]:
    terr = np.asarray(jax.vmap(lambda p: terrain_at(params, p))(d.positions))
    out = {}
    for code in np.unique(terr):
        if code in (GOAL, PIT) and float(params.fixed_horizon) < 0.5:
            continue  # terminal: no step is taken from there
        out[TERRAINS[int(code)]] = float(diff[terr == code].mean())
    return out


def report(chk: DesignCheck) -> str:
    """The check as text: routes, bias, identifiability, conditions and the verdict."""
    lines = [f"design check: {chk.world}, belief {chk.belief!r}", ""]
    lines.append("policy (planned on the reward below, run in the true world)   return  normalised  goal   ice   sand")
    labels = {
        "optimal": "optimal: r_H (what PrefBias should recover)",
        "unaware": "unaware: r_H + E log T_H (what PEBBLE learns)",
        "unbiased": "unbiased person: r_H + E log T",
        "random": "uniformly random",
    }
    for k, label in labels.items():
        o = chk.outcomes[k]
        lines.append(
            f"  {label:<58} {o.ret:8.1f}  {chk.normalised[k]:10.2f}  {o.goal:4.0%}  {o.ice:4.0%}  {o.sand:4.0%}"
        )
    lines += ["", "per-step bias E_T[log T_H − log T] (−KL, nats) by terrain:"]
    lines += [f"  {t:<6} {b:+.2f}" for t, b in chk.bias.items()]
    lines += ["", "belief parameters (truth → belief, standard error at the budget, gap in standard errors):"]
    for p in chk.parameters:
        z = "unbiased" if not p.biased else (f"{p.z:.1f} SE" + ("" if p.identified else "  NOT IDENTIFIED"))
        lines.append(f"  {p.name:<12} {p.truth:6.3f} → {p.belief:6.3f}   ± {p.stderr:.3g}   {z}")
    lines += ["", "conditions (docs/experiments/identifiability.md):"]
    lines += [f"  [{'ok' if c.met else '--'}] {c.text}: {c.why}" for c in chk.conditions]
    lines.append("")
    if chk.normalised["unbiased"] < UNBIASED_AT_LEAST:
        lines.append(
            f"warning: even an unbiased person's learner earns {chk.normalised['unbiased']:.2f} of the optimum"
        )
    why = []
    if not chk.routes_differ:
        why.append(f"the unaware learner keeps {chk.normalised['unaware']:.2f} of the optimum (> {UNAWARE_AT_MOST})")
    if not chk.identifiable:
        why.append("the belief is not identified at this budget")
    verdict = "VALID test of PrefBias" if chk.valid else "NOT a valid test of PrefBias: " + "; ".join(why)
    lines.append(f"verdict: {verdict}")
    return "\n".join(lines) + "\n"
