"""The terrain-world experiments on the command line: ``mindgap reproduce nav|priors|sampling|eps|lambda``,
and ``gym`` (the control domains, whose ``--worlds`` are domain names: lunar, hopper, cheetah, hopper-fixed,
hopper-fixed-seen, cheetah-seen, hopper-mjx, cheetah-mjx; :mod:`~.prefbias_gym`).

mindgap reproduce nav [--fast] [--seeds N] [--worlds W,W | --env SPEC …] [--method NAME …] [--out DIR] [--fresh] [--quiet] [--assemble]
mindgap reproduce gym --out DIR --job KEY --seed I     # seed I of one learner job alone (nav, priors, sampling, gym)
mindgap reproduce gym --out DIR --job KEY --reuse SRC  # a job the person never enters, from a run of the same robot

``--fast`` is the quick preset (1 seed, 1500 steps, tiny networks: a dry run and the tests'
preset, not results); without it the full one (the PrefBias experiments: 5 seeds, 50 000
steps, 80 queries a round; the EPS ones: 5 seeds, 60 000 steps, 800 queries). ``--worlds``
runs a subset of the experiment's worlds (or world files); ``--env SPEC`` (repeatable) runs
it on any world with a belief and an exact density, a user's ``path.py:factory`` included
(:mod:`~.world_measures` says what is measured on a world without a map). ``--method NAME``
(repeatable, nav and gym) adds a registered preference learner beside PEBBLE, on PEBBLE's schedule and
budget (``MINDGAP_METHODS=file.py`` registers one from a file). The run folder defaults to
``runs/NAME`` (``runs/NAME-fast``); rerunning resumes: finished jobs are read back, an
interrupted one continues from its checkpoint. ``--job KEY --seed I`` trains seed I of a learner
job alone (:mod:`~mindgap.experiments._seed_slices`: a full job outlasts a session), and the job's
record is assembled once every seed has run.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..algorithms import methods
from ..experiments import registry
from ..experiments._runfolder import print_run

NAMES = ("nav", "priors", "sampling", "eps", "lambda", "gym")


def reproduce(args) -> int:
    """Run one of :data:`NAMES` from the parsed ``mindgap reproduce`` arguments; print its table."""
    if args.name not in NAMES:
        raise ValueError(f"unknown terrain experiment {args.name!r}: choose from {', '.join(NAMES)}")
    if getattr(args, "participants", None) is not None:
        raise ValueError("--participants belongs to the coffee study")
    if getattr(args, "shard", None):
        raise ValueError(f"--shard is not supported by {args.name}: its seeds already run together in one program")
    module = registry.module(args.name)
    cfg = module.preset("fast" if args.fast else "full")
    if args.seeds is not None:
        if args.seeds < 1:
            raise ValueError("--seeds must be at least 1")
        cfg = replace(cfg, seeds=args.seeds)
    worlds = ()
    if getattr(args, "worlds", None):
        worlds = tuple(w.strip() for w in args.worlds.split(",") if w.strip())
        if not worlds:
            raise ValueError("--worlds needs at least one world")
    worlds += tuple(e.strip() for e in getattr(args, "env", None) or ())
    if worlds:
        if any(not w for w in worlds):
            raise ValueError("--env needs a world")
        cfg = replace(cfg, worlds=worlds)
    extra = tuple(getattr(args, "method", None) or ())
    if extra:  # nav and gym only: mindgap reproduce refuses it for the others
        for name in extra:
            methods.get(name)  # an unknown name is refused here, with the registered ones
        cfg = replace(cfg, methods=extra)
    if getattr(args, "levels", False):  # gym only: mindgap reproduce refuses it for the others
        cfg = replace(cfg, levels=True)
    out = args.out or Path("runs") / (args.name + ("-fast" if args.fast else ""))
    only = getattr(args, "job", None)
    kw = dict(fresh=args.fresh, progress=not args.quiet, assemble_only=getattr(args, "assemble", False), only=only)
    if getattr(args, "seed", None) is not None:
        kw["seed_ids"] = tuple(args.seed)
    if getattr(args, "reuse", None) is not None:  # gym only: mindgap reproduce refuses it for the others
        from ..experiments import gym_reuse

        return print_run(gym_reuse.reuse(cfg, out, only, args.reuse, progress=not args.quiet), out, only)
    summary = module.run(cfg, out, **kw)
    return print_run(summary, out, only)
