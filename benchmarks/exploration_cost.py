"""Benchmark: what the learners' default exploration costs per environment step.

Side by side in one process, the same jitted training chunk (``sac_loop.run_chunk``, one
update per step, seeds vmapped) with plain SAC exploration, with pink action noise, and
with pink noise plus the state-entropy bonus (``engine.EXPLORATION``, every learner's default). Compilation
is excluded (one warm-up chunk each); the ratio to plain SAC is printed.

    python benchmarks/exploration_cost.py [--world d3] [--seeds 5] [--chunks 3] [--hidden 64]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import jax

from mindgap.algorithms.engine import EXPLORATION
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.envs.terrain import load_world

CHUNK = 1000


def steps_per_second(world, cfg: SACConfig, seeds: int, chunks: int) -> float:
    keys = jax.random.split(jax.random.key(0), seeds)
    ls = jax.vmap(lambda k: loop_init(k, world.env, world.params, cfg, CHUNK * (chunks + 1)))(keys)
    chunk = jax.jit(
        jax.vmap(lambda s: run_chunk(s, world.env, world.params, None, n_steps=CHUNK, cfg=cfg, phase="train"))
    )
    ls = jax.block_until_ready(chunk(ls))  # compile, and fill the buffer a little
    start = time.perf_counter()
    for _ in range(chunks):
        ls = jax.block_until_ready(chunk(ls))
    return seeds * chunks * CHUNK / (time.perf_counter() - start)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="d3")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--chunks", type=int, default=3, help=f"timed chunks of {CHUNK} steps")
    ap.add_argument("--hidden", type=int, default=64)
    args = ap.parse_args()
    world = load_world(args.world)
    base = SACConfig(hidden=(args.hidden, args.hidden), learning_starts=0)
    variants = {
        "plain SAC": base,
        "pink noise": dataclasses.replace(base, noise_color=EXPLORATION["noise_color"]),
        "pink noise + entropy bonus (default)": dataclasses.replace(base, **EXPLORATION),
    }
    print(
        f"{args.world}, {args.seeds} seeds vmapped, {args.hidden}x{args.hidden}, batch {base.batch_size}, 1 update/step"
    )
    plain = None
    for name, cfg in variants.items():
        sps = steps_per_second(world, cfg, args.seeds, args.chunks)
        plain = plain or sps
        print(f"  {name:38s} {sps:8.0f} env steps/s   ratio to plain {sps / plain:.2f}")


if __name__ == "__main__":
    main()
