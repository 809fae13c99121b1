"""Benchmark: steps per second of the driving scenario (§4.4.2), vectorised JAX vs highway-env.

Side by side in one process:

* the JAX world (:mod:`mindgap.envs.driving`): ``jax.vmap``-ed ``step`` inside one jitted
  ``lax.scan`` over 1, 64 and 1024 worlds (uniformly random meta-actions, finished worlds
  restart), full sleet; the first call compiles (its time is printed), the figure is the best
  of three timed calls;
* highway-env's own ``highway-v0`` (its defaults: 4 lanes, 50 IDM cars, 15 integration steps a
  decision), stepped one call at a time, as an agent steps it;
* the same scenario in highway-env (:class:`~mindgap.envs.driving.highway.SleetHighwayEnv`: two
  cars, the sleet, r_A), stepped the same way.

One step is one decision (1 s of driving, 15 integration steps) everywhere. The ratio column
divides by ``highway-v0``'s rate. highway-env comes from the ``driving`` extra.

    python benchmarks/driving_step.py [--steps 200] [--highway-steps 30] [--scenario-steps 300]
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mindgap import rng
from mindgap.envs.driving import make_params, reset, step


@partial(jax.jit, static_argnums=(2, 3))
def run_vectorised(key, params, n_envs: int, n_steps: int):
    """n_steps × n_envs decisions with random meta-actions; finished worlds restart."""

    def body(carry, k):
        states, total = carry
        k_act, k_step, k_reset = jax.random.split(k, 3)
        actions = jax.random.randint(k_act, (n_envs,), 0, 5)
        out = jax.vmap(step, (0, 0, 0, None))(jax.random.split(k_step, n_envs), states, actions, params)
        fresh = jax.vmap(reset, (0, None))(jax.random.split(k_reset, n_envs), params)
        done = out.state.done
        states = jax.tree.map(lambda f, s: jnp.where(done.reshape((-1,) + (1,) * (s.ndim - 1)), f, s), fresh, out.state)
        return (states, total + out.reward.sum()), None

    states = jax.vmap(reset, (0, None))(jax.random.split(key, n_envs), params)
    (states, total), _ = jax.lax.scan(body, (states, 0.0), jax.random.split(key, n_steps))
    return total


def time_vectorised(params, n_envs: int, n_steps: int, repeats: int = 3) -> tuple[float, float]:
    """(compile seconds, steps per second)."""
    t0 = time.perf_counter()
    jax.block_until_ready(run_vectorised(rng.key(0), params, n_envs, n_steps))
    compile_s = time.perf_counter() - t0
    best = np.inf
    for r in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run_vectorised(rng.key(r + 1), params, n_envs, n_steps))
        best = min(best, time.perf_counter() - t0)
    return compile_s, n_envs * n_steps / best


def time_gym(env, n_steps: int) -> float:
    """Steps per second of a gymnasium env stepped in a Python loop with random actions (reset when done)."""
    env.reset(seed=0)
    env.action_space.seed(0)
    env.step(env.action_space.sample())  # warm-up
    t0 = time.perf_counter()
    for _ in range(n_steps):
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            env.reset()
    rate = n_steps / (time.perf_counter() - t0)
    env.close()
    return rate


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=200, help="decisions per world in the vectorised runs")
    p.add_argument("--highway-steps", type=int, default=30, help="decisions of highway-v0 (a few a second)")
    p.add_argument("--scenario-steps", type=int, default=300, help="decisions of the highway-env scenario")
    args = p.parse_args()

    import gymnasium
    import highway_env  # noqa: F401 - registers highway-v0

    from mindgap.envs.driving.highway import ENV_ID, register

    register()
    highway = time_gym(gymnasium.make("highway-v0"), args.highway_steps)
    scenario = time_gym(gymnasium.make(ENV_ID, sleet=1.0), args.scenario_steps)
    print(
        f"backend {jax.default_backend()}, {jax.device_count()} device(s); one step = one decision (1 s, 15 sub-steps)"
    )
    print(f"{'runner':<42} {'compile s':>9} {'steps/s':>12} {'vs highway-v0':>14}")
    print(f"{'highway-env highway-v0, Python loop':<42} {'':>9} {highway:>12,.1f} {1.0:>13.1f}×")
    print(f"{'highway-env sleet scenario, Python loop':<42} {'':>9} {scenario:>12,.1f} {scenario / highway:>13.1f}×")
    params = make_params(sleet=1.0)
    for n in (1, 64, 1024):
        compile_s, rate = time_vectorised(params, n, args.steps)
        name = f"JAX vmap + scan, {n} worlds"
        print(f"{name:<42} {compile_s:>9.1f} {rate:>12,.0f} {rate / highway:>13,.0f}×", flush=True)


if __name__ == "__main__":
    main()
