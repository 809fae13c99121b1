"""The PrefBias experiments on the command line: ``mindgap reproduce nav|priors|sampling``.

mindgap reproduce nav [--fast] [--seeds N] [--out DIR] [--fresh] [--quiet] [--assemble]

``--fast`` is the quick preset (1 seed, 1500 steps, 30 queries: a dry run and the tests'
preset, not results); without it the full one (5 seeds, 30 000 steps, 80 queries a round).
The run folder defaults to ``runs/NAME`` (``runs/NAME-fast``); rerunning resumes: finished
jobs are read back, an interrupted one continues from its checkpoint.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

NAMES = ("nav", "priors", "sampling")


def reproduce(args) -> int:
    """Run one of :data:`NAMES` from the parsed ``mindgap reproduce`` arguments; print its table."""
    import importlib

    if args.name not in NAMES:
        raise ValueError(f"unknown PrefBias experiment {args.name!r}: choose from {', '.join(NAMES)}")
    if getattr(args, "participants", None) is not None:
        raise ValueError("--participants belongs to the coffee study")
    if getattr(args, "shard", None):
        raise ValueError(f"--shard is not supported by {args.name}: its seeds already run together in one program")
    module = importlib.import_module(f".prefbias_{args.name}", __package__)
    cfg = module.preset("fast" if args.fast else "full")
    if args.seeds is not None:
        if args.seeds < 1:
            raise ValueError("--seeds must be at least 1")
        cfg = replace(cfg, seeds=args.seeds)
    out = args.out or Path("runs") / (args.name + ("-fast" if args.fast else ""))
    summary = module.run(
        cfg, out, fresh=args.fresh, progress=not args.quiet, assemble_only=getattr(args, "assemble", False)
    )
    print(summary["table_md"])
    for c in summary.get("claims", []):
        print(f"[{'ok' if c['held'] else 'not met'}] {c['text']}: {c['measured']}")
    if summary.get("missing_jobs"):
        print(f"{summary['missing_jobs']} jobs not run yet; rerun without --assemble to finish them")
    print(f"results, curves and figures in {out}/")
    return 0
