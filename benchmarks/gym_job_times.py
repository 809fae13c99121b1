"""Benchmark: the time of each of the gym experiment's jobs, one seed, a short run, at given SAC settings.

The full preset's budget (docs/experiments/gym.md, "The budget") is set from these: each job of
``mindgap reproduce gym`` (the reference, SAC, PEBBLE 800, PrefBias 800) on each domain, one seed,
``--steps`` environment steps (5,000 random, PEBBLE's and PrefBias's pre-training, the first
feedback rounds), the full preset's learners with the SAC widths and update rate given, compilation
included, one job after another in this process. It prints each job's seconds and the full job
extrapolated linearly to ``--full-steps`` and 5 seeds run one after another (the host loop's 5
vmapped seeds cost about 5 times one on this CPU, docs/benchmarks.md (e″)) — a rough figure: it
counts compilation and the random steps as learning steps, and the feedback rounds the short run
holds. ``--job-seeds 5`` trains the short run's 5 seeds together, as a whole job does, and
extrapolates in steps only: the figure for an accelerator, where vmapped seeds share each step.

    python benchmarks/gym_job_times.py --hidden 128 --train-every 2 [--steps 11000] [--full-steps 200000]
    python benchmarks/gym_job_times.py --hidden 128 --train-every 2 --job-seeds 5   # on a GPU
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import jax

from mindgap.experiments import prefbias_common as pc
from mindgap.experiments import prefbias_gym as gym


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--domains", nargs="+", default=["lunar", "hopper", "cheetah"])
    p.add_argument("--hidden", type=int, default=256)
    p.add_argument("--train-every", type=int, default=1)
    p.add_argument("--steps", type=int, default=11_000)
    p.add_argument("--full-steps", type=int, default=300_000)
    p.add_argument("--seeds", type=int, default=5, help="the full preset's seeds, for the extrapolation")
    p.add_argument(
        "--methods", nargs="+", default=None, help="learner jobs to time (default all; the reference always runs)"
    )
    p.add_argument("--job-seeds", type=int, default=1, help="seeds trained together in the short run")
    args = p.parse_args()
    if not 1 <= args.job_seeds <= args.seeds:
        p.error(f"--job-seeds must be between 1 and --seeds ({args.seeds}), not {args.job_seeds}")
    base = gym.gym_learners("full")
    sac = replace(base.sac.sac, hidden=(args.hidden, args.hidden), train_every=args.train_every)
    learners = pc.Learners(*(replace(c, sac=sac) for c in (base.prefbias, base.pebble, base.sac)))
    scale = args.full_steps / args.steps * args.seeds / args.job_seeds
    print(
        f"{args.hidden}×{args.hidden}, an update every {args.train_every} step(s); "
        f"{args.job_seeds} seed(s) together, {args.steps} steps; {jax.default_backend()}",
        flush=True,
    )
    for domain in args.domains:
        cfg = replace(
            gym.preset("full"),
            worlds=(domain,),
            budgets=(800,),
            seeds=args.job_seeds,
            steps={domain: args.steps},
            levels=False,
            learners=learners,
        )
        with tempfile.TemporaryDirectory() as out:
            for job in gym.jobs(cfg):
                if args.methods and job.method != "reference" and job.method not in args.methods:
                    continue
                t0 = time.perf_counter()
                gym.run(cfg, Path(out), fresh=False, progress=False, assemble_only=False, only=job.key)
                seconds = time.perf_counter() - t0
                full = "" if job.method == "reference" else f"; full job ≈ {seconds * scale / 3600:.1f} h"
                print(f"{job.key}: {seconds:.0f} s{full}", flush=True)


if __name__ == "__main__":
    main()
