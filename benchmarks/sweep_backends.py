"""Benchmark: what the sweep backends gain on a real experiment and what each costs per job.

1. Wall time of ``mindgap reproduce table1`` in one process against ``--backend local
   --workers N`` (default 2), each in a fresh process with its own empty JAX compilation
   cache (``--cache cold``, the default: every worker compiles what it runs, as on a new
   machine) or both on one cache warmed by a first run that is not timed (``--cache warm``).
   ``--preset fast`` (default; minutes) or ``full`` (the real Table 1; 14 + 11 minutes on two
   cores). Prints both times and the ratio.
2. The backends' own overhead, on ``--jobs`` no-op jobs that only write their record (the run
   folder's contract) with the time they end: start-up = until the first job ended (the
   workers' start; for Ray, starting a local Ray as a run does and its workers), per job = the
   time between the first and the last job's end divided by ``--jobs - 1`` (with ``--workers``
   at work). Ray's part is skipped when Ray is not installed (``pip install 'mindgap[ray]'``).

    python benchmarks/sweep_backends.py [--preset fast|full] [--seeds N] [--workers 2] [--cache cold|warm] [--jobs 41]
                                        [--skip-table1 | --skip-overhead]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mindgap import sweeps as backends
from mindgap.experiments._runfolder import RunFolder, record_path


def noop(root: str, key: str) -> None:
    """A job that does nothing but keep the contract: write its record (with the time it ends)."""
    RunFolder(Path(root), {"noop": 1}).save(key, {"key": key, "end": time.time()})


def reproduce(preset: str, out: Path, cache: Path, extra: list[str]) -> float:
    """Seconds of ``mindgap reproduce table1`` in a fresh process."""
    cmd = [sys.executable, "-m", "mindgap.cli", "reproduce", "table1", "--quiet", "--out", str(out), *extra]
    if preset == "fast":
        cmd.insert(cmd.index("--quiet"), "--fast")
    env = {**os.environ, "MINDGAP_JAX_CACHE": str(cache)}
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def overhead(backend: str, workers: int, n: int, root: Path) -> tuple[float, float]:
    """``n`` no-op jobs on ``backend``: (seconds until the first job ended: the start-up, workers
    or a local Ray included; seconds between job ends after it, so per job with ``workers`` at work)."""
    root.mkdir()
    jobs = [
        backends.Job(f"j{i}", noop, {"root": str(root), "key": f"j{i}"}, record_path(root, f"j{i}"), root / f"j{i}.log")
        for i in range(n)
    ]
    t0 = time.time()
    out = backends.run(jobs, backend, workers=workers, progress=False, cache_dir="")
    assert not out.failed and len(out.ran) == n, out.report()
    ends = sorted(json.loads(j.record.read_text())["end"] for j in jobs)
    return ends[0] - t0, (ends[-1] - ends[0]) / (n - 1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", choices=("fast", "full"), default="fast")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--cache", choices=("cold", "warm"), default="cold")
    p.add_argument("--seeds", type=int, help="table1's seeds (default: the preset's)")
    p.add_argument("--jobs", type=int, default=41, help="no-op jobs of the overhead measurement")
    p.add_argument("--skip-table1", action="store_true", help="only the per-job overhead")
    p.add_argument("--skip-overhead", action="store_true", help="only table1")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="mindgap-bench-") as d:
        tmp = Path(d)
        if not args.skip_table1:
            caches = {k: tmp / f"cache-{k}" for k in ("one", "local")}
            if args.cache == "warm":
                caches = dict.fromkeys(caches, tmp / "cache")
                print("warming the cache (not timed) ...", flush=True)
                reproduce(args.preset, tmp / "warm", caches["one"], ["--seeds", str(args.seeds)] if args.seeds else [])
            seeds = ["--seeds", str(args.seeds)] if args.seeds else []
            one = reproduce(args.preset, tmp / "one", caches["one"], seeds)
            print(f"table1 --{args.preset}, one process:             {one:7.1f} s", flush=True)
            backend = ["--backend", "local", "--workers", str(args.workers), *seeds]
            local = reproduce(args.preset, tmp / "local", caches["local"], backend)
            print(f"table1 --{args.preset}, local backend, {args.workers} workers: {local:7.1f} s", flush=True)
            same = (tmp / "one" / "table.md").read_text() == (tmp / "local" / "table.md").read_text()
            print(f"ratio one process / local backend: {one / local:.2f}  (same table: {same})", flush=True)
        for backend in [] if args.skip_overhead else ["local"] + (["ray"] if importlib.util.find_spec("ray") else []):
            start, per = overhead(backend, args.workers, args.jobs, tmp / f"noop-{backend}")
            print(
                f"{backend:5s} backend, {args.jobs} no-op jobs on {args.workers} workers: start-up {start:5.2f} s "
                f"(until the first job ended), then {per * 1000:6.1f} ms a job",
                flush=True,
            )


if __name__ == "__main__":
    main()
