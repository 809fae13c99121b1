"""SAC on a gymnasium env: mindgap's host loop (one seed) against sbx's SAC, side by side in one process.

Same settings on both sides (SB3/sbx defaults where not given): train_freq=1, gradient_steps=1,
batch 256, learning_starts, buffer = total steps, white noise, no entropy bonus, auto-tuned α.
Each side first runs the identical configuration once, so that neither is timed compiling
(mindgap's compiled programs depend on the buffer's capacity, which is the run's length); the
compile-inclusive first run is printed too. mindgap's time includes its evaluations (20 greedy
episodes at the end); sbx evaluates nothing.

    .venv/bin/python benchmarks/host_loop_sbx.py --env Pendulum-v1 --steps 5000 --hidden 256,256
"""

from __future__ import annotations

import argparse
import time


def ours(env_id: str, steps: int, hidden, starts: int, batch: int) -> tuple[float, float]:
    from mindgap.algorithms.pbrl import method_config, train
    from mindgap.algorithms.sac import SACConfig
    from mindgap.envs.gym_world import make_gym_world

    world = make_gym_world(env_id)
    sac = SACConfig(hidden=hidden, batch_size=batch, learning_starts=starts)
    cfg = method_config("sac", total_steps=steps, chunk=starts, eval_every=steps, eval_episodes=1, sac=sac)
    return _twice(lambda: train(world, cfg, progress=False), steps)


def _twice(run, steps: int) -> tuple[float, float]:
    """Steps per second of a first (compiling) and a second run of the same thing."""
    rates = []
    for _ in range(2):
        t = time.perf_counter()
        run()
        rates.append(steps / (time.perf_counter() - t))
    return rates[0], rates[1]


def theirs(env_id: str, steps: int, hidden, starts: int, batch: int) -> tuple[float, float]:
    import gymnasium
    from sbx import SAC

    kw = dict(
        policy_kwargs=dict(net_arch=list(hidden)),
        batch_size=batch,
        learning_starts=starts,
        buffer_size=steps,
        train_freq=1,
        gradient_steps=1,
        verbose=0,
        seed=0,
    )
    return _twice(lambda: SAC("MlpPolicy", gymnasium.make(env_id), **kw).learn(steps), steps)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="Pendulum-v1")
    p.add_argument("--steps", type=int, default=5000)
    p.add_argument("--hidden", default="256,256")
    p.add_argument("--learning-starts", type=int, default=1000)
    p.add_argument("--batch", type=int, default=256)
    a = p.parse_args()
    hidden = tuple(int(x) for x in a.hidden.split(","))
    args = (a.env, a.steps, hidden, a.learning_starts, a.batch)
    first, mine = ours(*args)
    print(f"({a.env}, {a.steps} steps, {a.hidden}, batch {a.batch}; steps/s, first run compiling)")
    print(f"mindgap host loop: {mine:.0f} steps/s (first run {first:.0f})")
    try:
        import sbx  # noqa: F401
    except ImportError:
        print("sbx is not installed (pip install -e '.[bench]'): no comparison")
        return
    first, other = theirs(*args)
    print(f"sbx SAC:           {other:.0f} steps/s (first run {first:.0f})")
    print(f"ratio (mindgap / sbx): {mine / other:.2f}")


if __name__ == "__main__":
    main()
