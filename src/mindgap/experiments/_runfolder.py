"""Run folders: atomic writes, per-job checkpoints and resume after a kill."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict, is_dataclass
from pathlib import Path

from .._io import atomic_write


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
            for p in self.jobs.glob("*.json"):
                p.unlink()
        elif cfg_path.exists() and cfg_path.read_text() != cfg:
            raise RuntimeError(
                f"{self.root} holds a run with another configuration; pass --fresh to overwrite it "
                "or --out to use another folder"
            )
        self.jobs.mkdir(parents=True, exist_ok=True)
        atomic_write(cfg_path, cfg)

    def _path(self, key: str) -> Path:
        return self.jobs / (key.replace("/", "__") + ".json")

    def done(self, key: str) -> dict | None:
        p = self._path(key)
        return json.loads(p.read_text()) if p.exists() else None

    def save(self, key: str, record: dict) -> None:
        atomic_write(self._path(key), json.dumps(record))
