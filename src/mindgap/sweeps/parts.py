"""Sweeps: named experiments and grids run as jobs on a backend, into one results store.

A sweep is a list of *parts*, each one run folder (:class:`~._runfolder.RunFolder`): a named
experiment of ``mindgap reproduce`` with its options, or a grid of learners × worlds ×
hyperparameters × seeds (:mod:`~.grid`). Every job of every part goes to one backend
(:mod:`~.local`, :mod:`~.ray_cluster`) at once, so the parts share the workers; a job whose record exists is
skipped, which is what makes a killed sweep resumable. When the jobs are done each part's
outputs are assembled from its records by the experiment's own code (``run(...,
assemble_only=True)``: no second format), and the sweep's store gets ``results.csv`` (every
part's rows, with ``part`` and ``experiment`` columns) and ``sweep.json`` (what ran, what
failed, where the logs are). ``mindgap report STORE`` reads the part folders.
"""

from __future__ import annotations

import csv
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from .._io import atomic_write
from ..experiments import registry
from ..experiments._runfolder import RunFolder, record_path, write_csv
from . import grid as sweep_grid
from . import run as run_jobs
from .jobs import Job, Outcome


@dataclass(frozen=True)
class Part:
    """One run folder of a sweep.

    Attributes:
        name: a named experiment (:data:`~.registry.NAMES`) or ``grid``.
        label: the folder's name under the sweep's store (unique in a sweep).
        config: the experiment's configuration, or a :class:`~.grid.GridConfig`.
    """

    name: str
    label: str
    config: object


def run_experiment_job(name: str, config, out: str, key: str) -> None:
    """One job of a named experiment: ``mindgap reproduce NAME --job KEY`` without the printing."""
    registry.module(name).run(config, Path(out), fresh=False, progress=False, assemble_only=False, only=key)


def part_jobs(part: Part, out: Path, *, cpus: float = 1.0, gpus: float = 0.0) -> list[Job]:
    """The part's jobs for a backend; a job's key is ``LABEL/KEY`` (``KEY`` its record's name)."""
    if part.name == "grid":
        keys = [(job.key, ()) for job in sweep_grid.jobs(part.config)]
        call, fixed = sweep_grid.run_job, {"grid": part.config, "out": str(out)}
    else:
        keys = registry.jobs(part.name, part.config)
        call, fixed = run_experiment_job, {"name": part.name, "config": part.config, "out": str(out)}
    return [
        Job(
            key=f"{part.label}/{key}",
            call=call,
            kwargs={**fixed, "key": key},
            record=record_path(out, key),
            log=out / "logs" / (key.replace("/", "__") + ".log"),
            needs=tuple(f"{part.label}/{n}" for n in needs),
            cpus=cpus,
            gpus=gpus,
        )
        for key, needs in keys
    ]


def assemble(part: Part, out: Path, *, progress: bool = False, command: str = "") -> dict:
    """Write the part's outputs from its finished records; its summary (``missing_jobs`` included).
    ``command`` is the line that runs the sweep (a grid's ``progress.json`` keeps it)."""
    if part.name == "grid":
        return sweep_grid.assemble(part.config, out, command)
    return registry.module(part.name).run(
        part.config, out, fresh=False, progress=progress, assemble_only=True, only=None
    )


@dataclass
class SweepResult:
    outcome: Outcome
    summaries: dict[str, dict]
    """Each assembled part's summary, by label."""
    errors: dict[str, str]
    """Parts that could not be assembled (no finished job), by label."""


def run_parts(
    parts: list[Part],
    folders: dict[str, Path],
    *,
    backend: str = "local",
    fresh: bool = False,
    progress: bool = True,
    cpus: float = 1.0,
    gpus: float = 0.0,
    desc: str = "sweep",
    command: str = "",
    **backend_kw,
) -> SweepResult:
    """Run every part's unfinished jobs on ``backend``, then assemble each part in ``folders[label]``.

    A part's folder made with another configuration is refused before anything runs
    (``fresh`` empties the parts' finished jobs instead). ``command`` is the line that runs
    the sweep (kept in a grid's ``progress.json``). ``backend_kw`` go to
    :func:`mindgap.sweeps.run` (``workers``, ``address``, ``retries``).
    """
    jobs = []
    for part in parts:
        RunFolder(folders[part.label], part.config, fresh=fresh)
        if fresh:  # the workers resume what they find: checkpoints of the discarded jobs go too
            for stale in ("train", "logs"):
                shutil.rmtree(folders[part.label] / stale, ignore_errors=True)
        jobs += part_jobs(part, folders[part.label], cpus=cpus, gpus=gpus)
    outcome = run_jobs(jobs, backend, progress=progress, desc=desc, **backend_kw)
    summaries, errors = {}, {}
    for part in parts:
        try:
            summaries[part.label] = assemble(part, folders[part.label], command=command)
        except RuntimeError as e:  # no finished job to assemble
            errors[part.label] = str(e)
    return SweepResult(outcome, summaries, errors)


def write_store(root: Path, parts: list[Part], folders: dict[str, Path], result: SweepResult, spec: str) -> Path:
    """The sweep's store in ``root``: ``results.csv`` (every part's rows) and ``sweep.json``."""
    rows = []
    for part in parts:
        path = folders[part.label] / "results.csv"
        if part.label in result.summaries and path.exists():
            with open(path, newline="") as f:
                rows += [{"part": part.label, "experiment": part.name, **r} for r in csv.DictReader(f)]
    write_csv(root / "results.csv", rows, ["part", "experiment"])
    o = result.outcome
    record = {
        "spec": spec,
        "parts": {p.label: {"experiment": p.name, "folder": str(folders[p.label])} for p in parts},
        "jobs": {"ran": len(o.ran), "already_done": len(o.skipped), "failed": len(o.failed)},
        "failed": {k: {"why": why, "log": str(o.logs.get(k, ""))} for k, why in o.failed.items()},
        "unassembled": result.errors,
        "seconds": o.seconds,
        "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    atomic_write(root / "sweep.json", json.dumps(record, indent=2))
    return root / "results.csv"
