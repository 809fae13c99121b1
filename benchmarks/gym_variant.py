"""Check: one seed of a gym job with PrefBias's inference or the domain changed, beside the committed run's seed.

A modelling choice (a :class:`~mindgap.algorithms.prefbias_inference.PrefBiasConfig` field with
``--set``, e.g. ``log_f_floor=-20``: f_φ's log density floored as the simulated person floors log T_H;
or another domain of :data:`~mindgap.experiments.prefbias_gym.DOMAINS` with ``--world``, e.g.
``hopper-fixed``: the hopper whose episodes do not end when it falls) is held against the full run
as committed: the same job of the full preset (:mod:`~mindgap.experiments.prefbias_gym`), the same
seed, the same person and schedule, only what is given changed, trained in its own folder
(``--out/KEY``; it checkpoints and resumes). ``--set`` takes PrefBias jobs; ``--world`` any learner
job (SAC, PEBBLE, PrefBias), so that every method can be run on the changed domain alike. It prints
the final greedy return, the greedy episodes' top second observation (the lander's and the
hopper's height: the lander's learned reward paying height shows as a climb; docs/experiments/gym.md,
"The runs so far") and their mean length (a hopper that falls at once ends its episodes in a few
steps), for the variant and the committed seed, and keeps the variant's record in
``--out/KEY__seed-I.json``. One process; about a slice's time (15–20 minutes on one core of the
2-core machine for the full preset's 300,000 steps).

    python benchmarks/gym_variant.py --job lunar/prefbias-q200 --seed 3 --set log_f_floor=-20
    python benchmarks/gym_variant.py --job hopper/pebble-q800 --seed 1 --world hopper-fixed
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from mindgap._io import atomic_write
from mindgap.commands.design import prefbias_overrides
from mindgap.envs.interface import EnvError
from mindgap.experiments import prefbias_gym as gym
from mindgap.experiments._runfolder import RunFolder, partial_path


def _summary(rec: dict) -> dict:
    """Final greedy return, the greedy episodes' top second observation (the lander's and the hopper's
    height) and their mean length in steps."""
    eps = [np.asarray(ep) for seed in rec["paths"] for ep in seed]
    top = max(float(np.max(ep[:, 1])) for ep in eps)
    steps = [len(ep) - 1 for ep in eps]  # a path holds the first observation and one a step
    return {"final": float(np.mean(rec["final"])), "top_height": top, "length": float(np.mean(steps))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--job", required=True, help="a learner job of the full preset, e.g. lunar/prefbias-q200")
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="a PrefBiasConfig field")
    p.add_argument("--world", default=None, help="run the job on this domain instead (e.g. hopper-fixed)")
    p.add_argument("--out", type=Path, default=Path("runs/gym-variant"))
    p.add_argument("--committed", type=Path, default=Path("results/gym"), help="the full run to compare with")
    args = p.parse_args()
    try:
        cfg = gym.preset("full")
        by_key = {j.key: j for j in gym.jobs(cfg)}
        job = by_key.get(args.job)
        kinds = ("prefbias",) if args.world is None else ("prefbias", "pebble", "sac")
        if job is None or job.method not in kinds:
            keys = ", ".join(k for k, j in by_key.items() if j.method in kinds)
            raise ValueError(f"--job must be one of the full preset's jobs {keys}, got {args.job!r}")
        if not 0 <= args.seed < cfg.seeds:
            raise ValueError(f"--seed must lie in 0 … {cfg.seeds - 1}, got {args.seed}")
        changed = prefbias_overrides(args.set)
        if not changed and args.world is None:
            raise ValueError("give --set FIELD=VALUE or --world DOMAIN: with neither this is the committed job")
        if changed and job.method != "prefbias":
            raise ValueError(f"--set changes PrefBias's inference, and {args.job} is not a PrefBias job")
        if args.world is not None:
            gym.check_domain(args.world, "--world")
            cfg = dataclasses.replace(cfg, worlds=(args.world,))  # its steps: gym._steps
            job = {j.method + j.label: j for j in gym.jobs(cfg)}[job.method + job.label]
        if changed:
            pb = dataclasses.replace(job.cfg.prefbias, **changed)
            pb.check()
            job = job._replace(cfg=dataclasses.replace(job.cfg, prefbias=pb))
    except (ValueError, TypeError, EnvError) as e:
        sys.exit(f"gym_variant: {e}")
    if args.world is not None:
        changed = {**changed, "world": args.world}
    name = job.key.replace("/", "__")
    folder = RunFolder(args.out / name, job.cfg)  # a folder a job: its config
    rec = gym.compute_job(folder, job, cfg.seeds, cfg=cfg, fresh=False, progress=True, seed_ids=(args.seed,))
    rec = {**rec, "changed": changed, "job": args.job, "seed": args.seed}
    path = args.out / f"{name}__seed-{args.seed}.json"
    atomic_write(path, json.dumps(rec))

    def said(x: dict) -> str:
        return f"final {x['final']:.1f}, top height {x['top_height']:.1f}, episodes of {x['length']:.0f} steps"

    line = f"{job.key} seed {args.seed} with {changed}: {said(_summary(rec))}"
    committed = partial_path(args.committed, args.job, args.seed)
    if committed.is_file():
        line += f"; committed {args.job}: {said(_summary(json.loads(committed.read_text())))}"
    print(line)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
