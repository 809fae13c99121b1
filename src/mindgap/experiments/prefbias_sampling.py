"""Experiment ``sampling``: PrefBias's four query samplers on nav1 (dissertation §3.4.3.2).

Each feedback round keeps K of 3K random pairs of segments by ``uniform`` (no scoring),
``disagreement`` (spread of the predicted preference over posterior draws), ``entropy``
(binary entropy of their mean) or ``preference_disagreement`` (KL between the preference
predicted with the agent's dynamics f_ψ and with the learned belief f_φ, §3.3.3.3); see
:mod:`~mindgap.algorithms.prefbias_queries`. Same biased person, budget and schedule for all;
a SAC oracle and a random policy for the normalised score. The dissertation found
preference disagreement slightly better, "but not much".

Outputs in the run folder: ``curves.csv`` (method, world, queries, sampler, seed, step,
return), ``results.csv`` (per sampler: final return, normalised score, share of seeds on
the truly better route, belief and reward errors; mean and std over seeds),
``curves_WORLD.png`` (return curves, mean ± std over seeds), ``final_WORLD.png`` (bars of the
final return, belief and reward errors), ``summary.json`` and ``table.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from ..plotting.learning import save_learning_curves
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import to_jsonable, write_csv


@dataclass(frozen=True)
class SamplingConfig:
    """What ``mindgap reproduce sampling`` runs."""

    worlds: tuple[str, ...] = ("nav1",)
    """Named worlds or world files (each needs a belief)."""
    samplers: tuple[str, ...] = ("uniform", "disagreement", "entropy", "preference_disagreement")
    """The four samplers of §3.4.3.2, named: a sampler registered later (a user's) is not one of the
    dissertation's, and must not change this experiment's preset."""
    queries: int = 800
    seeds: int = 10
    learners: pc.Learners = field(default_factory=lambda: pc.learners("full"))
    reference: pc.ReferenceConfig = pc.ReferenceConfig()


def preset(name: str) -> SamplingConfig:
    """``full`` (10 seeds, 800 queries, 50 000 steps) or ``fast`` (1 seed, 30 queries, 1500 steps)."""
    if name == "full":
        return SamplingConfig()
    if name == "fast":
        return SamplingConfig(queries=30, seeds=1, learners=pc.learners("fast"))
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: SamplingConfig) -> list[pc.Job]:
    out = []
    for w in cfg.worlds:
        out += [pc.reference_job(w, cfg.reference), pc.oracle_job(w, cfg.learners)]
        for s in cfg.samplers:
            pb = replace(cfg.learners.prefbias, queries=cfg.queries, sampler=s)
            out.append(pc.prefbias_job(w, pb, f"PrefBias, {s}", f"prefbias-{s}", sampler=s))
    return out


def run(cfg: SamplingConfig, out: Path, **kw) -> dict:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    Keywords (``fresh``, ``progress``, ``assemble_only``, ``only``, ``seed_ids``) as
    :func:`~.prefbias_common.run_experiment`; every learner job may train seed by seed.
    """
    return pc.run_experiment(cfg, out, jobs(cfg), write_outputs, name="sampling", sliceable=pc.trains_seeds, **kw)


def write_outputs(cfg: SamplingConfig, out: Path, records: dict) -> dict:
    refs, oracles, learned = pc.split(records)
    rows, curves, table = [], [], []
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "sampling")
        recs = [r for r in learned if r["world"] == spec]
        oracle, ref = oracles.get(spec), refs.get(spec)
        if not recs:
            continue
        mine = [pc.result_row(r, ref, oracle) for r in recs]
        rows += mine + ([pc.result_row(oracle, ref, oracle)] if oracle else [])
        curves += [c for r in recs + [oracle] * (oracle is not None) for c in pc.curve_rows(r)]
        for r in mine:
            table.append(
                [
                    world.name,
                    r["sampler"],
                    pc.fmt(r["return_mean"], r["return_std"]),
                    pc.fmt(r["normalised_mean"], r["normalised_std"], 2),
                    pc.share(r["better_route"]),
                    pc.fmt(r.get("belief_error_mean"), r.get("belief_error_std"), 3),
                    pc.fmt(r["reward_error_mean"], r["reward_error_std"], 2),
                ]
            )
        runs = {r["label"]: r["curve"] for r in recs}
        if oracle is not None:
            runs[oracle["label"]] = oracle["curve"]
        save_learning_curves(
            out / f"curves_{world.name}.png",
            runs,
            title=f"{world.name}: PrefBias by query sampler (mean ± std over seeds)",
            reference=ref["plan_return"] if ref else None,
        )
        pc.save_bars(
            out / f"final_{world.name}.png",
            [
                ("final return (true reward)", {r["tags"]["sampler"]: r["final"] for r in recs}),
                ("belief error (noise RMS, cells)", {r["tags"]["sampler"]: r.get("belief_error") or [] for r in recs}),
                ("reward error (z-scored RMS)", {r["tags"]["sampler"]: r["reward_error"] for r in recs}),
            ],
            title=f"{world.name}: query samplers (§3.4.3.2)",
        )
    write_csv(
        out / "results.csv",
        rows,
        ["method", "world", "sampler", "queries", "seeds", "return_mean", "return_std", "normalised_mean"],
    )
    write_csv(out / "curves.csv", curves, ["method", "world", "queries", "sampler", "seed", "step", "return"])
    header = ["world", "sampler", "final return", "normalised", "better route", "belief error", "reward error"]
    table_md = (
        f"sampling (§3.4.3.2): PrefBias with {cfg.queries} queries by sampler, mean ± std over {cfg.seeds} "
        "seed(s); normalised: 0 = random policy, 1 = SAC oracle; better route: share of seeds on the truly "
        "better route; belief error in cells; reward error z-scored RMS (0 exact, 1.41 unrelated).\n\n"
        + pc.markdown(header, table)
    )
    summary = {"experiment": "sampling", "config": to_jsonable(cfg), "results": rows, "table_md": table_md}
    pc.write_summary(out, summary)
    return summary
