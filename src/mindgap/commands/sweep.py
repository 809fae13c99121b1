"""``mindgap sweep SPEC`` and ``mindgap reproduce NAME --backend local|ray``: jobs on workers or a Ray cluster.

mindgap sweep sweeps/demo.toml [--backend local|ray] [--workers N] [--address ADDR] [--out DIR] [--fresh] [--check]
mindgap reproduce table1 --fast --backend local --workers 2

The sweep file is checked whole before anything runs (:mod:`mindgap.sweeps.spec`);
its jobs run on the backend (:mod:`mindgap.sweeps`), each part's outputs are
assembled from the records, and the store (``results.csv``, ``sweep.json``, the run folders)
is what ``mindgap report`` reads. Exit status 1 when a job failed (the others' results are kept).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_backend_flags(p) -> None:
    """``--backend``, ``--workers``, ``--address``, ``--retries``, ``--cpus-per-job``, ``--gpus-per-job``."""
    p.add_argument(
        "--backend",
        choices=("local", "ray"),
        help="run the jobs on worker processes of this machine (local) or as Ray tasks (ray), then assemble",
    )
    p.add_argument("--workers", type=int, help="local: worker processes; ray: CPUs of a local Ray (default: all)")
    p.add_argument("--address", help="ray: the address of a running Ray cluster (default: start one for the run)")
    p.add_argument("--retries", type=int, help="times a job whose worker died is retried (default 2)")
    p.add_argument("--cpus-per-job", type=float, help="ray: CPUs each job asks for (default 1)")
    p.add_argument("--gpus-per-job", type=float, help="ray: GPUs each job asks for (default 0)")


def add_parser(sub) -> None:
    p = sub.add_parser("sweep", help="run a sweep file's experiments and grids on local workers or a Ray cluster")
    p.add_argument("spec", type=Path, help="the sweep file (TOML; see docs/sweeps.md)")
    add_backend_flags(p)
    p.add_argument("--out", type=Path, help="the store (default: the file's [sweep] out, else runs/sweeps/NAME)")
    p.add_argument("--fresh", action="store_true", help="discard the parts' finished jobs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--check", action="store_true", help="check the file and list its parts and jobs; run nothing")


def _backend_kw(args, spec=None) -> dict:
    pick = lambda flag, default: getattr(args, flag, None) if getattr(args, flag, None) is not None else default  # noqa: E731
    backend = pick("backend", spec.backend if spec else "local")
    kw = {
        "workers": pick("workers", spec.workers if spec else None),
        "retries": pick("retries", spec.retries if spec else 2),
    }
    address = pick("address", spec.address if spec else None)
    if address and backend != "ray":
        raise ValueError("--address names a Ray cluster: use it with --backend ray")
    if backend == "ray":
        kw["address"] = address
    if kw["retries"] < 0:
        raise ValueError("--retries must be at least 0")
    return {
        "backend": backend,
        "cpus": pick("cpus_per_job", spec.cpus if spec else 1.0),
        "gpus": pick("gpus_per_job", spec.gpus if spec else 0.0),
        **kw,
    }


def run(args: argparse.Namespace) -> int:
    from ..experiments import registry
    from ..sweeps import parts as sweep
    from ..sweeps import spec as sweep_spec

    spec = sweep_spec.load(args.spec)
    root = args.out or spec.out
    folders = {p.label: root / p.label for p in spec.parts}
    kw = _backend_kw(args, spec)
    if args.check:
        total = 0
        for part in spec.parts:
            n = len(sweep.part_jobs(part, folders[part.label]))
            total += n
            what = part.name if part.name == "grid" else f"{part.name} ({registry.preset_of(part.name, part.config)})"
            print(f"{part.label:16s} {what:20s} {n:4d} jobs  -> {folders[part.label]}")
        print(f"{args.spec}: {len(spec.parts)} parts, {total} jobs; backend {kw['backend']}")
        return 0
    command = f"mindgap sweep {args.spec}" + (f" --out {args.out}" if args.out else "")
    result = sweep.run_parts(
        list(spec.parts), folders, fresh=args.fresh, progress=not args.quiet, command=command, **kw
    )
    csv_path = sweep.write_store(root, list(spec.parts), folders, result, str(args.spec))
    for label, summary in result.summaries.items():
        missing = summary.get("missing_jobs") or 0
        print(f"{label}: assembled in {folders[label]}" + (f" ({missing} jobs missing)" if missing else ""))
    for label, why in result.errors.items():
        print(f"{label}: not assembled: {why}")
    print(result.outcome.report())
    print(f"results in {csv_path} and the run folders beside it (mindgap report {root})")
    return 1 if result.outcome.failed else 0


def reproduce(args: argparse.Namespace) -> int:
    """``mindgap reproduce NAME --backend …``: every job of the experiment on the backend, then its outputs."""
    from ..experiments import registry
    from ..sweeps import parts as sweep

    for flag in ("shard", "job", "assemble"):
        if getattr(args, flag, None):
            raise ValueError(f"--backend runs every job and assembles; it does not combine with --{flag}")
    worlds = tuple(w.strip() for w in (args.worlds or "").split(",") if w.strip()) + tuple(
        e.strip() for e in args.env or ()
    )
    cfg = registry.configure(
        args.name,
        "fast" if args.fast else "full",
        seeds=args.seeds,
        worlds=worlds or None,
        participants=args.participants,
        methods=tuple(getattr(args, "method", None) or ()) or None,
    )
    if worlds:  # refused here in one line, not in every worker
        from ..experiments.world_measures import experiment_world

        for w in worlds:
            experiment_world(w, args.name)
    out = args.out or Path("runs") / (args.name + ("-fast" if args.fast else ""))
    part = sweep.Part(args.name, out.name, cfg)
    kw = _backend_kw(args)
    result = sweep.run_parts([part], {part.label: out}, fresh=args.fresh, progress=not args.quiet, desc=args.name, **kw)
    summary = result.summaries.get(part.label)
    if summary is not None:
        print(summary["table_md"])
        for c in summary.get("claims", []):
            print(f"[{'ok' if c['held'] else 'not met'}] {c['text']}: {c['measured']}")
        if summary.get("missing_jobs"):
            print(f"{summary['missing_jobs']} jobs not finished; rerun the same command to run them")
    else:
        print(f"{out}: nothing assembled ({result.errors.get(part.label, 'no finished job')})")
    print(result.outcome.report())
    print(f"results, curves and figures in {out}/")
    return 1 if result.outcome.failed else 0
