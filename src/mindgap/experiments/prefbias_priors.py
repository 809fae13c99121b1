"""Experiment ``priors``: PrefBias with the dynamics-based vs a random belief prior (§3.4.3.1, Figs. 22–24).

The centre of p(φ) is either the agent's learned dynamics model f_ψ (``belief_prior =
"dynamics"``, the default: a belief is a disturbance of the true dynamics) or a random
initialisation (``"random"``); everything else is the same, including the biased person and
the query budget. Per prior, with a SAC oracle and a random policy for the normalised score:

* **belief error** (Fig. 22): per seed, the RMS over passable cells between the noise the
  learned belief f_φ predicts and the noise of the person's own table, in cells
  (:func:`~.prefbias_common.noise_rms_error`; ``belief_noise_rms_error`` of ``mindgap
  prefbias``). ``dynamics_error`` is the same for the agent's f_ψ — the error of simply
  assuming the person knows the true dynamics;
* **reward error** (Fig. 23): the z-scored RMS error of the posterior-mean reward against
  the true expected reward on a grid of states × actions (:func:`~.prefbias_common.reward_error`:
  0 exact up to offset and scale, 1.41 unrelated, 2 reversed);
* **return** (Fig. 24): learning curves and the final greedy return under the true reward.

Outputs in the run folder: ``results.csv`` (per world and prior: the three, mean and std
over seeds), ``curves.csv`` (method, world, queries, prior, seed, step, return),
``errors_WORLD.png`` (bars: belief error, reward error, final return), ``curves_WORLD.png``,
``beliefs_WORLD.png`` (noise per cell: the person's table, f_ψ, the learned belief under each
prior), ``summary.json`` (with the claims as measured) and ``table.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..algorithms.prefbias_inference import BELIEF_PRIORS
from ..planning.terrain_maps import table_noise_map, table_stay_map
from ..plotting.learning import save_learning_curves
from ..plotting.terrain import save_fields
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import to_jsonable, write_csv


@dataclass(frozen=True)
class PriorsConfig:
    """What ``mindgap reproduce priors`` runs."""

    worlds: tuple[str, ...] = ("nav1",)
    """Named worlds or world files (each needs a belief)."""
    priors: tuple[str, ...] = BELIEF_PRIORS
    """Centres of p(φ) to compare: 'dynamics' (f_ψ) and 'random'."""
    queries: int = 800
    seeds: int = 10
    learners: pc.Learners = field(default_factory=lambda: pc.learners("full"))
    reference: pc.ReferenceConfig = pc.ReferenceConfig()


def preset(name: str) -> PriorsConfig:
    """``full`` (10 seeds, 800 queries, 50 000 steps) or ``fast`` (1 seed, 30 queries, 1500 steps)."""
    if name == "full":
        return PriorsConfig()
    if name == "fast":
        return PriorsConfig(queries=30, seeds=1, learners=pc.learners("fast"))
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: PriorsConfig) -> list[pc.Job]:
    out = []
    base = cfg.learners.prefbias
    for w in cfg.worlds:
        out += [pc.reference_job(w, cfg.reference), pc.oracle_job(w, cfg.learners)]
        for p in cfg.priors:
            pb = replace(base, queries=cfg.queries, prefbias=replace(base.prefbias, belief_prior=p))
            out.append(pc.prefbias_job(w, pb, f"PrefBias, {p} prior", f"prefbias-{p}", prior=p))
    return out


def run(cfg: PriorsConfig, out: Path, **kw) -> dict:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    Keywords (``fresh``, ``progress``, ``assemble_only``, ``only``, ``seed_ids``) as
    :func:`~.prefbias_common.run_experiment`; every learner job may train seed by seed.
    """
    return pc.run_experiment(cfg, out, jobs(cfg), write_outputs, name="priors", sliceable=pc.trains_seeds, **kw)


def write_outputs(cfg: PriorsConfig, out: Path, records: dict) -> dict:
    refs, oracles, learned = pc.split(records)
    rows, curves, claims, table = [], [], [], []
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "priors")
        recs = [r for r in learned if r["world"] == spec]
        oracle = oracles.get(spec)
        if not recs:
            continue
        mine = [pc.result_row(r, refs.get(spec), oracle) for r in recs]
        rows += mine + ([pc.result_row(oracle, refs.get(spec), oracle)] if oracle else [])
        curves += [c for r in recs + [oracle] * (oracle is not None) for c in pc.curve_rows(r)]
        for r in mine:
            table.append(
                [
                    world.name,
                    r["prior"],
                    pc.fmt(r.get("belief_error_mean"), r.get("belief_error_std"), 3),
                    pc.fmt(r.get("belief_stay_error_mean"), r.get("belief_stay_error_std"), 3),
                    pc.fmt(r.get("dynamics_error_mean"), r.get("dynamics_error_std"), 3),
                    pc.fmt(r["reward_error_mean"], r["reward_error_std"], 2),
                    pc.fmt(r["return_mean"], r["return_std"]),
                    pc.fmt(r["normalised_mean"], r["normalised_std"], 2),
                ]
            )
        claims += _claims(world, mine)
        _figures(out, world, recs, oracle, refs.get(spec))
    write_csv(
        out / "results.csv",
        rows,
        ["method", "world", "prior", "queries", "seeds", "belief_error_mean", "belief_error_std"]
        + ["belief_stay_error_mean", "belief_stay_error_std"]
        + ["reward_error_mean", "reward_error_std", "return_mean", "return_std"],
    )
    write_csv(out / "curves.csv", curves, ["method", "world", "queries", "prior", "seed", "step", "return"])
    header = ["world", "prior", "belief error (noise)", "belief error (stay)", "f_ψ's error", "reward error"]
    header += ["final return", "normalised"]
    table_md = (
        f"priors (Figs. 22–24): PrefBias with {cfg.queries} queries, mean ± std over {cfg.seeds} seed(s). "
        "belief error (noise): RMS over cells of the learned belief's noise minus the person's (cells); "
        "(stay): the same for the probability of not moving; f_ψ's error: the noise error of the agent's "
        "dynamics model; reward error: z-scored RMS (0 exact, 1.41 unrelated); "
        "normalised return: 0 = random policy, 1 = SAC oracle.\n\n" + pc.markdown(header, table)
    )
    summary = {"experiment": "priors", "config": to_jsonable(cfg), "results": rows, "claims": claims}
    summary["table_md"] = table_md
    pc.write_summary(out, summary)
    return summary


ERRORS = {
    "noise": ("belief error (noise)", "belief_error_mean"),
    "stay": ("belief error (stay)", "belief_stay_error_mean"),
}
"""The belief error of each part of the table a person can get wrong (:func:`~.prefbias_common.biased_parts`)."""


def _claims(world, rows: list[dict]) -> list[dict]:
    """§3.4.3.1 (l. 764, Figs. 22–24): the prior centred on the learned dynamics gives the lower error
    on what the person gets wrong (the noise of a move, the probability of not moving, or both), the
    lower reward error, and at least equal return. The rule for "outperforms … in policy learning" is
    weaker than the words: a return at least the random prior's (a tie holds)."""
    by = {r["prior"]: r for r in rows}
    if "dynamics" not in by or "random" not in by:
        return []
    d, r = by["dynamics"], by["random"]
    measures = [ERRORS[p] for p in pc.biased_parts(world)] if wm.has_map(world) else []

    def se(key):  # standard error of the difference of the two priors' means (seeds independent)
        std = key.replace("_mean", "_std")
        return float(np.sqrt(d[std] ** 2 / max(d["seeds"], 1) + r[std] ** 2 / max(r["seeds"], 1)))

    out = [
        pc.claim(
            "priors/belief-error",
            f"{world.name}: with the prior centred on the learned dynamics PrefBias learns the belief "
            f"better: the lower {what} (by at least 2 standard errors)",
            r[key] - d[key] >= 2 * se(key),
            f"{d[key]:.3f} vs {r[key]:.3f} (2 SE = {2 * se(key):.3f})",
        )
        for what, key in measures
        if key in d and key in r  # belief errors need a map
    ]
    if "reward_error_mean" in d and "reward_error_mean" in r:
        d_err, r_err = d["reward_error_mean"], r["reward_error_mean"]
        out.append(
            pc.claim(
                "priors/reward-error",
                f"{world.name}: the dynamics prior outperforms the random prior in reward learning: the lower reward error",
                d_err < r_err,
                f"{d_err:.3f} vs {r_err:.3f}",
            )
        )
    return out + [
        pc.claim(
            "priors/return",
            f"{world.name}: the dynamics prior outperforms the random prior in policy learning: a return "
            "at least the random prior's",
            d["return_mean"] >= r["return_mean"],
            f"{d['return_mean']:.1f} vs {r['return_mean']:.1f}",
        )
    ]


def _figures(out: Path, world, recs: list[dict], oracle: dict | None, ref: dict | None) -> None:
    label = {r["label"]: r for r in recs}
    pc.save_bars(
        out / f"errors_{world.name}.png",
        [
            ("belief error (noise RMS, cells)", {k: r.get("belief_error") or [] for k, r in label.items()}),
            ("belief error (stay RMS)", {k: r.get("belief_stay_error") or [] for k, r in label.items()}),
            ("reward error (z-scored RMS)", {k: r["reward_error"] for k, r in label.items()}),
            ("final return (true reward)", {k: r["final"] for k, r in label.items()}),
        ],
        title=f"{world.name}: belief prior centred on f_ψ (dynamics) or at random (Figs. 22–24)",
    )
    runs = {k: r["curve"] for k, r in label.items()}
    if oracle is not None:
        runs[oracle["label"]] = oracle["curve"]
    save_learning_curves(
        out / f"curves_{world.name}.png",
        runs,
        title=f"{world.name}: return under the true reward by belief prior (Fig. 24)",
        reference=ref["plan_return"] if ref else None,
    )
    if not wm.has_map(world):  # belief maps need a map
        return
    person = np.asarray(table_noise_map(world.belief()))
    fields = [
        ("the person's belief (table)", person),
        (f"agent's f_ψ ({recs[0]['tags']['prior']} prior's run)", pc.map_array(recs[0]["dynamics_map"])),
    ]
    fields += [(f"learned belief, {r['tags']['prior']} prior", pc.map_array(r["belief_map"])) for r in recs]
    save_fields(out / f"beliefs_{world.name}.png", world.params, fields, label="noise σ (cells)")
    stays = [
        (f"learned belief, {r['tags']['prior']} prior", r["belief_stay_map"]) for r in recs if r.get("belief_stay_map")
    ]
    if stays:
        fields = [("the person's belief (table)", np.asarray(table_stay_map(world.belief())))]
        fields += [(name, pc.map_array(m)) for name, m in stays]
        save_fields(out / f"stays_{world.name}.png", world.params, fields, label="P(not moving)")
