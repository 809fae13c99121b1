"""``mindgap reproduce NAME``: a named experiment of the dissertation, run, resumed or assembled in a run folder.

Table 1 is run here; the coffee study (:mod:`~.coffee`), the driving study
(:mod:`~.reproduce_driving`) and the terrain experiments (:mod:`~.reproduce_terrain`) have their own
modules, and ``--backend`` hands every job to workers or Ray (:mod:`~.sweep`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..experiments import registry
from ..experiments.registry import NAMES as EXPERIMENTS
from .reproduce_terrain import NAMES as TERRAIN_EXPERIMENTS


def add_parser(sub) -> None:
    """The ``reproduce`` subcommand and its flags."""
    r = sub.add_parser("reproduce", help="run a named experiment of the dissertation")
    r.add_argument("name", help=f"experiment: {', '.join(EXPERIMENTS)}")
    r.add_argument("--fast", action="store_true", help="the quick preset (seconds to minutes)")
    r.add_argument("--seeds", type=int, help="seeds per setting (overrides the preset)")
    r.add_argument("--worlds", help="terrain experiments: a comma-separated subset of the worlds (names or files)")
    r.add_argument(
        "--env",
        action="append",
        metavar="SPEC",
        help="terrain experiments: run on this world instead (repeatable): a named world, a world file, "
        "or path.py:factory[,key=value…] with a belief and an exact log_prob",
    )
    r.add_argument(
        "--method",
        action="append",
        metavar="NAME",
        help="nav, gym: also run this registered preference learner beside PEBBLE (repeatable; "
        "MINDGAP_METHODS=file.py registers one)",
    )
    r.add_argument(
        "--levels",
        action="store_true",
        help="gym: also train SAC on each domain's belief env at the published SAC levels' budgets (days on a CPU)",
    )
    r.add_argument("--participants", type=int, help="coffee: valid participants per robot type (overrides the preset)")
    r.add_argument("--sleet", type=float, help="driving: the road's sleet level, 0 (dry) to 1 (full sleet)")
    r.add_argument("--traffic", type=int, help="driving: other cars on the road (0 to 4 on its three lanes)")
    r.add_argument(
        "--sanity",
        choices=("expectation", "preference"),
        help="driving: recruits answer the sanity item by which clip they prefer (default) or find more expected",
    )
    r.add_argument("--importance", metavar="A,B,C,D", help="driving: the participants' mean importance answers (1-5)")
    r.add_argument(
        "--answers-by",
        choices=("rollout", "rollout-behaviour", "expectation", "decisions"),
        help="driving: participants judge a clip by its decisions played out in the world they believe in "
        "(rollout-behaviour, default; rollout also charges a crash they did not expect), by log T_H + log pi_H "
        "at its states (expectation) or by log pi_H there alone (decisions)",
    )
    r.add_argument("--out", type=Path, help="run folder (default runs/NAME or runs/NAME-fast); reruns resume")
    r.add_argument("--fresh", action="store_true", help="discard finished jobs in the run folder")
    r.add_argument("--quiet", action="store_true", help="no progress bars")
    r.add_argument("--assemble", action="store_true", help="write outputs from the finished jobs only; run nothing")
    r.add_argument("--shard", help="I/N: run only slice I of N (processes sharing --out); rerun without it to assemble")
    r.add_argument(
        "--job", metavar="KEY", help="run only this job (a record's `command` names it) and print its record"
    )
    r.add_argument(
        "--seed",
        type=int,
        action="append",
        metavar="I",
        help="nav, priors, sampling, gym: with --job, train only seed I (0-based; repeatable) of a learner job, "
        "resumable; the job's record is assembled once every seed has run",
    )

    r.add_argument(
        "--reuse",
        type=Path,
        metavar="DIR",
        help="gym: with --job KEY of a job the person never enters (SAC), take its record from the run folder DIR, "
        "where the same robot ran with this configuration, instead of training it again",
    )

    from . import sweep

    sweep.add_backend_flags(r)


def run(args) -> int:
    """Run ``mindgap reproduce`` (the parsed ``args``)."""
    if args.name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {args.name!r}: choose from {', '.join(EXPERIMENTS)}")
    from ..experiments import table1

    if args.assemble and (args.fresh or args.shard):
        raise ValueError("--assemble only reads a run folder; it does not combine with --fresh or --shard")
    if args.job and (args.assemble or args.shard):
        raise ValueError("--job runs one job; it does not combine with --assemble or --shard")
    if args.seed is not None:
        check_seed(args)
    if args.reuse is not None and (
        args.name != "gym" or not args.job or args.seed or args.assemble or args.fresh or args.backend
    ):
        raise ValueError("--reuse goes with gym and --job KEY alone (not --seed, --assemble, --fresh or --backend)")
    for flag in ("worlds", "env"):
        if getattr(args, flag) and args.name not in TERRAIN_EXPERIMENTS:
            raise ValueError(f"--{flag} belongs to the terrain experiments ({', '.join(TERRAIN_EXPERIMENTS)})")
    if args.method and "methods" not in registry.options(args.name):
        raise ValueError("--method adds learners to nav and gym; the other experiments have their own fixed sets")
    if getattr(args, "levels", False) and "levels" not in registry.options(args.name):
        raise ValueError("--levels adds SAC's level runs to gym")
    for flag in ("sleet", "traffic", "sanity", "importance", "answers_by"):
        if getattr(args, flag) is not None and args.name != "driving":
            raise ValueError(f"--{flag.replace('_', '-')} belongs to the driving study")
    if args.backend:
        from . import sweep

        return sweep.reproduce(args)
    for flag in ("workers", "address", "retries", "cpus_per_job", "gpus_per_job"):
        if getattr(args, flag) is not None:
            raise ValueError(f"--{flag.replace('_', '-')} goes with --backend local|ray")
    if args.name == "driving":
        from . import reproduce_driving

        return reproduce_driving.reproduce(args)
    if args.name == "coffee":
        from . import coffee

        return coffee.reproduce(args, shard(args.shard))
    if args.name in TERRAIN_EXPERIMENTS:
        from . import reproduce_terrain

        return reproduce_terrain.reproduce(args)
    if args.participants is not None:
        raise ValueError("--participants belongs to the coffee study")
    cfg = table1.preset("fast" if args.fast else "full")
    if args.seeds is not None:
        if args.seeds < 1:
            raise ValueError("--seeds must be at least 1")
        cfg = replace(cfg, seeds=args.seeds, demo_count_seeds=min(cfg.demo_count_seeds, args.seeds))
    out = args.out or Path("runs") / (args.name + ("-fast" if args.fast else ""))
    shard_ = shard(args.shard)
    summary = table1.run(
        cfg, out, fresh=args.fresh, progress=not args.quiet, shard=shard_, assemble_only=args.assemble, only=args.job
    )
    return finish(summary, out, args, "curves and figures")


def finish(summary: dict | None, out: Path, args, outputs: str, unit: str = "jobs") -> int:
    """What a sharded experiment (Table 1, the coffee study) prints at the end: that a shard is done,
    else what every experiment prints (:func:`~mindgap.experiments._runfolder.print_run`)."""
    from ..experiments._runfolder import print_run

    if summary is None:
        print(f"shard {args.shard} done; rerun without --shard to assemble {out}/")
        return 0
    return print_run(summary, out, args.job, outputs, unit)


def check_seed(args) -> None:
    """Refuse ``--seed`` where it cannot slice: without ``--job``, with ``--backend``, or in an
    experiment whose jobs run whole (the range and the job's kind are checked with the job)."""
    from ..experiments._seed_slices import EXPERIMENTS as SLICED

    if args.name not in SLICED:
        raise ValueError(f"--seed: {args.name} runs its jobs whole; seeds are sliced in {', '.join(SLICED)}")
    if not args.job:
        raise ValueError("--seed trains seeds of one job: name it with --job KEY")
    if getattr(args, "backend", None):
        raise ValueError("--seed trains in this process; it does not combine with --backend")


def shard(spec: str | None) -> tuple[int, int] | None:
    if not spec:
        return None
    try:
        i, n = (int(x) for x in spec.split("/"))
    except ValueError:
        raise ValueError(f"--shard must look like 0/2, got {spec!r}") from None
    if not 0 <= i < n:
        raise ValueError(f"--shard {spec}: need 0 <= I < N")
    return i, n
