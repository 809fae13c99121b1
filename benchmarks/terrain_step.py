"""Benchmark: terrain-world steps per second, vectorised JAX vs the gymnasium adapter in a Python loop.

Side by side in one process: ``jax.vmap``-ed ``step`` inside one jitted ``lax.scan``
(1, 64 and 4096 worlds, random actions, automatic reset at episode end) against
:class:`~mindgap.envs.terrain.gym_env.TerrainEnv` stepped one call at a time, as a
gymnasium-based library would. Compilation is excluded (one warm-up call each).

    python benchmarks/terrain_step.py [--world nav1] [--steps 200] [--gym-steps 2000]
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mindgap import rng
from mindgap.envs.terrain import load_world, reset, step
from mindgap.envs.terrain.gym_env import TerrainEnv


@partial(jax.jit, static_argnums=(2, 3))
def run_vectorised(key, params, n_envs: int, n_steps: int):
    """n_steps × n_envs transitions with random actions; finished worlds restart."""

    def body(carry, k):
        states, total = carry
        k_act, k_step, k_reset = jax.random.split(k, 3)
        actions = jax.random.uniform(k_act, (n_envs, 2), minval=-1.0, maxval=1.0)
        out = jax.vmap(step, (0, 0, 0, None))(jax.random.split(k_step, n_envs), states, actions, params)
        fresh = jax.vmap(reset, (0, None))(jax.random.split(k_reset, n_envs), params)
        states = jax.tree.map(
            lambda f, s: jnp.where(out.state.done[:, None] if s.ndim > 1 else out.state.done, f, s), fresh, out.state
        )
        return (states, total + out.reward.sum()), None

    states = jax.vmap(reset, (0, None))(jax.random.split(key, n_envs), params)
    (states, total), _ = jax.lax.scan(body, (states, 0.0), jax.random.split(key, n_steps))
    return total


def time_vectorised(params, n_envs, n_steps, repeats=3):
    jax.block_until_ready(run_vectorised(rng.key(0), params, n_envs, n_steps))  # compile
    best = np.inf
    for r in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run_vectorised(rng.key(r + 1), params, n_envs, n_steps))
        best = min(best, time.perf_counter() - t0)
    return n_envs * n_steps / best


def time_gym(world, n_steps):
    env = TerrainEnv(world)
    env.reset(seed=0)
    env.step(env.action_space.sample())  # compile
    acts = np.random.default_rng(0).uniform(-1, 1, (n_steps, 2)).astype(np.float32)
    t0 = time.perf_counter()
    for a in acts:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return n_steps / (time.perf_counter() - t0)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--world", default="nav1")
    p.add_argument("--steps", type=int, default=200, help="steps per world in the vectorised runs")
    p.add_argument("--gym-steps", type=int, default=2000, help="steps of the gymnasium loop")
    args = p.parse_args()
    world = load_world(args.world)
    gym_rate = time_gym(args.world, args.gym_steps)
    print(f"world {args.world}, backend {jax.default_backend()}, {jax.device_count()} device(s)")
    print(f"{'runner':<34} {'steps/s':>12} {'vs gymnasium loop':>18}")
    print(f"{'gymnasium adapter, Python loop':<34} {gym_rate:>12,.0f} {1.0:>17.1f}×")
    for n in (1, 64, 4096):
        rate = time_vectorised(world.params, n, args.steps)
        print(f"{f'JAX vmap + scan, {n} worlds':<34} {rate:>12,.0f} {rate / gym_rate:>17.1f}×", flush=True)


if __name__ == "__main__":
    main()
