"""Run folders: atomic writes, per-job checkpoints and resume after a kill.

A folder keeps each finished job's record in ``jobs/`` and each seed slice's partial record in
``seeds/`` (:mod:`~._seed_slices`); checkpoints live under ``train/``.
"""

from __future__ import annotations

import csv
import io
import json
import time
from dataclasses import MISSING, asdict, fields, is_dataclass
from pathlib import Path

import numpy as np

from .._io import atomic_write
from .claim_sources import PROJECT, sourced


def write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    """Write rows (dicts) as CSV with the given leading columns (extra keys follow)."""
    extra = [k for r in rows for k in r if k not in columns]
    cols = columns + list(dict.fromkeys(extra))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _fmt(r.get(k, "")) for k in cols})
    atomic_write(path, buf.getvalue())


def _fmt(v):
    return f"{v:.6g}" if isinstance(v, float) else v


def to_jsonable(obj):
    if is_dataclass(obj):
        return {k: to_jsonable(v) for k, v in asdict(obj).items()}
    if isinstance(obj, dict):
        return {k: to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    return obj


def nan_to_none(a, digits: int | None = 5) -> list:
    """A map [H, W] as JSON rows: floats rounded to ``digits`` (None: kept whole), None where it is NaN."""
    return [
        [None if not np.isfinite(x) else float(x) if digits is None else round(float(x), digits) for x in row]
        for row in np.asarray(a)
    ]


def same_config(stored, config, ignore=()) -> bool:
    """Whether ``stored`` (a run folder's ``config.json``, parsed) describes ``config`` (a dataclass).

    Equal as JSON, except that a field added to a configuration after the folder was written
    (absent from ``stored``) is accepted when ``config`` holds that field's default, so run
    folders stay resumable across releases that add options. ``ignore`` names top-level
    fields left out of the comparison.
    """
    return _same(stored, config, set(ignore))


def _same(stored, obj, ignore=frozenset()) -> bool:
    if is_dataclass(obj) and not isinstance(obj, type):
        if not isinstance(stored, dict):
            return False
        names = {f.name for f in fields(obj)}
        if set(stored) - names - ignore:
            return False
        for f in fields(obj):
            if f.name in ignore:
                continue
            value = getattr(obj, f.name)
            if f.name not in stored:
                if not _is_default(f, value):
                    return False
            elif not _same(stored[f.name], value):
                return False
        return True
    if isinstance(obj, dict):
        return isinstance(stored, dict) and set(stored) == set(obj) and all(_same(stored[k], obj[k]) for k in obj)
    if isinstance(obj, (list, tuple)):
        return isinstance(stored, list) and len(stored) == len(obj) and all(map(_same, stored, obj))
    return json.loads(json.dumps(obj)) == stored


def _is_default(f, value) -> bool:
    if f.default is not MISSING:
        return value == f.default
    if f.default_factory is not MISSING:
        return value == f.default_factory()
    return False


class RunFolder:
    """A results folder that remembers finished jobs.

    Each finished job is one JSON file under ``jobs/``; rerunning the same experiment
    with the same folder skips them. A folder made with another configuration is
    refused rather than mixed.
    """

    def __init__(self, root: Path, config, *, fresh: bool = False):
        self.root = Path(root)
        self.jobs = self.root / "jobs"
        cfg = json.dumps(to_jsonable(config), indent=2, sort_keys=True)
        cfg_path = self.root / "config.json"
        if fresh and self.root.exists():
            for p in [*self.jobs.glob("*.json"), *(self.root / SEEDS).glob("*/*.json")]:
                p.unlink()
        elif cfg_path.exists() and cfg_path.read_text() != cfg:
            if not same_config(json.loads(cfg_path.read_text()), config):
                raise RuntimeError(
                    f"{self.root} holds a run with another configuration; pass --fresh to overwrite it "
                    "or --out to use another folder"
                )
            cfg = cfg_path.read_text()  # the same run, written before options were added: kept as it is
        self.jobs.mkdir(parents=True, exist_ok=True)
        atomic_write(cfg_path, cfg)

    def _path(self, key: str) -> Path:
        return record_path(self.root, key)

    def done(self, key: str) -> dict | None:
        p = self._path(key)
        return json.loads(p.read_text()) if p.exists() else None

    def save(self, key: str, record: dict) -> None:
        atomic_write(self._path(key), json.dumps(record))

    def write_progress(self, experiment: str, expected: list[str], command: str) -> dict:
        """Write ``progress.json``: which of the ``expected`` job keys have records, and who wrote them.

        ``mindgap report`` reads it to show a partial run's missing jobs; ``command`` is the
        command line that finishes (or repeats) the run.
        """
        from .. import __version__

        missing = [k for k in expected if not self._path(k).exists()]
        record = {
            "experiment": experiment,
            "jobs": len(expected),
            "done": len(expected) - len(missing),
            "missing": missing,
            "command": command,
            "version": __version__,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        apart = {k: seeds for k in missing if (seeds := partial_seeds(self.root, k))}
        if apart:  # the missing jobs' seeds already trained apart (--seed)
            record["seeds_done"] = apart
        atomic_write(self.root / "progress.json", json.dumps(record, indent=2))
        return record


def print_run(
    summary: dict, out: Path, only: str | None, outputs: str = "curves and figures", unit: str = "jobs"
) -> int:
    """What ``mindgap reproduce NAME`` prints at the end: the one job's numbers (``--job``), or the
    table, each claim as held or not (the project's own checks marked), the ``unit`` still missing and
    where the outputs are. Returns 0."""
    if only:
        print(job_summary(summary["job"], out, only, summary.get("record")))
        for line in summary.get("notes", ()):
            print(line)
        return 0
    print(summary["table_md"])
    for c in summary.get("claims", []):
        own = sourced(summary.get("experiment", ""), c)["kind"] == PROJECT  # not the dissertation's claim
        print(f"[{'ok' if c['held'] else 'not met'}] {'(project check) ' * own}{c['text']}: {c['measured']}")
    if summary.get("missing_jobs"):
        print(f"{summary['missing_jobs']} {unit} not run yet; rerun without --assemble to finish them")
    print(f"results, {outputs} in {out}/")
    return 0


def record_path(root: Path, key: str) -> Path:
    """Where the run folder ``root`` keeps job ``key``'s record (``jobs/KEY.json``, ``/`` as ``__``)."""
    return Path(root) / "jobs" / (key.replace("/", "__") + ".json")


SEEDS = "seeds"
"""The folder of a run folder that keeps seed slices' partial records."""


def partial_path(root: Path, key: str, seed: int) -> Path:
    """Where the run folder ``root`` keeps seed ``seed``'s partial record of job ``key``
    (``seeds/KEY/seed-I.json``, ``/`` as ``__``)."""
    return Path(root) / SEEDS / key.replace("/", "__") / f"seed-{seed}.json"


def partial_seeds(root: Path, key: str) -> list[int]:
    """The seeds of job ``key`` whose partial records the run folder ``root`` holds, in order."""
    folder = partial_path(root, key, 0).parent
    return sorted(int(p.stem.removeprefix("seed-")) for p in folder.glob("seed-*.json"))


def job_summary(record: dict, root: Path, key: str, path: Path | None = None) -> str:
    """What ``mindgap reproduce … --job KEY`` prints: the record's numbers (a Table 1 fit's
    metrics included) and where the record is (``path``, default the job's record)."""
    flat = {**record, **record.get("row", {})}
    shown = {k: v for k, v in flat.items() if isinstance(v, (int, float, str)) and k != "command"}
    return json.dumps(shown, indent=1) + f"\nrecord in {path or record_path(root, key)}"
