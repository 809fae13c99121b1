"""Check: one seed of a gym PrefBias job with PrefBias's inference changed, beside the committed run's seed.

A modelling choice of PrefBias (a :class:`~mindgap.algorithms.prefbias_inference.PrefBiasConfig`
field, e.g. ``log_f_floor=-20``: f_φ's log density floored as the simulated person floors log T_H)
is held against the full run as committed: the same job of the full preset
(:mod:`~mindgap.experiments.prefbias_gym`), the same seed, the same person and schedule, only the
fields given changed, trained in its own folder (``--out/KEY``; it checkpoints and resumes). It prints
the final greedy return and the greedy episodes' top height (the lander's y: the learned reward
paying height shows as a climb; docs/experiments/gym.md, "The runs so far") of both, and keeps the
variant's record in ``--out/KEY__seed-I.json``. One process; about a slice's time (15–18 minutes
on one core of the 2-core machine for the full preset's 300,000 steps).

    python benchmarks/gym_prefbias_variant.py --job lunar/prefbias-q200 --seed 3 --set log_f_floor=-20
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
from mindgap.experiments import prefbias_gym as gym
from mindgap.experiments._runfolder import RunFolder


def _summary(rec: dict) -> dict:
    """Final greedy return, and the greedy episodes' top second observation (the lander's height)."""
    top = max(float(np.max(np.asarray(ep)[:, 1])) for seed in rec["paths"] for ep in seed)
    return {"final": float(np.mean(rec["final"])), "top_height": top}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--job", required=True, help="a PrefBias job of the full preset, e.g. lunar/prefbias-q200")
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="a PrefBiasConfig field")
    p.add_argument("--out", type=Path, default=Path("runs/gym-prefbias-variant"))
    p.add_argument("--committed", type=Path, default=Path("results/gym"), help="the full run to compare with")
    args = p.parse_args()
    try:
        cfg = gym.preset("full")
        by_key = {j.key: j for j in gym.jobs(cfg)}
        job = by_key.get(args.job)
        if job is None or job.method != "prefbias":
            keys = ", ".join(k for k, j in by_key.items() if j.method == "prefbias")
            raise ValueError(f"--job must be a PrefBias job of the full preset ({keys}), got {args.job!r}")
        if not 0 <= args.seed < cfg.seeds:
            raise ValueError(f"--seed must lie in 0 … {cfg.seeds - 1}, got {args.seed}")
        changed = prefbias_overrides(args.set)
        if not changed:
            raise ValueError("give at least one --set FIELD=VALUE: with none this is the committed job")
        pb = dataclasses.replace(job.cfg.prefbias, **changed)
        pb.check()
    except (ValueError, TypeError) as e:
        sys.exit(f"gym_prefbias_variant: {e}")
    variant = job._replace(cfg=dataclasses.replace(job.cfg, prefbias=pb))
    folder = RunFolder(args.out / args.job.replace("/", "__"), variant.cfg)  # a folder a job: its config
    rec = gym.compute_job(folder, variant, cfg.seeds, cfg=cfg, fresh=False, progress=True, seed_ids=(args.seed,))
    rec = {**rec, "changed": changed, "job": args.job, "seed": args.seed}
    path = args.out / f"{args.job.replace('/', '__')}__seed-{args.seed}.json"
    atomic_write(path, json.dumps(rec))
    mine = _summary(rec)
    line = f"{args.job} seed {args.seed} with {changed}: final {mine['final']:.1f}, top height {mine['top_height']:.1f}"
    committed = args.committed / "seeds" / args.job.replace("/", "__") / f"seed-{args.seed}.json"
    if committed.is_file():
        base = _summary(json.loads(committed.read_text()))
        line += f"; committed: final {base['final']:.1f}, top height {base['top_height']:.1f}"
    print(line)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
