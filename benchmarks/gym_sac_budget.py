"""Benchmark: the gym preset's SAC oracle at other network widths and update rates, side by side.

The control domains' full preset is almost all SAC updates (docs/experiments/gym.md, "The
budget"). This trains the preset's SAC oracle — ``gym_learners("full").sac`` of
:mod:`~mindgap.experiments.prefbias_gym`, on the domain's true env through the host loop — with
the hidden widths and ``train_every`` given (everything else the preset's), so that one setting can
be held against another — the preset's 128 × 128 with an update every second step against the SAC
levels' 256 × 256 with one every step: the final greedy return per seed and the wall time, one
process on one core. Each run
checkpoints into ``--out`` and resumes; ``--out/NAME.json`` keeps the result.

    python benchmarks/gym_sac_budget.py --domain hopper --hidden 256 --train-every 1 --seeds 3 --steps 100000
    python benchmarks/gym_sac_budget.py --domain hopper --hidden 128 --train-every 2 --seeds 1 --steps 100000
    python benchmarks/gym_sac_budget.py --domain cheetah --hidden 128 --seeds 3 --seed 1   # 3 other seeds
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mindgap._io import atomic_write
from mindgap.algorithms import methods
from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.experiments import prefbias_gym as gym


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--domain", default="hopper", choices=("lunar", "hopper", "cheetah"))
    p.add_argument(
        "--hidden", type=int, default=256, help="h of the h×h actor and critics (SAC levels: 256; preset 128)"
    )
    p.add_argument("--train-every", type=int, default=1, help="environment steps per update (SAC levels: 1; preset 2)")
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--seed", type=int, help="the run's base seed, for other seeds than the preset's (default: its own)")
    p.add_argument("--out", type=Path, default=Path("runs/gym-sac-budget"))
    args = p.parse_args()
    base = gym.gym_learners("full").sac
    cfg = replace(
        base,
        total_steps=args.steps,
        seed=base.seed if args.seed is None else args.seed,
        sac=replace(base.sac, hidden=(args.hidden, args.hidden), train_every=args.train_every),
    )
    cfg.check()
    world = gym_world_from_spec(gym._spec(gym.domain(args.domain).env, None))
    name = f"{args.domain}-h{args.hidden}-every{args.train_every}-s{args.seeds}-{args.steps}"
    name += "" if args.seed is None else f"-seed{args.seed}"
    t0 = time.perf_counter()
    res = methods.train("sac", world, cfg, args.seeds, teacher="true", out=args.out / name, progress=True)
    seconds = time.perf_counter() - t0
    final = np.asarray(res["final_returns"], np.float64).mean(1)
    rec = {
        "domain": args.domain,
        "hidden": args.hidden,
        "train_every": args.train_every,
        "seeds": args.seeds,
        "seed": cfg.seed,
        "steps": args.steps,
        "final_per_seed": [round(float(x), 1) for x in final],
        "curve": [[int(s), int(t), round(float(r), 1)] for s, t, r, _ in res["curve"]],
        "seconds_this_process": round(seconds, 1),
    }
    atomic_write(args.out / f"{name}.json", json.dumps(rec, indent=1))
    print(f"{name}: final return per seed {rec['final_per_seed']} ({seconds:.0f} s in this process)")


if __name__ == "__main__":
    main()
