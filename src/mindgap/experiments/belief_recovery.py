"""Does PrefBias's inference recover the belief that the answers identify? ``mindgap design recovery``.

The design check (:mod:`~mindgap.design.design_check`) says whether a world's answers *could*
identify the person's belief, and its tabular fit (:mod:`~mindgap.design.belief_fit`) that an
ideal learner recovers it. This takes PrefBias's own inference out of its loop and asks the same
of it, on the same answers:

1. ``budget`` queries between segments of the design check's behaviour (its optimal and unaware
   policies, ε-random), answered by the person (Bradley–Terry on r_H + log T_H, β), and as many
   again, answered alike, held out;
2. the agent's dynamics model f_ψ trained on the training segments' transitions, as the loop
   trains it (:func:`~mindgap.models.gaussian_dynamics.train_dynamics`);
3. q(w) q(φ) fitted to the training answers for ``updates`` rounds
   (:func:`~mindgap.algorithms.prefbias_inference.fit`; ten fits of the full preset's 300);
4. on the held-out segments' true transitions, by terrain of the start: the probability of not
   moving under the truth, the person, f_ψ and f_φ's posterior mean; the spread (standard
   deviation across ``draws`` draws of q(φ)) of f_φ's predicted move mean, in cells and in units
   of the world's noise σ_T there; and how well the posterior mean predicts the held-out answers
   next to the person's own model of them;
5. the tabular maximum-likelihood fit of the belief to the same training answers, the reference.

Everything PrefBias's result depends on enters through :class:`~mindgap.algorithms.prefbias_inference.PrefBiasConfig`,
so a variant (``--set belief_prior_std=0.1``) is measured by the same tool that measures the default
(docs/experiments/identifiability.md, "The belief posterior").
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..algorithms.prefbias_inference import PrefBiasConfig, bt_cross_entropy, fit, prefbias_init, preference_prob
from ..data.prefs import PrefData
from ..data.segments import Segments
from ..design.belief_fit import fit_belief, person_step_score, simulate_queries
from ..design.design_check import ACTIONS, DesignConfig, plan_policies
from ..envs.terrain.dynamics import log_prob_pos, move_model, terrain_at
from ..envs.terrain.layout import TERRAINS
from ..models.bayes import sample_params
from ..models.gaussian_dynamics import dynamics_init, fit_norm, train_dynamics
from ..models.prefbias_nets import belief_predict, belief_stay_prob
from ..planning.terrain_maps import belief_stay_map, table_stay_map

PERSONS = ("biased", "unbiased")
"""Who answers: the world's person (r_H + log T_H) or one whose belief is the truth (r_H + log T)."""
MIN_TRANSITIONS = 20
"""A terrain is reported when at least this many held-out transitions start on it."""


@dataclasses.dataclass(frozen=True)
class RecoveryConfig:
    """The answers and the fit of a recovery check."""

    budget: int = 800
    """Answered queries the fit learns from (as many again are held out)."""
    segment: int = 10
    """Steps per segment."""
    beta: float = 1.0
    """The person's rationality."""
    updates: int = 3000
    """Rounds of the inference (ten fits of the full preset's 300, as the loop's ten feedback rounds)."""
    draws: int = 32
    """Draws of q(φ) for the spread of the predicted move."""
    rounds: int = 1
    """Fit as the loop does: in round r of R, ``updates / R`` rounds on the first r/R of the answers, warm-started
    (the full preset: 10 rounds of 300 on 80, 160, … 800 answers). 1: all answers at once."""
    person: str = "biased"
    tabular: bool = True
    """Also run the tabular maximum-likelihood fit (the reference)."""
    seed: int = 0

    def check(self, pcfg: PrefBiasConfig | None = None) -> None:
        """Refuse a bad setting in one line; with ``pcfg``, also the inference each fit runs
        (``updates / rounds`` rounds of it), before any answer is simulated."""
        if self.budget < 1 or self.segment < 1 or self.updates < 1 or self.draws < 2:
            raise ValueError("budget, segment and updates must be at least 1, draws at least 2")
        if self.rounds < 1 or self.updates % self.rounds:
            raise ValueError(f"updates ({self.updates}) must be a multiple of rounds ({self.rounds})")
        if self.person not in PERSONS:
            raise ValueError(f"unknown person {self.person!r}: choose from {', '.join(PERSONS)}")
        if not self.beta > 0:
            raise ValueError(f"beta must be positive, got {self.beta}")
        if pcfg is not None:
            fit_config(pcfg, self).check()


def fit_config(pcfg: PrefBiasConfig, cfg: RecoveryConfig) -> PrefBiasConfig:
    """The inference of one of the ``cfg.rounds`` fits: ``cfg.updates / cfg.rounds`` rounds of ``pcfg``."""
    return dataclasses.replace(pcfg, updates=cfg.updates // cfg.rounds)


class TerrainRow(NamedTuple):
    """Held-out true transitions starting on one terrain: P(not moving) under each model (``person``: the
    one who answered), and the spread of f_φ's predicted move mean across draws of q(φ) (cells, and in
    units of σ_T)."""

    terrain: str
    transitions: int
    stay_truth: float
    stay_person: float
    stay_psi: float
    stay_phi: float
    spread: float
    spread_sigma: float


class Recovery(NamedTuple):
    """Result of :func:`belief_recovery`."""

    world: str
    belief: str
    person: str
    terrains: list[TerrainRow]
    stay_error: float
    """RMS over the held-out transitions of f_φ's P(not moving) minus the answering person's."""
    prior_stay_error: float
    """The same for f_ψ, the centre of the prior."""
    held_nll: float
    held_accuracy: float
    person_nll: float
    person_accuracy: float
    train_accuracy: float
    fit_held_nll: float
    tabular: list[dict] | None
    config: dict
    maps: dict
    """P(not moving) at each cell centre (:mod:`~mindgap.planning.terrain_maps`): ``person`` (the one who
    answered), ``f_psi``, ``f_phi``; [H, W] nested lists, None on walls."""

    def row(self, terrain: str) -> TerrainRow:
        """The row of ``terrain`` (ValueError naming the reported ones if it has too few transitions)."""
        for r in self.terrains:
            if r.terrain == terrain:
                return r
        raise ValueError(f"no terrain {terrain!r} reported; have {', '.join(r.terrain for r in self.terrains)}")

    def as_dict(self) -> dict:
        d = self._asdict()
        d["terrains"] = [r._asdict() for r in self.terrains]
        return d


def _person_logits(world_params, belief, floor, q):
    """S(a) − S(b) of each query under the answering person's own reward and belief: [Q]."""

    def score(s, a, s2):
        return person_step_score(world_params, belief, floor, s, a, s2)

    per = jax.vmap(jax.vmap(jax.vmap(score)))(q.pos, q.act, q.nxt)
    s = jnp.sum(jnp.where(q.live, per, 0.0), -1)
    return s[:, 0] - s[:, 1]


def _as_data(world_params, q) -> PrefData:
    """Queries in observation units (as :func:`~mindgap.envs.terrain.world.observe`), as PrefBias stores answers."""
    h, w = world_params.grid.shape
    scale = jnp.array([w, h], jnp.float32)
    obs, nxt = 2 * q.pos / scale - 1, 2 * q.nxt / scale - 1
    seg_a = Segments(obs[:, 0], q.act[:, 0], nxt[:, 0], q.live[:, 0])
    seg_b = Segments(obs[:, 1], q.act[:, 1], nxt[:, 1], q.live[:, 1])
    return PrefData(seg_a, seg_b, q.label.astype(jnp.float32), jnp.asarray(q.label.shape[0], jnp.int32))


def _nll_acc(logit, label) -> tuple[float, float]:
    nll = float(bt_cross_entropy(logit, label).mean())
    return nll, float(((logit > 0) == (label > 0.5)).mean())


def _flat_transitions(world_params, q):
    """The live transitions of every held-out segment: positions, actions, next positions, observations."""
    live = np.asarray(q.live).reshape(-1)
    pos, act, nxt = (np.asarray(x).reshape(-1, 2)[live] for x in (q.pos, q.act, q.nxt))
    h, w = world_params.grid.shape
    scale = np.array([w, h], np.float32)
    return pos, act, nxt, 2 * pos / scale - 1


def belief_recovery(world, pcfg: PrefBiasConfig, cfg: RecoveryConfig = RecoveryConfig(), belief: str | None = None,
                    *, progress=None) -> Recovery:  # fmt: skip
    """Run the check (module docstring) on a terrain world; ``progress(message)`` is told each stage."""
    cfg.check()
    pcfg.check()
    say = progress or (lambda _msg: None)
    person = world.belief(belief)
    answerer = world.params if cfg.person == "unbiased" else person
    floor = DesignConfig().teacher.log_t_floor
    dcfg = DesignConfig(budget=cfg.budget, segment=cfg.segment, seed=cfg.seed)
    say("planning the behaviour")
    d, _, policies = plan_policies(world, person, dcfg)
    behaviour = [np.asarray(policies["optimal"]), np.asarray(policies["unaware"])]
    q, held = (
        simulate_queries(jax.random.fold_in(rng.key(cfg.seed), k), world.params, answerer, behaviour, ACTIONS,
                         d.index, dcfg.n, beta=cfg.beta, budget=cfg.budget, segment=cfg.segment, log_t_floor=floor)
        for k in (1, 11)
    )  # fmt: skip
    data, held_data = _as_data(world.params, q), _as_data(world.params, held)

    say("training f_ψ")
    k_psi0, k_psi, k_init, k_fit, k_draw = jax.random.split(jax.random.fold_in(rng.key(cfg.seed), 2), 5)
    obs, act, nxt, valid = (
        jnp.concatenate([getattr(seg, f).reshape(-1, *getattr(seg, f).shape[2:]) for seg in (data.seg_a, data.seg_b)])
        for f in ("obs", "act", "next_obs", "mask")
    )
    norm = fit_norm(obs, act, nxt, valid)
    start = dynamics_init(k_psi0, 2, 2, pcfg.dynamics, norm, stay=pcfg.stay_head)
    dyn, _ = train_dynamics(k_psi, obs, act, nxt, valid, pcfg.dynamics, init=start)

    say(f"fitting q(w) q(φ) for {cfg.updates} rounds" + (f" in {cfg.rounds} fits" if cfg.rounds > 1 else ""))
    fcfg = fit_config(pcfg, cfg)
    fcfg.check()
    state = prefbias_init(k_init, 2, 2, fcfg, dyn, units=world.obs_units())
    fit_jit = jax.jit(fit, static_argnames="cfg")
    if cfg.rounds == 1:
        state, info = fit_jit(state, data, k_fit, cfg=fcfg)
    else:  # round r learns from the first r/R of the answers, warm-started, as the loop's feedback rounds
        for r in range(1, cfg.rounds + 1):
            part = data._replace(count=jnp.asarray(cfg.budget * r // cfg.rounds, jnp.int32))
            state, info = fit_jit(state, part, jax.random.fold_in(k_fit, r), cfg=fcfg)

    say("measuring")
    p = preference_prob(state.reward.mean, state.belief.mean, state.norm, held_data.seg_a, held_data.seg_b, fcfg,
                        state.log_unit)  # fmt: skip
    p = jnp.clip(p, 1e-6, 1 - 1e-6)
    held_nll, held_acc = _nll_acc(jnp.log(p) - jnp.log1p(-p), held.label)
    person_nll, person_acc = _nll_acc(_person_logits(world.params, answerer, floor, held), held.label)
    rows, errors = _terrain_rows(world, answerer, dyn, state, fcfg, held, k_draw, cfg.draws)
    maps = {
        "person": table_stay_map(answerer),
        "f_psi": belief_stay_map(dyn.params, dyn.norm, world.params),
        "f_phi": belief_stay_map(state.belief.mean, state.norm, world.params),
    }
    maps = {k: [[None if np.isnan(v) else float(v) for v in row] for row in np.asarray(m)] for k, m in maps.items()}
    tabular = None
    if cfg.tabular and cfg.person == "biased":
        say("the tabular fit")
        tab = fit_belief(q, world.params, person, beta=cfg.beta, log_t_floor=floor, profile="")
        tabular = [e._asdict() for e in tab.parameters]
    return Recovery(
        world.name, belief or next(iter(world.beliefs)), cfg.person, rows, *errors, held_nll, held_acc, person_nll, person_acc,
        float(info.accuracy), float(info.held_nll), tabular,
        {"recovery": dataclasses.asdict(cfg), "prefbias": dataclasses.asdict(pcfg)}, maps,
    )  # fmt: skip


def _terrain_rows(world, answerer, dyn, state, pcfg, held, key, draws) -> tuple[list[TerrainRow], tuple[float, float]]:
    wp = world.params
    pos, act, nxt, obs = _flat_transitions(wp, held)
    pos_j, act_j, obs_j = jnp.asarray(pos), jnp.asarray(act), jnp.asarray(obs)
    units = np.asarray(world.obs_units())  # cells per observation unit

    def stay_of(params):
        return np.asarray(jax.vmap(lambda s, a: jnp.exp(log_prob_pos(params, s, a, s)))(pos_j, act_j))

    terr = np.asarray(jax.vmap(lambda s: terrain_at(wp, s))(pos_j))
    sigma = np.asarray(jax.vmap(lambda s, a: move_model(wp, s, a)[1])(pos_j, act_j))
    stay_t, stay_h = stay_of(wp), stay_of(answerer)
    stay_psi = np.asarray(belief_stay_prob(dyn.params, dyn.norm, obs_j, act_j))
    stay_phi = np.asarray(belief_stay_prob(state.belief.mean, state.norm, obs_j, act_j))

    def drawn_mean(k):
        phi = sample_params(state.belief, k)
        return belief_predict(phi, state.norm, obs_j, act_j, pcfg.dynamics.min_std)[0]

    means = np.asarray(jax.vmap(drawn_mean)(jax.random.split(key, draws))) * units  # [draws, T, 2] cells
    spread = np.sqrt(means.var(0).mean(-1))  # [T]: RMS over the axes of the per-axis std across draws
    rows = []
    for code, name in enumerate(TERRAINS):
        at = terr == code
        if at.sum() < MIN_TRANSITIONS:
            continue
        rows.append(TerrainRow(
            name, int(at.sum()), float(stay_t[at].mean()), float(stay_h[at].mean()), float(stay_psi[at].mean()),
            float(stay_phi[at].mean()), float(spread[at].mean()), float((spread[at] / sigma[at]).mean()),
        ))  # fmt: skip
    errors = (float(np.sqrt(np.mean((stay_phi - stay_h) ** 2))), float(np.sqrt(np.mean((stay_psi - stay_h) ** 2))))
    return rows, errors


def report(r: Recovery) -> str:
    """The check as text: one line a terrain, the held-out answers, the tabular reference."""
    c = r.config["recovery"]
    lines = [
        f"belief recovery on {r.world} (belief {r.belief}; answers by the {r.person} person, {c['budget']} to learn from"
        f" and {c['budget']} held out, β = {c['beta']:g}; PrefBias's inference alone, {c['updates']} rounds"
        + (f" in {c['rounds']} fits on growing answers" if c.get("rounds", 1) > 1 else "") + ")",
        "  held-out true transitions by terrain of the start:",
        "    terrain  transitions   P(not moving): truth  person   f_ψ    f_φ    f_φ's move mean across draws",
    ]
    for t in r.terrains:
        lines.append(
            f"    {t.terrain:<8} {t.transitions:>11}   {t.stay_truth:>19.2f}  {t.stay_person:>6.2f}  {t.stay_psi:>5.2f}"
            f"  {t.stay_phi:>5.2f}    spread {t.spread:.3f} cells = {t.spread_sigma:.2f} σ_T"
        )
    lines.append(
        f"  P(not moving) against the answering person's, RMS over the held-out transitions: f_φ {r.stay_error:.3f}"
        f" (f_ψ, the prior's centre: {r.prior_stay_error:.3f})"
    )
    lines.append(
        f"  held-out answers: posterior mean NLL {r.held_nll:.3f} a pair (accuracy {r.held_accuracy:.2f}); the answering"
        f" person's own model {r.person_nll:.3f} ({r.person_accuracy:.2f}); training accuracy {r.train_accuracy:.2f}"
    )
    if r.tabular is not None:
        lines.append("  the tabular maximum-likelihood fit to the same answers (the reference):")
        for e in r.tabular:
            if abs(e["belief"] - e["truth"]) > 1e-6:
                lines.append(
                    f"    {e['name']:<12} truth {e['truth']:.3f} → person {e['belief']:.3f}: {e['estimate']:.3f} ± {e['stderr']:.3f}"
                )
    return "\n".join(lines) + "\n"


def save_figure(r: Recovery, world, path) -> None:
    """The three stay maps side by side: the answering person's, f_ψ's (the prior's centre) and f_φ's."""
    from ..plotting.terrain import save_fields

    def arr(m):
        return np.array([[np.nan if v is None else v for v in row] for row in m], np.float64)

    fields = [
        (f"the {r.person} person", arr(r.maps["person"])),
        ("f_ψ, the prior's centre", arr(r.maps["f_psi"])),
        ("f_φ, the posterior mean", arr(r.maps["f_phi"])),
    ]
    save_fields(path, world.params, fields, label="P(not moving)")
