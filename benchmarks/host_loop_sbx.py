"""SAC on gymnasium envs: mindgap's host loop (1 and N seeds) against sbx and Stable-Baselines3, side by side in one process.

Same settings on every side (SB3/sbx defaults where not given): train_freq=1, gradient_steps=1,
batch 256, learning_starts, buffer = total steps, white noise, no entropy bonus, auto-tuned α.
mindgap and sbx first run the identical configuration once, so that neither is timed
compiling (mindgap's compiled programs depend on the buffer's capacity, which is the run's
length); the compile-inclusive first run is printed too. SB3 compiles nothing and runs once,
on one torch thread (two threads stall on this 2-core machine whenever another process takes
a core; ``benchmarks/sac_throughput.py`` measures both). mindgap's time includes its
evaluations (one greedy episode per seed at the end); sbx and SB3 evaluate nothing.

``--seeds 1 8``: mindgap runs the seeds vmapped (one gymnasium env per seed, one compiled
dispatch a step for all of them); the rate is all seeds' environment steps per second, to
compare with running the seeds one after another at the single-seed rate. sbx and SB3 train
one seed per process.

``--env`` takes gymnasium ids or the control domains' names: ``lunar`` (``LunarLander-v3``
with ``continuous=True``), ``hopper`` (``Hopper-v5``), ``cheetah`` (``HalfCheetah-v5``), the
true dynamics' envs without the hidden noise, so that all three libraries step the same env.

    .venv/bin/python benchmarks/host_loop_sbx.py --env Pendulum-v1 --steps 5000 --hidden 256,256
    .venv/bin/python benchmarks/host_loop_sbx.py --env lunar hopper cheetah --steps 3000 --seeds 1 8
"""

from __future__ import annotations

import argparse
import time

DOMAINS = {
    "lunar": ("LunarLander-v3", {"continuous": True}),
    "hopper": ("Hopper-v5", {}),
    "cheetah": ("HalfCheetah-v5", {}),
}


def env_of(name: str) -> tuple[str, dict]:
    """gymnasium id and keyword arguments of a domain name or a plain id."""
    return DOMAINS.get(name, (name, {}))


def ours(name: str, steps: int, hidden, starts: int, batch: int, seeds: int) -> tuple[float, float]:
    from mindgap.algorithms.pbrl import method_config, train
    from mindgap.algorithms.sac import SACConfig
    from mindgap.envs.gym_world import make_gym_world

    env_id, kwargs = env_of(name)
    world = make_gym_world(env_id, **kwargs)
    sac = SACConfig(hidden=hidden, batch_size=batch, learning_starts=starts)
    cfg = method_config("sac", total_steps=steps, chunk=starts, eval_every=steps, eval_episodes=1, sac=sac)
    return _twice(lambda: train(world, cfg, seeds=seeds, progress=False), steps * seeds)


def _twice(run, steps: int) -> tuple[float, float]:
    """Steps per second of a first (compiling) and a second run of the same thing."""
    rates = []
    for _ in range(2):
        t = time.perf_counter()
        run()
        rates.append(steps / (time.perf_counter() - t))
    return rates[0], rates[1]


def _kwargs(steps: int, hidden, starts: int, batch: int) -> dict:
    return dict(
        policy_kwargs=dict(net_arch=list(hidden)),
        batch_size=batch,
        learning_starts=starts,
        buffer_size=steps,
        train_freq=1,
        gradient_steps=1,
        verbose=0,
        seed=0,
    )


def sbx_rate(name: str, steps: int, hidden, starts: int, batch: int) -> tuple[float, float]:
    import gymnasium
    from sbx import SAC

    env_id, kwargs = env_of(name)
    kw = _kwargs(steps, hidden, starts, batch)
    return _twice(lambda: SAC("MlpPolicy", gymnasium.make(env_id, **kwargs), **kw).learn(steps), steps)


def sb3_rate(name: str, steps: int, hidden, starts: int, batch: int) -> float:
    import gymnasium
    import torch
    from stable_baselines3 import SAC

    torch.set_num_threads(1)
    env_id, kwargs = env_of(name)
    model = SAC("MlpPolicy", gymnasium.make(env_id, **kwargs), device="cpu", **_kwargs(steps, hidden, starts, batch))
    t = time.perf_counter()
    model.learn(steps)
    return steps / (time.perf_counter() - t)


def _installed(module: str) -> bool:
    try:
        __import__(module)
    except ImportError:
        return False
    return True


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", nargs="+", default=["Pendulum-v1"])
    p.add_argument("--steps", type=int, default=5000)
    p.add_argument("--hidden", default="256,256")
    p.add_argument("--learning-starts", type=int, default=1000)
    p.add_argument("--batch", type=int, default=256)
    p.add_argument("--seeds", type=int, nargs="+", default=[1], help="mindgap's vmapped seed counts")
    p.add_argument("--no-sb3", action="store_true", help="skip Stable-Baselines3 (the slowest side)")
    a = p.parse_args()
    hidden = tuple(int(x) for x in a.hidden.split(","))
    missing = [m for m in ("sbx", "stable_baselines3") if not _installed(m)]
    if missing:
        print(f"{', '.join(missing)} not installed (pip install -e '.[bench]'): those rows are skipped")
    have_sbx, have_sb3 = "sbx" not in missing, "stable_baselines3" not in missing and not a.no_sb3
    print(f"({a.steps} steps per seed, {a.hidden}, batch {a.batch}, {a.learning_starts} random steps first;")
    print(" environment steps per second of all seeds, compiled; first run in brackets)")
    for name in a.env:
        args = (name, a.steps, hidden, a.learning_starts, a.batch)
        print(f"\n{name} ({env_of(name)[0]})")
        mine = {}
        for seeds in a.seeds:
            first, mine[seeds] = ours(*args, seeds)
            print(f"  mindgap host loop, {seeds} seed(s): {mine[seeds]:7.0f}  ({first:.0f})")
        one = mine.get(1)
        if one is not None:
            for seeds, rate in mine.items():
                if seeds > 1:
                    print(f"  {seeds} seeds vmapped / one after another: {rate / one:.2f}")
        if have_sbx:
            first, other = sbx_rate(*args)
            print(f"  sbx SAC:                      {other:7.0f}  ({first:.0f})")
            if one is not None:
                print(f"  ratio mindgap 1 seed / sbx: {one / other:.2f}")
        if have_sb3:
            sb3 = sb3_rate(*args)
            print(f"  Stable-Baselines3 SAC (1 thread): {sb3:7.0f}")
            if one is not None:
                print(f"  ratio mindgap 1 seed / SB3: {one / sb3:.2f}")


if __name__ == "__main__":
    main()
