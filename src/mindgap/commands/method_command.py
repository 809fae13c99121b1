"""``mindgap NAME``: the command of a registered method that has none of its own, built from its record.

mindgap NAME --env nav1 --teacher biased --seeds 5 --out runs/NAME-nav1 [--fast] [--queries 400] [--sac.lr 1e-3] …

Every field of the method's config is a flag (:mod:`~.config_flags`), its default the preset's
(``--fast``: the ``fast`` preset). The run goes through :func:`mindgap.algorithms.methods.train`
and writes what ``mindgap pebble`` writes (curve.csv, curve.png, trajectories.png, summary.json).
Methods that ask for expectations are run by ``mindgap eps``, whose person is built from the
world's expected policy.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..algorithms import methods
from ..algorithms.engine import TEACHERS
from .config_flags import add_config_flags, with_flags
from .learn import add_env_flag, write_outputs


def generated(taken) -> list[methods.Method]:
    """The registered methods whose command is built here: those without a command of their own
    (``taken``) that ask for preferences or nothing."""
    return [m for m in methods.METHODS.values() if m.name not in taken and m.answers != "expectations"]


def add_parsers(sub, taken) -> list[str]:
    """A subcommand for each of :func:`generated`; returns their names."""
    names = []
    for m in generated(taken):
        p = sub.add_parser(m.name, help=f"{m.label} (a registered method; flags from its config)")
        add_env_flag(p)
        if m.answers == "preferences":
            p.add_argument(
                "--teacher", choices=TEACHERS, default="biased",
                help="biased: r_H + log T_H under the belief; unbiased: r_H + log T; true: r_H alone (B-Pref's)",
            )  # fmt: skip
            p.add_argument("--belief", help="belief of a biased teacher (default: the world's first)")
        p.add_argument("--fast", action="store_true", help="the fast preset (for dry runs; default: full)")
        p.add_argument("--seeds", type=int, default=1, help="seeds, vmapped in one program (default 1)")
        p.add_argument("--out", type=Path, required=True, help="run folder (reruns resume from its checkpoint)")
        p.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        add_config_flags(p, m.preset("full"), skip=("method",))
        names.append(m.name)
    return names


def run(args: argparse.Namespace) -> int:
    from ..envs.resolve import resolve_env

    m = methods.get(args.command)
    if args.seeds < 1:
        raise ValueError("--seeds must be at least 1")
    world = resolve_env(args.env)
    cfg = with_flags(m.preset("fast" if args.fast else "full"), args)
    who = dict(teacher=args.teacher, belief=args.belief) if m.answers == "preferences" else {}
    res = methods.train(m, world, cfg, args.seeds, out=args.out, progress=not args.quiet, fresh=args.fresh, **who)
    label = m.label if not who else f"{m.label} ({args.teacher} teacher)"
    summary = write_outputs(args.out, world, res, label, method=m.name, **who)
    print(
        f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
        f"{summary['final_return_std']:.1f} over {args.seeds} seed(s), {summary['queries']} queries; "
        f"curve.csv, curve.png, trajectories.png in {args.out}/"
    )
    return 0
