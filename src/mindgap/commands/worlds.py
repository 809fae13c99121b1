"""``mindgap worlds``: list, draw and plan the terrain worlds.

mindgap worlds list
mindgap worlds show NAME|FILE [--belief [NAME]] --out FILE.png|.svg
mindgap worlds plan NAME|FILE [NAME|FILE …] [--belief NAME] [--resolution N] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_parser(sub) -> None:
    w = sub.add_parser("worlds", help="list, draw and plan the terrain worlds (nav1, nav2, d1–d4 or a world file)")
    wsub = w.add_subparsers(dest="worlds_command", required=True)
    wsub.add_parser("list", help="the named worlds and what each tests")

    s = wsub.add_parser("show", help="draw a world (and a belief's noise field)")
    s.add_argument("world", help="a named world or a world file (.toml)")
    s.add_argument(
        "--belief",
        nargs="?",
        const="",
        help="also draw the noise scale under the truth and under this belief (default: the world's first)",
    )
    s.add_argument("--out", type=Path, required=True, help="picture to write (.png or .svg)")

    p = wsub.add_parser("plan", help="value-iterate a discretised world: optimal and expected routes")
    p.add_argument("worlds", nargs="+", help="named worlds or world files")
    p.add_argument("--belief", help="belief to plan the expected route with (default: each world's first)")
    p.add_argument("--resolution", type=int, default=4, help="sub-cells per cell side (default 4)")
    p.add_argument("--rollouts", type=int, default=200, help="rollouts per plan for the statistics (default 200)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the rollouts")
    p.add_argument("--out", type=Path, help="folder for the pictures and plan.json (default runs/worlds)")


def run(args: argparse.Namespace) -> int:
    if args.worlds_command == "list":
        return _list()
    if args.worlds_command == "show":
        return _show(args)
    return _plan(args)


def _list() -> int:
    from ..envs.terrain import NAMED_WORLDS, load_world

    for name in NAMED_WORLDS:
        w = load_world(name)
        h, wd = w.layout.shape
        first = w.description.replace("\n", " ").split(". ")[0]
        print(f"{name:5} {wd}×{h}, horizon {int(w.params.horizon)}: {first}.")
    return 0


def _show(args) -> int:
    from ..envs.terrain import load_world
    from ..plotting.terrain import save_fields, save_world

    world = load_world(args.world)
    if args.belief is None:
        save_world(args.out, world.params, title=world.name)
    else:
        from ..design.terrain_check import noise_field

        bname = args.belief or None
        bparams = world.belief(bname)
        bname = bname or next(iter(world.beliefs))
        save_fields(
            args.out,
            world.params,
            [
                ("true dynamics\n" + _table_line(world.params.dynamics), noise_field(world.params)),
                (f"belief '{bname}'\n" + _table_line(bparams.dynamics), noise_field(bparams)),
            ],
        )
    print(f"wrote {args.out}")
    return 0


def _table_line(dyn) -> str:
    """One line summarising a dynamics table for a picture's title."""
    t = dyn.as_dict()
    parts = [
        f"{name} ×{t[name]['speed']:g} σ{t[name]['noise']:g}"
        + (f" stuck {t[name]['stuck']:g}" if t[name]["stuck"] else "")
        for name in ("ice", "sand")
    ]
    if t["pit_noise"]:
        parts.append(f"pit +{t['pit_noise']:g}·e^(−d/{t['pit_scale']:g})")
    return ", ".join(parts)


def _plan(args) -> int:
    import jax

    from .._io import atomic_write
    from ..design.terrain_check import check_world
    from ..envs.terrain import load_world
    from ..plotting.terrain import save_panels, save_rollout_gif

    if args.resolution < 1 or args.rollouts < 1:
        raise ValueError("--resolution and --rollouts must be at least 1")
    out = args.out or Path("runs") / "worlds"
    report, failed = {}, []
    for spec in args.worlds:
        world = load_world(spec)
        chk = check_world(world, args.belief, n=args.resolution, count=args.rollouts, seed=args.seed)
        print(f"\n{world.name}: reference return {chk.reference_return:.1f} (planned policy under the true dynamics)")
        print(f"  optimal route:  {chk.true.describe()}")
        if chk.expected is not None:
            print(f"  expected route: {chk.expected.describe()}   (belief '{chk.belief}', as the person imagines it)")
            print(f"  expected policy run in the real world: {chk.expected_in_truth.describe()}")
            sc = chk.person_scores
            print(
                f"  the person's Σ[r + log T_H] of each route as the robot drives it: optimal {sc['optimal']:+.1f}, "
                f"expected {sc['expected']:+.1f}"
            )
        for e in chk.expectations:
            print(f"  [{'ok' if e.held else 'FAILED'}] {e.text}: {e.measured}")
        if not chk.passed:
            failed.append(world.name)
        panels = [("optimal (true dynamics)", world.params, {"optimal": chk.true_paths})]
        if chk.expected is not None:
            panels.append(
                (f"expected (belief '{chk.belief}')", world.belief(chk.belief), {"expected": chk.expected_paths})
            )
        colours = {"optimal": "#d62728", "expected": "#1f77b4"}
        for ext in ("png", "svg"):
            save_panels(out / f"{world.name}-routes.{ext}", panels, colours)
        save_rollout_gif(out / f"{world.name}-rollout.gif", world.params, chk.true_paths[0], title=world.name)
        report[world.name] = {
            "source": world.source,
            "belief": chk.belief,
            "resolution": args.resolution,
            "reference_return": chk.reference_return,
            "optimal": chk.true._asdict(),
            "expected": chk.expected._asdict() if chk.expected is not None else None,
            "expected_in_truth": chk.expected_in_truth._asdict() if chk.expected is not None else None,
            "person_scores": chk.person_scores,
            "expectations": [e._asdict() for e in chk.expectations],
        }
    atomic_write(out / "plan.json", json.dumps(report, indent=2))
    print(f"\nroutes (PNG, SVG), rollout GIFs and plan.json in {out}/  [{jax.default_backend()}]")
    if failed:
        print(f"expected behaviour not shown in: {', '.join(failed)}")
        return 1
    return 0
