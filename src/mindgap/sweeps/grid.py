"""A grid sweep: learners × worlds × hyperparameters × seeds, each cell one job of the terrain experiments' kind.

The cells are :class:`~.prefbias_common.Job` s, computed by the same code as ``mindgap reproduce
nav`` (:func:`~.prefbias_common.run_jobs`: one JSON record per cell, the engine's checkpoint
under ``train/``), so a grid's records, rows and curves read like the named experiments'. Per
world there is a ``reference`` job (a uniformly random policy and the planning check: the 0 of
the normalised score); the oracle (the 1) is the grid's ``sac`` cell when it has one.

Seeds: ``seeds = N`` trains N seeds vmapped inside each job (the learners allow it); a list
``seed_values`` makes one job per seed (the configuration's ``seed``), for when jobs should be
small or spread over machines.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..algorithms import methods as registry
from ..experiments import prefbias_common as pc
from ..experiments._runfolder import RunFolder, write_csv

METHODS = ("sac", "pebble", "drlhp", "prefbias")
"""The built-in learners a grid runs: SAC on the true reward, PEBBLE, DRLHP (:mod:`~mindgap.algorithms.pbrl`),
PrefBias; :func:`grid_methods` adds every registered method that learns from preferences."""

SHARED = ("total_steps", "chunk", "eval_every", "eval_episodes", "sac", "seed", "teacher", "queries", "per_round",
          "feedback_every", "segment")  # fmt: skip
"""The schedule a registered method takes from the grid's PEBBLE, so that all of a grid's learners share it."""


def grid_methods() -> tuple[str, ...]:
    """The learners a grid can run: :data:`METHODS` and every registered method that learns from preferences
    (:mod:`mindgap.algorithms.methods`)."""
    extra = [m.name for m in registry.METHODS.values() if m.answers == "preferences" and m.name not in METHODS]
    return METHODS + tuple(extra)


@dataclass(frozen=True)
class GridConfig:
    """A grid sweep (its run folder's ``config.json``)."""

    methods: tuple[str, ...]
    """Learners, from :func:`grid_methods`."""
    worlds: tuple[str, ...]
    """Named worlds, world files or ``path.py:factory`` specs (with a belief and an exact density)."""
    preset: str = "fast"
    """The learners' preset (``fast`` or ``full``, as the PrefBias experiments')."""
    seeds: int = 1
    """Seeds vmapped inside each job."""
    seed_values: tuple[int, ...] = ()
    """One job per seed with this ``seed`` (then ``seeds`` is 1)."""
    params: tuple[tuple[str, tuple], ...] = ()
    """The hyperparameter grid: ``(field, values)``; a dotted field reaches inside (``sac.lr``);
    a field applies to the methods that take it (:func:`takes`)."""
    reference: pc.ReferenceConfig = field(default_factory=pc.ReferenceConfig)


def base_configs(preset: str) -> dict:
    """Each method's configuration under ``preset`` (one schedule for all, as :func:`~.prefbias_common.learners`)."""
    learn = pc.learners(preset)
    out = {
        "sac": learn.sac,
        "pebble": learn.pebble,
        "drlhp": dataclasses.replace(learn.pebble, method="drlhp", explore_steps=0, reset_critic=False),
        "prefbias": learn.prefbias,
    }
    for name in grid_methods()[len(METHODS) :]:
        m = registry.get(name)
        fields = {f.name for f in dataclasses.fields(m.config)}
        out[name] = m.preset(preset, **{k: getattr(learn.pebble, k) for k in SHARED if k in fields})
    return out


SAC_FIELDS = ("total_steps", "chunk", "eval_every", "eval_episodes", "sac")
"""The settings SAC on the true reward takes from a grid (it asks no queries: the feedback settings pass it by)."""


def takes(method: str, cfg, path: str) -> bool:
    """Whether ``method`` (configured by ``cfg``) takes the grid's setting ``path``."""
    return has_field(cfg, path) and (method != "sac" or path.split(".")[0] in SAC_FIELDS)


def has_field(cfg, path: str) -> bool:
    """Whether the (nested) dataclass ``cfg`` has the dotted field ``path``."""
    for name in path.split("."):
        if not dataclasses.is_dataclass(cfg) or name not in {f.name for f in dataclasses.fields(cfg)}:
            return False
        cfg = getattr(cfg, name)
    return True


def with_field(cfg, path: str, value):
    """``cfg`` with the dotted field ``path`` set to ``value`` (lists become tuples, as the configurations hold)."""
    head, _, rest = path.partition(".")
    if rest:
        return dataclasses.replace(cfg, **{head: with_field(getattr(cfg, head), rest, value)})
    if isinstance(value, list):
        value = tuple(value)
    return dataclasses.replace(cfg, **{head: value})


def _slug(v) -> str:
    return ",".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v)


def cells(grid: GridConfig, method: str) -> list[tuple[dict, object]]:
    """``(the cell's settings, the method's configuration)`` for each hyperparameter cell of ``method``."""
    base = base_configs(grid.preset)[method]
    names = [n for n, _ in grid.params if takes(method, base, n)]
    values = dict(grid.params)
    out = []
    for combo in itertools.product(*(values[n] for n in names)):
        cfg = base
        for n, v in zip(names, combo):
            cfg = with_field(cfg, n, v)
        if hasattr(cfg, "check"):
            cfg.check()
        out.append((dict(zip(names, combo)), cfg))
    return out


def jobs(grid: GridConfig) -> list[pc.Job]:
    """Every cell's job, per world: the reference, then each method's cells (× seeds)."""
    out = []
    for world in grid.worlds:
        out.append(pc.reference_job(world, grid.reference))
        for method in grid.methods:
            for setting, cfg in cells(grid, method):
                for seed in grid.seed_values or (None,):
                    tags = {k: _slug(v) for k, v in setting.items()}
                    if seed is not None:
                        cfg_s, tags = dataclasses.replace(cfg, seed=seed), {**tags, "seed": seed}
                    else:
                        cfg_s = cfg
                    name = "-".join([method] + [f"{k}={v}" for k, v in tags.items()])
                    label = method + (f" ({', '.join(f'{k}={v}' for k, v in tags.items())})" if tags else "")
                    out.append(pc.Job(f"{world}/{name}", world, method, label, cfg_s, tags))
    return out


def run_job(grid: GridConfig, out: str, key: str) -> None:
    """Compute one cell of the grid into the run folder ``out`` (its record: ``jobs/KEY.json``)."""
    folder = RunFolder(Path(out), grid)
    job = pc.select_job(jobs(grid), key, "the grid")[-1]
    seeds = 1 if grid.seed_values else grid.seeds
    pc.run_jobs(folder, [job], seeds, fresh=False, progress=False, assemble_only=False)


def assemble(grid: GridConfig, out: Path, command: str = "") -> dict:
    """``results.csv`` (a row per learner cell: return, normalised score, routes, errors),
    ``curves.csv``, ``table.md`` and ``summary.json`` from the finished cells; ``progress.json``
    names ``command``, the line that runs (or finishes) the sweep."""
    out = Path(out)
    folder = RunFolder(out, grid)
    everything = jobs(grid)
    records = {j.key: r for j in everything if (r := folder.done(j.key)) is not None}
    folder.write_progress("grid", [j.key for j in everything], command)
    refs, oracles, learned = pc.split(records)
    if not learned and not oracles:
        raise RuntimeError(f"{out} has no finished learner jobs to assemble")
    rows, curves = [], []
    for rec in [r for r in records.values() if r["method"] != "reference"]:
        rows.append({"key": rec["key"], **pc.result_row(rec, refs.get(rec["world"]), oracles.get(rec["world"]))})
        curves += pc.curve_rows(rec)
    write_csv(out / "results.csv", rows, ["key", "method", "world"])
    write_csv(out / "curves.csv", curves, ["method", "world"])
    header = ["world", "learner", "seeds", "final return", "normalised score"]
    table = [
        [
            r["world"],
            r["label"],
            str(r["seeds"]),
            pc.fmt(r["return_mean"], r["return_std"]),
            pc.fmt(r["normalised_mean"], r["normalised_std"], 2),
        ]
        for r in rows
    ]
    table_md = f"Grid sweep ({grid.preset} preset): {', '.join(grid.methods)} on {', '.join(grid.worlds)}\n\n"
    table_md += pc.markdown(header, table)
    summary = {
        "experiment": "grid",
        "table_md": table_md,
        "rows": len(rows),
        "best": _best(rows),
        "missing_jobs": len(everything) - len(records),
    }
    pc.write_summary(out, summary)
    return summary


def _best(rows: list[dict]) -> dict:
    """Per world, the learner cell with the highest mean final return."""
    best = {}
    for r in rows:
        if r["method"] != "sac" and np.isfinite(r["return_mean"]):
            if r["world"] not in best or r["return_mean"] > best[r["world"]]["return_mean"]:
                best[r["world"]] = {"key": r["key"], "return_mean": r["return_mean"]}
    return best
