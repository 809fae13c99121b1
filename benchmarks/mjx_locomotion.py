"""Benchmark: the MJX hopper and cheetah (vmapped worlds) against gymnasium's Hopper-v5 / HalfCheetah-v5 on the host.

Side by side in one process: the MJX world's ``step`` (:mod:`mindgap.envs.mjx_locomotion`,
hidden noise on) ``jax.vmap``-ed over 1, 8, 64 and 256 worlds inside one jitted ``lax.scan``,
random actions, finished episodes restarting — against gymnasium's env stepped one call at a
time in a Python loop (the host loop's stepping; N envs on the host cost N times one). The
MJX rows give the compile time (lowering and compiling the scan) and the best of three timed
calls after a warm-up; the ratio is MJX steps/s over the host's.

``--sac 1 8`` times instead mindgap's SAC (64 × 64, batch 256, 3,000 steps: 500 random, one
evaluation episode) on ``mjx:BODY`` and on gymnasium's noisy env through the host loop, for
each number of seeds: a first run (compiling) and a second (compiled).

``--accuracy`` prints instead how far each named solver option set moves one step from
gymnasium's options, in MuJoCo's C engine (float64, so the difference is the options' own),
from the states of random-action episodes: the table of :mod:`mindgap.envs.mjx_model`.

    python benchmarks/mjx_locomotion.py [--body hopper cheetah] [--solver fast] [--steps 100]
    python benchmarks/mjx_locomotion.py --sac 1 8 --body cheetah
    python benchmarks/mjx_locomotion.py --accuracy
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.envs.mjx_locomotion import BODIES, mjx_world
from mindgap.envs.mjx_model import SOLVERS, load_model


@partial(jax.jit, static_argnums=(0, 3, 4))
def run_vectorised(env, key, params, n_worlds: int, n_steps: int):
    """n_steps × n_worlds transitions with random actions; finished worlds restart."""
    a_dim = env.action_space.dim

    def body(carry, k):
        states, total = carry
        k_act, k_step, k_reset = jax.random.split(k, 3)
        actions = jax.random.uniform(k_act, (n_worlds, a_dim), minval=-1.0, maxval=1.0)
        out = jax.vmap(env.step, (0, 0, 0, None))(jax.random.split(k_step, n_worlds), states, actions, params)
        fresh = jax.vmap(env.reset, (0, None))(jax.random.split(k_reset, n_worlds), params)
        done = out.terminated | out.truncated
        states = jax.tree.map(lambda f, s: jnp.where(done.reshape((-1,) + (1,) * (s.ndim - 1)), f, s), fresh, out.state)
        return (states, total + out.reward.sum()), None

    states = jax.vmap(env.reset, (0, None))(jax.random.split(key, n_worlds), params)
    (_, total), _ = jax.lax.scan(body, (states, 0.0), jax.random.split(key, n_steps))
    return total


def time_mjx(world, n_worlds: int, n_steps: int, repeats: int = 3) -> tuple[float, float]:
    """(compile seconds, steps/s over all worlds) of :func:`run_vectorised`."""
    args = (world.env, jax.random.key(0), world.params, n_worlds, n_steps)
    t0 = time.perf_counter()
    compiled = run_vectorised.lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(jax.random.key(0), world.params))  # warm-up
    best = np.inf
    for r in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.key(r + 1), world.params))
        best = min(best, time.perf_counter() - t0)
    return compile_s, n_worlds * n_steps / best


def time_gym(gym_id: str, n_steps: int) -> float:
    """Steps/s of gymnasium's env stepped one call at a time, restarting at episode ends."""
    import gymnasium

    env = gymnasium.make(gym_id)
    env.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-1, 1, (n_steps, env.action_space.shape[0])).astype(np.float32)
    t0 = time.perf_counter()
    for a in acts:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    rate = n_steps / (time.perf_counter() - t0)
    env.close()
    return rate


def speed(bodies, solvers, steps: int, gym_steps: int) -> None:
    print(f"backend {jax.default_backend()}, {jax.device_count()} device(s); hidden noise on (share 0.2, scale 0.5)")
    print(f"{'runner':<44} {'compile s':>10} {'steps/s':>10} {'vs host':>8}")
    for body in bodies:
        gym_id = BODIES[body].gym_id
        host = time_gym(gym_id, gym_steps)
        print(f"{f'{gym_id}, gymnasium on the host':<44} {'':>10} {host:>10,.0f} {1.0:>7.2f}×", flush=True)
        for solver in solvers:
            world = mjx_world(body, solver=solver)
            for n in (1, 8, 64, 256):
                n_steps = max(20, steps * 8 // max(n, 8))  # fewer steps per world as the batch grows
                compile_s, rate = time_mjx(world, n, n_steps)
                label = f"mjx:{body} solver={solver}, {n} worlds"
                print(f"{label:<44} {compile_s:>10.1f} {rate:>10,.0f} {rate / host:>7.2f}×", flush=True)


def sac(bodies, seed_counts, steps: int = 3000) -> None:
    """Seconds of mindgap's SAC on the MJX world and on the gym world through the host loop, compiling and compiled."""
    from mindgap.algorithms.pbrl import method_config, train
    from mindgap.algorithms.sac import SACConfig
    from mindgap.envs.mujoco_noise import IDS
    from mindgap.envs.resolve import resolve_env

    noisy = {base: noisy for noisy, base in IDS.items()}
    cfg = method_config(
        "sac",
        total_steps=steps,
        chunk=500,
        eval_every=steps,
        eval_episodes=1,
        sac=SACConfig(hidden=(64, 64), batch_size=256, learning_starts=500),
    )
    print(f"SAC, {steps} steps a seed (500 random), one evaluation episode; seconds")
    print(f"{'world':<36} {'seeds':>5} {'compiling':>10} {'compiled':>9} {'steps/s':>8}")
    for body in bodies:
        for spec in (f"gym:{noisy[BODIES[body].gym_id]}", f"mjx:{body}"):
            world = resolve_env(spec)
            for seeds in seed_counts:
                times = []
                for _ in range(2):
                    t0 = time.perf_counter()
                    train(world, cfg, seeds=seeds, progress=False)
                    times.append(time.perf_counter() - t0)
                rate = steps * seeds / times[1]
                print(f"{spec:<36} {seeds:>5} {times[0]:>10.1f} {times[1]:>9.1f} {rate:>8,.0f}", flush=True)


def accuracy(bodies, episodes: dict, seed: int = 0) -> None:
    """One-step |Δ qvel| of each solver option set against gymnasium's, in MuJoCo's C engine."""
    import gymnasium

    print("one step from gymnasium's states (random actions), MuJoCo C, float64: max |Δ qvel| over the joints")
    print(f"{'body':<8} {'solver':<7} {'states':>6} {'median':>9} {'95th pct':>9} {'max':>9}")
    for body in bodies:
        spec = BODIES[body]
        states = []
        env = gymnasium.make(spec.gym_id).unwrapped
        for ep in range(episodes[body]):
            env.reset(seed=seed + ep)
            rng = np.random.default_rng(seed + ep)
            for _ in range(200):
                a = rng.uniform(-1, 1, env.model.nu)
                states.append((env.data.qpos.copy(), env.data.qvel.copy(), env.data.qacc_warmstart.copy(), a))
                if env.step(a)[2]:
                    break
        env.close()
        ref = load_model(body, "gym")
        for solver in SOLVERS:
            if solver == "gym":
                continue
            model = load_model(body, solver)
            errs = [_one_step_gap(ref, model, spec.frame_skip, *s) for s in states]
            q = np.quantile(errs, [0.5, 0.95])
            print(f"{body:<8} {solver:<7} {len(errs):>6} {q[0]:>9.1e} {q[1]:>9.1e} {max(errs):>9.1e}", flush=True)


def _one_step_gap(ref, model, frame_skip, qpos, qvel, warm, ctrl) -> float:
    import mujoco

    out = []
    for m in (ref, model):
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:], d.qacc_warmstart[:], d.ctrl[:] = qpos, qvel, warm, ctrl
        mujoco.mj_step(m, d, nstep=frame_skip)
        out.append(d.qvel.copy())
    return float(np.abs(out[0] - out[1]).max())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--body", nargs="+", default=list(BODIES), choices=list(BODIES))
    p.add_argument("--solver", nargs="+", default=["fast"], choices=list(SOLVERS))
    p.add_argument("--steps", type=int, default=100, help="steps per world at 1 and 8 worlds (fewer at 64 and 256)")
    p.add_argument("--gym-steps", type=int, default=5000, help="steps of the gymnasium loop")
    p.add_argument("--accuracy", action="store_true", help="print the solver options' one-step differences instead")
    p.add_argument("--sac", type=int, nargs="+", metavar="SEEDS", help="time SAC on both runtimes with these seeds")
    args = p.parse_args()
    if args.sac:
        sac(args.body, args.sac)
    elif args.accuracy:
        accuracy(args.body, {"hopper": 60, "cheetah": 5})
    else:
        speed(args.body, args.solver, args.steps, args.gym_steps)


if __name__ == "__main__":
    main()
