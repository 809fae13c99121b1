"""Experiment ``lambda``: EPS's reconciliation factor λ from 0 to 3 on d1–d4 (dissertation §4.4.1.4, Fig. 31).

λ weighs the person's expectations (u_H, and the entropy terms) against the task reward in
Eq. 4.6: at λ = 0 EPS is SAC on r_A with no entropy bonus; the larger λ, the more it does
what the person expects. One EPS job per (world, λ), seeds vmapped, all on the schedule of
``mindgap reproduce eps`` (:func:`~.eps_common.learners`), plus the person's job per world.

Outputs in the run folder:

* ``results.csv``: per world and λ, the return and explicability score of ``rollouts``
  stochastic episodes per seed (mean, std over seeds), greedy return, routes;
* ``curves.csv``; ``table.md``; ``summary.json`` (with the claims per world: the
  explicability score rises and the return falls with λ, each within seed noise of
  monotone — :func:`~.eps_common.monotone_within_noise`);
* ``routes.png`` (Fig. 31: per world, each λ's greedy routes from light green, small λ,
  to dark green, large λ, over the person's expected routes in blue), ``lambda.png``
  (return and explicability against λ, one line per world, ± std over seeds).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._io import atomic_write
from ..plotting.terrain import save_panels
from . import eps_common as ec
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import to_jsonable, write_csv
from .eps_table import PERSON_COLOUR


@dataclass(frozen=True)
class LambdaConfig:
    """What ``mindgap reproduce lambda`` runs."""

    worlds: tuple[str, ...] = ("d1", "d2", "d3", "d4")
    lams: tuple[float, ...] = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
    """The λ values (the dissertation's range is [0, 3])."""
    seeds: int = 5
    learners: ec.EPSLearners = field(default_factory=lambda: ec.learners("full"))


def preset(name: str) -> LambdaConfig:
    """``full`` (λ 0, 0.5, …, 3; 5 seeds, 60 000 steps) or ``fast`` (λ 0, 1.5, 3; 1 seed, 1500 steps)."""
    if name == "full":
        return LambdaConfig()
    if name == "fast":
        return LambdaConfig(lams=(0.0, 1.5, 3.0), seeds=1, learners=ec.learners("fast"))
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: LambdaConfig) -> list[pc.Job]:
    if len(cfg.lams) < 2 or any(b <= a for a, b in zip(cfg.lams, cfg.lams[1:])):
        raise ValueError(f"λ values must be at least two and increasing, got {cfg.lams}")
    out = []
    for w in cfg.worlds:
        out.append(ec.person_job(w, cfg.learners))
        out += [ec.eps_job(w, cfg.learners, lam) for lam in cfg.lams]
    return out


def run(cfg: LambdaConfig, out: Path, **kw) -> dict:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    Keywords (``fresh``, ``progress``, ``assemble_only``, ``only``) as
    :func:`~.prefbias_common.run_experiment`.
    """
    return ec.run_experiment(cfg, out, jobs(cfg), write_outputs, name="lambda", **kw)


def write_outputs(cfg: LambdaConfig, out: Path, records: dict) -> dict:
    people = ec.persons(records)
    rows, curves, claims, table, panels, series = [], [], [], [], [], {}
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "lambda")
        person = people.get((spec, "biased"))
        recs = sorted(
            (r for r in records.values() if r["world"] == spec and r["method"] == "eps"), key=lambda r: r["tags"]["lam"]
        )
        if not recs:
            continue
        mine = [ec.result_row(world, r, person) for r in recs]
        rows += mine
        curves += [c for r in recs for c in pc.curve_rows(r)]
        for r in mine:
            table.append(
                [
                    world.name,
                    f"{r['lam']:g}",
                    pc.fmt(r["return_mean"], r["return_std"]),
                    pc.fmt(r["explicability_mean"], r["explicability_std"]),
                    pc.share(r["required_route"]),
                    pc.share(r["goal_rate"]),
                    _count(r["held_still"], r["seeds"]),
                ]
            )
        series[world.name] = mine
        claims += _claims(world, mine, cfg.seeds)
        panels.append(_routes_panel(world, person, recs, cfg.lams))
    if panels:
        save_panels(out / "routes.png", [p for p, _ in panels], {k: v for _, c in panels for k, v in c.items()})
    if series:
        _save_lambda_plot(out / "lambda.png", series)
    write_csv(out / "results.csv", rows, ["method", "world", "lam", "seeds", "return_mean", "return_std"])
    write_csv(out / "curves.csv", curves, ["method", "world", "lam", "seed", "step", "return"])
    table_md = (
        f"lambda (Fig. 31): EPS with λ from {cfg.lams[0]:g} to {cfg.lams[-1]:g}; return and explicability "
        f"score of {cfg.learners.rollouts} stochastic rollouts per seed, mean ± std over {cfg.seeds} seed(s); "
        "required route: share of seeds on the route EPS should take; goal: share of greedy rollouts "
        "reaching the goal; held still: seeds whose greedy rollouts mostly stop short of the goal.\n\n"
        + pc.markdown(["world", "λ", "return", "explicability", "required route", "goal", "held still"], table)
    )
    summary = {
        "experiment": "lambda",
        "config": to_jsonable(cfg),
        "results": rows,
        "claims": claims,
        "table_md": table_md,
    }
    pc.write_summary(out, summary)
    return summary


def _claims(world, rows: list[dict], seeds: int) -> list[dict]:
    """Fig. 31 (§4.4.1.4, l. 1008): "the lower the λ, the closer the behavior is to the SAC agent, while the
    higher the λ, the closer the behavior is to the human's expectation", checked as the explicability
    score rising and the return (which SAC maximises) falling across λ, each within seed noise."""
    if len(rows) < 2:
        return []
    out = []
    for claim_id, statement, name, rising, verb in (
        (
            "lambda/explicability-rises",
            "the higher λ, the closer EPS to the person's expectation",
            "explicability",
            True,
            "rises",
        ),
        ("lambda/return-falls", "the lower λ, the closer EPS to SAC", "return", False, "falls"),
    ):
        means = [r[f"{name}_mean"] for r in rows]
        held, worst = ec.monotone_within_noise(means, [r[f"{name}_std"] for r in rows], seeds, rising)
        out.append(
            pc.claim(
                claim_id,
                f"{world.name}: {statement}: the {name} {verb} with λ within seed noise",
                held,
                ", ".join(f"{m:.1f}" for m in means)
                + (
                    f" (worst reversal {worst:.1f} standard errors)"
                    if seeds > 1
                    else " (one seed: no noise to judge by)"
                ),
            )
        )
    return out


def _shades(lams) -> dict[float, tuple]:
    """Light green for the smallest λ to dark green for the largest (Fig. 31)."""
    import matplotlib

    cmap = matplotlib.colormaps["Greens"]
    lo, hi = min(lams), max(lams)
    return {lam: cmap(0.3 + 0.7 * (lam - lo) / max(hi - lo, 1e-9)) for lam in lams}


def _routes_panel(world, person: dict | None, recs: list[dict], lams) -> tuple:
    shade = _shades(lams)
    trajs, colours = {}, {}
    if person is not None:
        trajs["person expects"] = [np.asarray(p) for p in person["expected_paths"]]
        colours["person expects"] = PERSON_COLOUR
    for r in recs:
        label = f"λ {r['tags']['lam']:g}"
        trajs[label] = [np.asarray(p) for seed in r["paths"] for p in seed]
        colours[label] = shade[r["tags"]["lam"]]
    return (f"{world.name}: routes by λ", world.params, trajs), colours


def _save_lambda_plot(path: Path, series: dict[str, list[dict]]) -> None:
    """Return and explicability against λ, one line per world (mean ± std over seeds)."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for name, ax in zip(("return", "explicability"), axes):
        for world, rows in series.items():
            lam = [r["lam"] for r in rows]
            ax.errorbar(
                lam,
                [r[f"{name}_mean"] for r in rows],
                yerr=[r[f"{name}_std"] for r in rows],
                marker="o",
                ms=3,
                capsize=3,
                label=world,
            )
        ax.set_xlabel("λ")
        ax.set_ylabel(name if name == "return" else "explicability score")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=150)
    plt.close(fig)
    atomic_write(path, buf.getvalue())


def _count(n: int | None, seeds: int) -> str:
    """``n of seeds``, or – where it is not measured (a world without a map)."""
    return "–" if n is None else f"{n} of {seeds}"
