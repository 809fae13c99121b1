"""Experiment ``nav``: PrefBias vs PEBBLE vs SAC on nav1 and nav2 (dissertation §3.4.3, Figs. 16, 17, 21).

On each world a simulated person with the world's belief (nav1: the robot slides on ice and
copes with sand; nav2: the nearer the pit, the likelier a fall) answers preference queries
by Σ [r_H + log T_H]. PrefBias learns from 200, 400 and 800 of them; PEBBLE from the same
person with 800; SAC on the true reward is the oracle. With ``unbiased`` (the default),
PrefBias and PEBBLE also learn from an unbiased person (Σ [r_H + log T]) at the largest
budget: the control that PrefBias costs nothing when there is no bias to find. With ``coin``
(the default), PrefBias at the largest budget also learns from coin-flip answers: the control
that it learns from what the answers contain. All share one
schedule (:func:`~.prefbias_common.learners`); every (world, learner, person) is one job, its
seeds vmapped.

Outputs in the run folder:

* ``curves.csv``: method, world, queries (the budget), seed, step, return (greedy policy,
  true reward), queries_shown;
* ``results.csv``: per world and learner, the final return (mean, std over seeds), the
  normalised score (0 a uniformly random policy, 1 the SAC oracle), ``better_route`` (the
  fraction of seeds on the truly better route: nav1 the ice corridor, nav2 the shortcut past
  the pit; :func:`~.prefbias_common.route_of`), terrain shares, the learned reward's error;
* ``curves_WORLD.png`` (Figs. 16, 17: mean ± std over seeds, the planning check's return
  dashed), ``trajectories_WORLD.png`` (Fig. 21: greedy rollouts of PrefBias with the largest
  budget, PEBBLE and SAC), ``summary.json`` (rows, the claims as measured), ``table.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..plotting.learning import save_learning_curves
from ..plotting.terrain import METHOD_COLOURS, save_panels
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import to_jsonable, write_csv


@dataclass(frozen=True)
class NavConfig:
    """What ``mindgap reproduce nav`` runs."""

    worlds: tuple[str, ...] = ("nav1", "nav2")
    """Named worlds or world files (each needs a belief)."""
    budgets: tuple[int, ...] = (200, 400, 800)
    """PrefBias query budgets."""
    pebble_queries: int = 800
    """PEBBLE's budget (same person, same schedule)."""
    unbiased: bool = True
    """Also run PrefBias (largest budget) and PEBBLE with an unbiased person."""
    coin: bool = True
    """Also run PrefBias (largest budget) on coin-flip answers (:func:`~.prefbias_common.coin_flips`):
    a learner that learns from the answers must do worse on them than on the person's."""
    seeds: int = 10
    """Ten: with five, one oracle seed below the random policy moved nav2's normalised scores by half."""
    methods: tuple[str, ...] = ()
    """More preference learners, by the names they are registered under
    (:func:`~mindgap.algorithms.methods.register`; ``MINDGAP_METHODS`` registers one from a file):
    each runs on every world beside PEBBLE, with PEBBLE's budget and schedule
    (:func:`~.prefbias_common.method_job`). Empty in the dissertation's presets."""
    learners: pc.Learners = field(default_factory=lambda: pc.learners("full"))
    reference: pc.ReferenceConfig = pc.ReferenceConfig()


def preset(name: str) -> NavConfig:
    """``full`` (10 seeds, 50 000 steps, 80 queries a round) or ``fast`` (1 seed, 1500 steps, 30 queries)."""
    if name == "full":
        return NavConfig()
    if name == "fast":
        return NavConfig(
            budgets=(30,), pebble_queries=30, seeds=1, unbiased=False, coin=False, learners=pc.learners("fast")
        )
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: NavConfig) -> list[pc.Job]:
    out = []
    for w in cfg.worlds:
        out += [pc.reference_job(w, cfg.reference), pc.oracle_job(w, cfg.learners)]
        out.append(pc.pebble_job(w, cfg.learners, cfg.pebble_queries))
        out += [pc.method_job(w, name, cfg.learners, cfg.pebble_queries) for name in cfg.methods]
        for q in cfg.budgets:
            pb = replace(cfg.learners.prefbias, queries=q)
            out.append(pc.prefbias_job(w, pb, f"PrefBias ({q} queries)", f"prefbias-q{q}"))
        if cfg.unbiased:
            q = max(cfg.budgets)
            pb = replace(cfg.learners.prefbias, queries=q)
            label = f"PrefBias ({q} queries, unbiased person)"
            out.append(pc.prefbias_job(w, pb, label, f"prefbias-q{q}-unbiased", person="unbiased"))
            out.append(pc.pebble_job(w, cfg.learners, cfg.pebble_queries, person="unbiased"))
        if cfg.coin:
            q = max(cfg.budgets)
            pb = replace(cfg.learners.prefbias, queries=q)
            out.append(
                pc.prefbias_job(
                    w, pb, f"PrefBias ({q} queries, coin-flip answers)", f"prefbias-q{q}-coin", person="coin"
                )
            )
    return out


def run(cfg: NavConfig, out: Path, **kw) -> dict:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    Keywords (``fresh``, ``progress``, ``assemble_only``, ``only``, ``seed_ids``) as
    :func:`~.prefbias_common.run_experiment`; every learner job may train seed by seed.
    """
    return pc.run_experiment(cfg, out, jobs(cfg), write_outputs, name="nav", sliceable=pc.trains_seeds, **kw)


def _order(rec: dict) -> tuple:
    person = {"biased": 0, "unbiased": 1, "coin": 2}.get(rec["tags"].get("person", "biased"), 3)
    rank = {"prefbias": 0, "pebble": 1, "sac": 3}.get(rec["method"], 2)  # a registered learner after PEBBLE
    return (person, rank, rec["tags"].get("queries", 0), rec["method"])


def write_outputs(cfg: NavConfig, out: Path, records: dict) -> dict:
    refs, oracles, learned = pc.split(records)
    rows, curves, claims, table, routes = [], [], [], [], []
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "nav")
        routes.append(f"{world.name}: {wm.route_name(world)}")
        recs = sorted(
            [r for r in learned if r["world"] == spec] + ([oracles[spec]] if spec in oracles else []), key=_order
        )
        if not recs:
            continue
        ref = refs.get(spec)
        mine = [pc.result_row(r, ref, oracles.get(spec)) for r in recs]
        rows += mine
        curves += [c for r in recs for c in pc.curve_rows(r)]
        for r in mine:
            table.append(
                [
                    world.name,
                    r["label"],
                    pc.fmt(r["return_mean"], r["return_std"]),
                    pc.fmt(r["normalised_mean"], r["normalised_std"], 2),
                    pc.share(r["better_route"]),
                    pc.share(r["goal_seeds"]),
                    pc.fmt(r.get("reward_error_mean"), r.get("reward_error_std"), 2),
                ]
            )
        claims += _claims(world, mine)
        _figures(out, world, recs, ref)
    write_csv(out / "results.csv", rows, ["method", "world", "queries", "seeds", "return_mean", "return_std"])
    write_csv(out / "curves.csv", curves, ["method", "world", "queries", "seed", "step", "return"])
    header = ["world", "method", "final return", "normalised", "better route", "reaches goal", "reward error"]
    table_md = (
        f"nav (Figs. 16, 17, 21): greedy return under the true reward, mean ± std over {cfg.seeds} seed(s); "
        "normalised: 0 = random policy, 1 = the SAC oracle's median seed; better route: share of seeds on the "
        f"truly better route ({', '.join(routes)}); reaches goal: share of seeds whose rollouts mostly reach "
        "the goal; reward error: z-scored RMS (0 exact, 1.41 unrelated); persons: biased (r_H + log T_H), "
        "unbiased (r_H + log T), coin (a fair coin: the control that the answers are what is learned from).\n\n"
        + pc.markdown(header, table)
    )
    summary = {"experiment": "nav", "config": to_jsonable(cfg), "results": rows, "claims": claims, "table_md": table_md}
    pc.write_summary(out, summary)
    return summary


PEBBLE_CEILING = 0.8
"""The normalised score PEBBLE must stay at or below on a world that shows the effect (docs/experiments/identifiability.md, "The targets, measured")."""
PREFBIAS_FLOOR = 0.9
"""The normalised score PrefBias must reach (docs/experiments/identifiability.md, "The targets, measured")."""


def _se(a: dict, b: dict) -> float:
    """Standard error of the difference of two rows' normalised means (seeds independent)."""
    return float(np.sqrt(a["normalised_std"] ** 2 / max(a["seeds"], 1) + b["normalised_std"] ** 2 / max(b["seeds"], 1)))


def _claims(world, rows: list[dict]) -> list[dict]:
    """§3.4.3's claims on this world (l. 739, 741) and the project's controls (coin-flip answers,
    an unbiased person), as measured; held is False where not measured. Sources by id:
    :data:`~.claim_sources.SOURCES`."""
    biased = [r for r in rows if r.get("person", "biased") == "biased"]
    unbiased = [r for r in rows if r.get("person") == "unbiased"]
    pb = [r for r in biased if r["method"] == "prefbias"]
    peb = [r for r in biased if r["method"] == "pebble"]
    if not pb:
        return []
    top = max(pb, key=lambda r: r["queries"])
    route = wm.route_name(world)
    out = [
        pc.claim(
            "nav/prefbias-reaches-sac",
            f"{world.name}: {top['label']} reaches the performance of SAC, the oracle "
            f"(normalised score ≥ {PREFBIAS_FLOOR:.0%})",
            top["normalised_mean"] >= PREFBIAS_FLOOR,
            f"normalised {top['normalised_mean']:.2f}",
        )
    ]
    if route != "-":  # a world whose [expect] names the better route
        out.append(
            pc.claim(
                "nav/prefbias-route",
                f"{world.name}: {top['label']} recovers the optimal behaviour as SAC does: {route} in most seeds",
                top["better_route"] > 0.5,
                f"{pc.share(top['better_route'])} of seeds",
            )
        )
    for r in peb:
        out.append(
            pc.claim(
                "nav/pebble-below-sac",
                f"{world.name}: {r['label']} obtains less return than SAC, the oracle "
                f"(normalised score ≤ {PEBBLE_CEILING:.0%})",
                r["normalised_mean"] <= PEBBLE_CEILING,
                f"normalised {r['normalised_mean']:.2f}",
            )
        )
        if route != "-":
            out.append(
                pc.claim(
                    "nav/pebble-route",
                    f"{world.name}: {r['label']} follows the person's biased belief: not {route} in most seeds",
                    r["better_route"] < 0.5,
                    f"{pc.share(1 - r['better_route'])} of seeds off {route}",
                )
            )
        if "reward_error_mean" in top and "reward_error_mean" in r:
            out.append(
                pc.claim(
                    "nav/reward-error",
                    f"{world.name}: PEBBLE's reward is misguided by the biased belief: "
                    f"{top['label']}'s reward error is below {r['label']}'s",
                    top["reward_error_mean"] < r["reward_error_mean"],
                    f"{top['reward_error_mean']:.2f} vs {r['reward_error_mean']:.2f}",
                )
            )
    coin = [r for r in rows if r.get("person") == "coin" and r["method"] == "prefbias"]
    if coin:
        c = coin[0]
        twin = [r for r in pb if r["queries"] == c["queries"]]
        if twin:
            a = twin[0]
            out.append(
                pc.claim(
                    "nav/coin-control",
                    f"{world.name}: {a['label']} learns from the answers: above coin-flip answers by ≥ 2 standard errors",
                    a["normalised_mean"] - c["normalised_mean"] >= 2 * _se(a, c),
                    f"normalised {a['normalised_mean']:.2f} vs {c['normalised_mean']:.2f}",
                )
            )
    u_pb = [r for r in unbiased if r["method"] == "prefbias"]
    u_peb = [r for r in unbiased if r["method"] == "pebble"]
    if u_pb and u_peb:
        a, b = u_pb[0], u_peb[0]
        gap = a["normalised_mean"] - b["normalised_mean"]
        out.append(
            pc.claim(
                "nav/unbiased-control",
                f"{world.name}: with an unbiased person PrefBias is no worse than PEBBLE (within 2 standard errors)",
                gap >= -2 * _se(a, b),
                f"normalised {a['normalised_mean']:.2f} vs {b['normalised_mean']:.2f}",
            )
        )
    return out


def _figures(out: Path, world, recs: list[dict], ref: dict | None) -> None:
    colours = {r["label"]: METHOD_COLOURS[i % len(METHOD_COLOURS)] for i, r in enumerate(recs)}
    save_learning_curves(
        out / f"curves_{world.name}.png",
        {r["label"]: r["curve"] for r in recs},
        title=f"{world.name}: return under the true reward (mean ± std over seeds)",
        reference=ref["plan_return"] if ref else None,
    )
    pb = [r for r in recs if r["method"] == "prefbias"]
    shown = ([max(pb, key=lambda r: r["tags"]["queries"])] if pb else []) + [
        r for r in recs if r["method"] != "prefbias"
    ]
    panels = [(r["label"], world.params, {r["label"]: _flat(r["paths"])}) for r in shown]
    save_panels(out / f"trajectories_{world.name}.png", panels, colours)


def _flat(paths) -> list[np.ndarray]:
    return [np.asarray(p) for seed in paths for p in seed]
