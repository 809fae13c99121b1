"""Benchmark: SAC training throughput, mindgap vs Stable-Baselines3 vs sbx, on one terrain world.

Side by side in one process, with identical settings: terrain world ``d1`` (SB3 and sbx
step it through the gymnasium adapter :class:`~mindgap.envs.terrain.gym_env.TerrainEnv`),
actor and twin critics with the same hidden widths and ReLU, Adam 3e-4, batch 256, one
update per environment step (``train_freq=1, gradient_steps=1``), the same
``learning_starts`` of uniformly random actions, a buffer that holds every transition,
and automatically tuned α starting at 1. Each run does ``learning_starts`` random steps,
one warm-up chunk of ``--chunk`` training steps (compilation happens here) and then
``--chunks`` timed chunks of the same length; the figure is environment steps per second
(each with its update) in the fastest chunk, so that other processes on a shared machine
disturb it less. mindgap runs one seed with :func:`~mindgap.algorithms.sac_loop.run_chunk`
(one jitted call per chunk) and 8 seeds vmapped through it (aggregate steps per second of
all seeds); SB3 and sbx run ``SAC.learn`` with a callback that reads the clock at the
chunk boundaries. SB3 runs on whichever of 1 or all cores' torch threads is faster on a
matmul check just before its run (``--torch-threads`` fixes it): on a shared machine
two OpenMP threads slow down many times over as soon as another process takes a core.
The sbx and SB3 packages come from the ``bench`` extra; a missing one is skipped with a
message. Every JAX row (mindgap's and sbx's, every size) runs before the first SB3 row: once
torch's OpenMP threads have run in a process, their spin-waiting takes the second core from
XLA's later work (measured: mindgap's host loop at 256×256 141 steps/s after an SB3 run, 214
before it, 216 after it with ``OMP_WAIT_POLICY=PASSIVE``, which in turn slows SB3 twofold).

Arithmetic: the FLOPs of one SAC update count the matrix multiplications of the networks
(2 per multiply-add, :func:`~mindgap.models.mlp.mlp_flops`) and nothing else (no
elementwise work, no Adam, no acting). With ``A`` the actor's and ``C`` one critic's
forward pass on the batch, one update is

* target: actor on s' (A) and both target critics (2C);
* critic loss: both critics forward (2C) and backward (4C, backward = 2× forward);
* actor loss: actor forward (A), both critics forward on (s, ã) (2C), backward through
  the critics to the action only (2C, input gradients = 1× forward) and through the actor
  (2A);

in all ``4A + 12C`` (about 0.55 GFLOP for 256×256 networks). The GFLOP/s column is
``steps/s × FLOPs per update`` with this one count for all three (sbx does the same
arithmetic; SB3 does 2C more, as its actor loss also back-propagates into the critics'
weights, so its column slightly understates the rate it computes at); the reference is
a plain float32 matrix multiplication ``[batch, h] · [h, h]`` repeated in a chain, with
XLA (what the JAX updates use) and with NumPy's BLAS, best of the two.

The host loop (:mod:`~mindgap.algorithms.host_loop`: a gymnasium env stepped on the host, one
compiled dispatch a step) is timed on ``--host-env`` (Pendulum-v1 by default) the same way, best
of ``--chunks`` chunks of ``--chunk`` training steps after the random steps and a warm-up, with
``host_loop_profile.host_step_seconds`` (one seed, the SAC oracle's update), beside sbx and SB3 on
that env; its FLOPs count that env's observation and action sizes. The line after those rows is
the host loop's rate against the jitted loop's (one seed each, the same networks).

    python benchmarks/sac_throughput.py [--sizes 256 128 64] [--chunk 250] [--chunks 4] [--seeds 8] [--skip sb3 sbx] [--host-env Pendulum-v1|none]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from host_loop_profile import host_step_seconds
from mindgap import rng
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.envs.gym_world import make_gym_world
from mindgap.envs.interface import EnvError
from mindgap.envs.terrain import TERRAIN_ENV, load_world
from mindgap.envs.terrain.gym_env import TerrainEnv
from mindgap.models.mlp import mlp_flops

OBS_DIM, ACT_DIM = 2, 2


def update_flops(hidden: tuple[int, ...], batch: int, obs_dim: int = OBS_DIM, act_dim: int = ACT_DIM) -> int:
    """Matrix-multiply FLOPs of one SAC update (see the module docstring): 4A + 12C."""
    a = mlp_flops((obs_dim, *hidden, 2 * act_dim), batch)
    c = mlp_flops((obs_dim + act_dim, *hidden, 1), batch)
    return 4 * a + 12 * c


# ---------------------------------------------------------------------------------------
# plain matrix multiplication


@partial(jax.jit, static_argnums=2)
def _matmul_chain(x, w, n: int):
    return jax.lax.scan(lambda x, _: (x @ w, None), x, None, length=n)[0]


def matmul_gflops(batch: int, h: int, total_flops: float = 2e10, repeats: int = 3) -> tuple[float, float]:
    """GFLOP/s of ``x ← x · w`` with x [batch, h], w [h, h] (orthogonal, so no overflow): (XLA, NumPy)."""
    g = np.random.default_rng(0)
    w = np.linalg.qr(g.standard_normal((h, h)))[0].astype(np.float32)
    x = g.standard_normal((batch, h)).astype(np.float32)
    per = 2.0 * batch * h * h
    n = max(10, int(total_flops / per))
    xj, wj = jnp.asarray(x), jnp.asarray(w)
    jax.block_until_ready(_matmul_chain(xj, wj, n))  # compile
    best_x = best_n = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(_matmul_chain(xj, wj, n))
        best_x = min(best_x, time.perf_counter() - t0)
        y = x
        t0 = time.perf_counter()
        for _ in range(n):
            y = y @ w
        best_n = min(best_n, time.perf_counter() - t0)
    return n * per / best_x / 1e9, n * per / best_n / 1e9


# ---------------------------------------------------------------------------------------
# mindgap


@partial(jax.jit, static_argnames=("n_steps", "cfg", "phase"))
def _run_seeds(ls, world_params, *, n_steps: int, cfg: SACConfig, phase: str):
    return jax.vmap(lambda s: run_chunk(s, TERRAIN_ENV, world_params, None, n_steps=n_steps, cfg=cfg, phase=phase))(ls)


def time_ours(world_params, cfg: SACConfig, n_seeds: int, chunk: int, chunks: int) -> float:
    """Aggregate env steps/s of ``n_seeds`` seeds: best of ``chunks`` timed chunks after one warm-up chunk."""
    capacity = cfg.learning_starts + chunk * (1 + chunks)
    keys = jax.random.split(rng.key(0), n_seeds)
    if n_seeds == 1:
        ls = loop_init(keys[0], TERRAIN_ENV, world_params, cfg, capacity)

        def go(ls, n, phase):
            return run_chunk(ls, TERRAIN_ENV, world_params, None, n_steps=n, cfg=cfg, phase=phase)
    else:
        ls = jax.vmap(lambda k: loop_init(k, TERRAIN_ENV, world_params, cfg, capacity))(keys)

        def go(ls, n, phase):
            return _run_seeds(ls, world_params, n_steps=n, cfg=cfg, phase=phase)

    ls = jax.block_until_ready(go(ls, cfg.learning_starts, "random"))
    ls = jax.block_until_ready(go(ls, chunk, "train"))  # compiles
    best = np.inf
    for _ in range(chunks):
        t0 = time.perf_counter()
        ls = jax.block_until_ready(go(ls, chunk, "train"))
        best = min(best, time.perf_counter() - t0)
    return n_seeds * chunk / best


# ---------------------------------------------------------------------------------------
# Stable-Baselines3 and sbx through the gymnasium adapter


def time_library(lib: str, make_env: Callable, cfg: SACConfig, chunk: int, chunks: int) -> float:
    """Env steps/s of SB3's or sbx's ``SAC.learn`` on ``make_env()``: best of ``chunks`` timed chunks after
    one warm-up chunk."""
    from stable_baselines3.common.callbacks import BaseCallback

    if lib == "sb3":
        from stable_baselines3 import SAC

        extra = {"device": "cpu"}
    else:
        from sbx import SAC

        extra = {}

    start = cfg.learning_starts + chunk
    total = start + chunk * chunks
    ticks = []

    class Clock(BaseCallback):
        def _on_step(self) -> bool:  # after the env step, before that step's update
            if self.num_timesteps >= start and (self.num_timesteps - start) % chunk == 0:
                ticks.append(time.perf_counter())
            return True

    model = SAC(
        "MlpPolicy",
        make_env(),
        learning_rate=cfg.lr,
        buffer_size=total,
        learning_starts=cfg.learning_starts,
        batch_size=cfg.batch_size,
        tau=cfg.tau,
        gamma=cfg.gamma,
        train_freq=1,
        gradient_steps=cfg.utd,
        ent_coef="auto",
        policy_kwargs={"net_arch": list(cfg.hidden)},
        seed=0,
        verbose=0,
        **extra,
    )
    model.learn(total_timesteps=total, callback=Clock())
    return chunk / float(np.min(np.diff(ticks)))


def pick_torch_threads(batch: int, h: int, cores: int) -> int:
    """The faster of 1 and ``cores`` torch threads on a [batch, h]·[h, h] matmul chain, measured now.

    On a shared machine, torch's OpenMP threads slow down many times over as soon as another
    process takes a core, so SB3 gets whichever count is faster at the moment it runs.
    """
    import torch

    x, w = torch.randn(batch, h), torch.linalg.qr(torch.randn(h, h))[0]
    n = max(20, int(2e9 / (2 * batch * h * h)))
    best = {}
    for t in sorted({1, cores}):
        torch.set_num_threads(t)
        for _ in range(5):
            x = x @ w
        t0 = time.perf_counter()
        for _ in range(n):
            x = x @ w
        best[t] = time.perf_counter() - t0
    threads = min(best, key=best.get)
    torch.set_num_threads(threads)
    return threads


def time_adapter(world: str, n_steps: int = 2000) -> float:
    """Steps/s of the gymnasium adapter alone (random actions): the others' ceiling."""
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


def _available(module: str) -> str | None:
    try:
        __import__(module)
    except ImportError as e:  # the bench extra is not installed
        return f"{module} not importable ({e}); install the bench extra: pip install -e '.[bench]'"
    return None


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--world", default="d1")
    p.add_argument("--sizes", type=int, nargs="+", default=[256, 128, 64], help="hidden width h of h×h networks")
    p.add_argument("--chunk", type=int, default=250, help="training steps per timed chunk (and of the warm-up)")
    p.add_argument("--chunks", type=int, default=4, help="timed chunks per run; the best one counts")
    p.add_argument("--learning-starts", type=int, default=1000)
    p.add_argument("--seeds", type=int, default=8, help="vmapped seeds of the aggregate run (0 or 1 skips it)")
    p.add_argument("--seed-chunks", type=int, default=2, help="timed chunks of the vmapped run")
    p.add_argument("--torch-threads", type=int, default=None, help="torch threads (default: faster of 1 and all cores)")
    p.add_argument("--skip", nargs="*", default=[], choices=["sb3", "sbx"], help="libraries to leave out")
    p.add_argument(
        "--host-env", default="Pendulum-v1", help="gymnasium env of the host-loop rows ('none' leaves them out)"
    )
    args = p.parse_args()

    cores = len(os.sched_getaffinity(0))
    missing = {lib: _available(mod) for lib, mod in (("sb3", "stable_baselines3"), ("sbx", "sbx"))}
    if missing["sb3"] is None:
        import torch

        torch_info = f"torch {torch.__version__}"
    else:
        torch_info = "no torch"
    for lib, why in missing.items():
        if why is not None and lib not in args.skip:
            print(f"skipping {lib}: {why}")
            args.skip.append(lib)

    world = load_world(args.world)
    try:
        host = None if args.host_env == "none" else make_gym_world(args.host_env)
    except EnvError as e:
        p.error(str(e))
    adapter = time_adapter(args.world)
    print(
        f"SAC on terrain world {args.world} (SB3 and sbx through the gymnasium adapter); batch 256, "
        f"1 update per env step, learning_starts {args.learning_starts}, auto α, Adam 3e-4"
    )
    print(
        f"{args.learning_starts} random steps, 1 warm-up chunk, then the best of {args.chunks} timed chunks of "
        f"{args.chunk} training steps; backend {jax.default_backend()}, {cores} cores, {torch_info}"
    )
    print(f"gymnasium adapter alone, random actions: {adapter:,.0f} steps/s")
    print(
        f"{'networks':<9} {'env':<12} {'runner':<34} {'env steps/s':>11} {'GFLOP/s':>8} {'of matmul':>9} {'vs sbx':>7} {'vs SB3':>7}"
    )
    cfgs = {
        h: SACConfig(hidden=(h, h), batch_size=256, utd=1, learning_starts=args.learning_starts) for h in args.sizes
    }
    envs = {args.world: lambda: TerrainEnv(args.world)}
    if host is not None:
        envs[args.host_env] = lambda: host.make(0)[0]
    rates = {(h, where): {} for h in args.sizes for where in envs}  # (size, env) → {runner: steps/s}
    matmul, sb3_threads = {}, {}
    # JAX first, every size; SB3 (torch) last: once torch's OpenMP threads have run, they slow XLA's
    # later work in the same process (docs/benchmarks.md, "SAC throughput").
    for h, cfg in cfgs.items():
        print(f"measuring {h}×{h}: matmul, mindgap, sbx …", file=sys.stderr, flush=True)
        matmul[h] = matmul_gflops(cfg.batch_size, h)
        mine = rates[h, args.world]
        mine["mindgap SAC, 1 seed"] = time_ours(world.params, cfg, 1, args.chunk, args.chunks)
        if args.seeds > 1:
            rate = time_ours(world.params, cfg, args.seeds, args.chunk, args.seed_chunks)
            mine[f"mindgap SAC, {args.seeds} seeds vmapped"] = rate
        if host is not None:
            hosted = 1.0 / host_step_seconds(host, h, args.chunk, args.chunks, args.learning_starts)
            rates[h, args.host_env]["mindgap host loop, 1 seed"] = hosted
        if "sbx" not in args.skip:
            for where, make_env in envs.items():
                rates[h, where]["sbx"] = time_library("sbx", make_env, cfg, args.chunk, args.chunks)
    if "sb3" not in args.skip:
        import torch

        for h, cfg in cfgs.items():
            print(f"measuring {h}×{h}: Stable-Baselines3 …", file=sys.stderr, flush=True)
            sb3_threads[h] = args.torch_threads or pick_torch_threads(cfg.batch_size, h, cores)
            torch.set_num_threads(sb3_threads[h])
            for where, make_env in envs.items():
                rates[h, where]["sb3"] = time_library("sb3", make_env, cfg, args.chunk, args.chunks)
    for h, cfg in cfgs.items():
        mm = max(matmul[h])
        net = f"{h}×{h}"
        for where in envs:
            dims = () if where == args.world else (host.env.observation_space.dim, host.env.action_space.dim)
            report(net, where, rates[h, where], update_flops(cfg.hidden, cfg.batch_size, *dims), mm, sb3_threads.get(h))
        if host is not None:
            ratio = rates[h, args.host_env]["mindgap host loop, 1 seed"] / rates[h, args.world]["mindgap SAC, 1 seed"]
            print(f"{net:<9} host loop ({args.host_env}) / jitted loop ({args.world}), 1 seed: {ratio:.2f}")
        print(
            f"{net:<9} plain matmul [256×{h}]·[{h}×{h}]: XLA {matmul[h][0]:.1f}, NumPy {matmul[h][1]:.1f} GFLOP/s; "
            f"one update on {args.world} = {update_flops(cfg.hidden, cfg.batch_size) / 1e9:.3f} GFLOP",
            flush=True,
        )


def report(net: str, where: str, rates: dict, flops: float, mm: float, threads: int | None) -> None:
    """One line a runner on env ``where``: steps/s, GFLOP/s at ``flops`` per update, its share of the best
    matmul ``mm``, and its ratios to sbx and SB3 there (SB3 ran on ``threads`` torch threads)."""
    names = {"sbx": "sbx SAC", "sb3": f"Stable-Baselines3 SAC ({threads} thread{'s' if threads != 1 else ''})"}
    for runner, rate in rates.items():
        gf = rate * flops / 1e9
        ratios = [f"{rate / rates[lib]:>6.2f}×" if lib in rates else f"{'-':>7}" for lib in ("sbx", "sb3")]
        print(
            f"{net:<9} {where:<12} {names.get(runner, runner):<34} {rate:>11,.0f} {gf:>8.1f} {gf / mm:>8.0%} "
            f"{ratios[0]} {ratios[1]}",
            flush=True,
        )


if __name__ == "__main__":
    main()
