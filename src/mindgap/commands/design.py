"""``mindgap design check``: is a world (and its simulated person) a valid test of PrefBias?

mindgap design check NAME|FILE [NAME|FILE …] [--belief B] [--budget N] [--segment L] [--beta B] [--out DIR]

Prints, for each world, the exact finite-horizon plans under r_H, under what an unaware
learner learns and under an unbiased person, the per-step bias by terrain, each belief
parameter's standard error at the budget, the identifiability conditions, and the verdict
(:mod:`~mindgap.planning.design_check`). With ``--out``: ``WORLD.txt`` (the same text) and
``WORLD.json``. The exit status is 0 when every world is valid, 1 when one is not.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from .learn import beta_value


def add_parser(sub) -> None:
    d = sub.add_parser("design", help="check that a world can show PrefBias's effect before running a study")
    dsub = d.add_subparsers(dest="design_command", required=True)
    c = dsub.add_parser("check", help="plan, compare and measure identifiability (docs/identifiability.md)")
    c.add_argument("worlds", nargs="+", help="named terrain worlds or world files")
    c.add_argument("--belief", help="the person's belief (default: each world's first)")
    c.add_argument("--budget", type=int, default=800, help="answered queries (default 800)")
    c.add_argument("--segment", type=int, default=10, help="steps per segment (default 10)")
    c.add_argument(
        "--beta", type=beta_value, default=1.0, help="the person's rationality (default 1; inf: deterministic)"
    )
    c.add_argument("--resolution", type=int, default=4, help="sub-cells per cell side (default 4)")
    c.add_argument("--seed", type=int, default=0, help="random seed of the Monte Carlo parts")
    c.add_argument("--out", type=Path, help="folder for WORLD.txt and WORLD.json")


def run(args: argparse.Namespace) -> int:
    from ..envs.resolve import resolve_env
    from ..envs.terrain import TerrainWorld
    from ..planning.design_check import DesignConfig, design_check, report
    from ..teachers.preference import TeacherConfig

    if args.budget < 1 or args.segment < 1 or args.resolution < 1:
        raise ValueError("--budget, --segment and --resolution must be at least 1")
    worlds = []
    for spec in args.worlds:  # every world loaded and checked before anything is computed
        world = resolve_env(spec)
        if not isinstance(world, TerrainWorld):
            raise ValueError(f"the design check plans on a terrain world's map; {spec} is not a terrain world")
        if not world.beliefs:
            raise ValueError(f"{spec} declares no belief to check")
        if args.belief is not None:
            world.belief(args.belief)  # one line naming the beliefs it has
        worlds.append(world)
    cfg = DesignConfig(
        n=args.resolution,
        budget=args.budget,
        segment=args.segment,
        teacher=dataclasses.replace(TeacherConfig(), beta=args.beta),
        seed=args.seed,
    )
    valid = True
    for world in worlds:
        chk = design_check(world, args.belief, cfg)
        text = report(chk)
        print(text)
        valid &= chk.valid
        if args.out is not None:
            from .._io import atomic_write

            args.out.mkdir(parents=True, exist_ok=True)
            atomic_write(args.out / f"{world.name}.txt", text)
            atomic_write(args.out / f"{world.name}.json", json.dumps(chk.as_dict(), indent=2))
    return 0 if valid else 1
