"""Benchmark: PrefBias's training throughput against PEBBLE's, same world, budget and schedule.

Issue 6 asks that learning the person's belief cost well under twice PEBBLE's time. Both
learners run side by side in one process with the schedule of the ``nav`` experiment
(:func:`mindgap.experiments.prefbias_common.learners`: PrefBias's defaults, 80 queries a
round; PEBBLE copies its steps, chunks, evaluation, SAC settings, rounds, segments and
exploration), shortened to ``--rounds`` feedback rounds: 1000 random steps, 4000
state-entropy steps, then ``--rounds`` × 2000 training steps with a round at the start of
each. The biased teacher of the world's first belief answers; the query budget is what the
rounds ask (``--rounds`` × 80).

Each learner runs :func:`train` twice with the same configuration: the first run compiles
every program (random, exploration and training chunks, the feedback round, evaluation),
the second — timed — reuses them, so the figure is steady-state environment steps per second
of the whole loop: SAC updates, feedback rounds (PrefBias: train f_ψ, select queries, fit
q(w) q(φ), relabel; PEBBLE: select, fit the ensemble, relabel) and evaluations. With
``--seeds N`` the seeds run vmapped and the rate counts all of them. ``--runs`` repeats the
timed run and keeps the fastest, so that other processes on a shared machine disturb it less.

    python benchmarks/prefbias_throughput.py [--world nav1] [--rounds 3] [--seeds 1] [--runs 1] [--preset full|fast]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import jax

from mindgap.algorithms import pbrl, prefbias
from mindgap.envs.terrain import load_world
from mindgap.experiments.prefbias_common import learners


def configs(preset: str, rounds: int):
    """PrefBias's and PEBBLE's configurations of the ``nav`` experiment, cut to ``rounds`` feedback rounds."""
    learn = learners(preset)
    pb = learn.prefbias
    steps = pb.learning_steps() + rounds * pb.feedback_every
    common = dict(total_steps=steps, queries=rounds * pb.per_round, eval_every=steps)
    return dataclasses.replace(pb, **common), dataclasses.replace(learn.pebble, **common)


def time_train(train, world, cfg, seeds: int, runs: int) -> tuple[float, float]:
    """(seconds of the compiling run, fastest of ``runs`` timed runs) of ``train(world, cfg)``."""
    t0 = time.perf_counter()
    jax.block_until_ready(train(world, cfg, seeds=seeds, teacher="biased", progress=False)["final_returns"])
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        jax.block_until_ready(train(world, cfg, seeds=seeds, teacher="biased", progress=False)["final_returns"])
        best = min(best, time.perf_counter() - t0)
    return first, best


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--world", default="nav1", help="a named world or world file (needs a belief)")
    p.add_argument("--rounds", type=int, default=3, help="feedback rounds (2000 training steps each)")
    p.add_argument("--seeds", type=int, default=1, help="seeds, vmapped in one program")
    p.add_argument("--runs", type=int, default=1, help="timed runs per learner; the fastest counts")
    p.add_argument("--preset", default="full", choices=["full", "fast"], help="fast: tiny networks (a smoke test)")
    args = p.parse_args()
    if args.rounds < 1 or args.seeds < 1 or args.runs < 1:
        raise SystemExit("--rounds, --seeds and --runs must be at least 1")

    world = load_world(args.world)
    pb_cfg, peb_cfg = configs(args.preset, args.rounds)
    print(
        f"PrefBias vs PEBBLE on {world.name} ({args.preset} preset), biased teacher; {pb_cfg.total_steps} steps: "
        f"{pb_cfg.sac.learning_starts} random, {pb_cfg.explore_steps} exploration, {args.rounds} round(s) of "
        f"{pb_cfg.per_round} queries every {pb_cfg.feedback_every} steps; {args.seeds} seed(s); "
        f"backend {jax.default_backend()}, {len(os.sched_getaffinity(0))} cores"
    )
    rates = {}
    print(f"{'learner':<10} {'compiling run s':>15} {'timed run s':>11} {'env steps/s':>11}")
    for name, train, cfg in (("PEBBLE", pbrl.train, peb_cfg), ("PrefBias", prefbias.train, pb_cfg)):
        first, best = time_train(train, world, cfg, args.seeds, args.runs)
        rates[name] = args.seeds * cfg.total_steps / best
        print(f"{name:<10} {first:>15.1f} {best:>11.1f} {rates[name]:>11,.0f}", flush=True)
    ratio = rates["PEBBLE"] / rates["PrefBias"]
    print(f"PrefBias takes {ratio:.2f}× PEBBLE's time per environment step (issue 6: well under 2×)")


if __name__ == "__main__":
    main()
