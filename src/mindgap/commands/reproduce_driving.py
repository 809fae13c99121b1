"""The driving study on the command line: ``mindgap reproduce driving``.

mindgap reproduce driving [--fast] [--seeds N] [--sleet S] [--traffic N] [--sanity expectation] [--importance A,B,C,D] [--answers-by rollout-behaviour|rollout|expectation|decisions] [--out DIR] [--fresh] [--quiet] [--assemble] [--job KEY]

``--fast`` is the quick preset (1 seed, 1500 steps, 4 + 4 participants, tiny networks: a dry
run and the tests' preset, not results); without it the full one (5 seeds, 30 000 steps,
400 queries, 14 + 15 participants). ``--sleet`` sets the road (0 dry … 1 full sleet, default
1); ``--importance`` the population's mean answers to Fig. 32's four questions (1–5; default
the study's 3.42,4.57,3.28,3.78). ``--answers-by`` says how the participants judge which clip is
more expected (queries, the sanity item asked as an expectation, the testing phase's ratings):
``rollout-behaviour`` (default) plays the clip's decisions out in the world they believe in;
``rollout`` also charges a crash their rollout does not reproduce; ``expectation`` scores Σ [log T_H + log π_H] at the clip's own states and ``decisions`` log π_H
there alone (docs/experiments/driving.md). The run folder defaults to
``runs/driving`` (``runs/driving-fast``); rerunning resumes.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..experiments import driving
from ..experiments._runfolder import print_run


def reproduce(args) -> int:
    for flag in ("participants", "shard"):
        if getattr(args, flag, None):
            raise ValueError(f"--{flag} is not an option of the driving study")
    cfg = driving.preset("fast" if args.fast else "full")
    changes = {}
    if args.seeds is not None:
        changes["seeds"] = args.seeds
    if getattr(args, "sleet", None) is not None:
        changes["sleet"] = args.sleet
    if getattr(args, "traffic", None) is not None:
        changes["traffic"] = args.traffic
    if getattr(args, "sanity", None) is not None:
        changes["sanity"] = args.sanity
    if getattr(args, "importance", None):
        try:
            values = tuple(float(v) for v in args.importance.split(","))
        except ValueError:
            raise ValueError(f"--importance takes four numbers separated by commas, got {args.importance!r}") from None
        changes["importance"] = values
    if getattr(args, "answers_by", None) is not None:
        changes["answers_by"] = args.answers_by
    if changes:
        cfg = replace(cfg, **changes)  # checked in DrivingConfig.__post_init__: one line each
    out = args.out or Path("runs") / ("driving" + ("-fast" if args.fast else ""))
    only = getattr(args, "job", None)
    summary = driving.run(cfg, out, fresh=args.fresh, progress=not args.quiet, assemble_only=args.assemble, only=only)
    return print_run(summary, out, only, "ratings and figures")
