"""SAC on a gymnasium env: mindgap's host loop (one seed) against sbx's SAC, side by side in one process.

Same settings on both sides (SB3/sbx defaults where not given): train_freq=1, gradient_steps=1,
batch 256, learning_starts, buffer = total steps, white noise, no entropy bonus, auto-tuned α.

    .venv/bin/python benchmarks/host_loop_sbx.py --env Pendulum-v1 --steps 5000 --hidden 256,256
"""

from __future__ import annotations

import argparse
import time


def ours(env_id: str, steps: int, hidden, starts: int, batch: int) -> float:
    from mindgap.algorithms.pbrl import method_config, train
    from mindgap.algorithms.sac import SACConfig
    from mindgap.envs.gym_world import make_gym_world

    world = make_gym_world(env_id)
    sac = SACConfig(hidden=hidden, batch_size=batch, learning_starts=starts)
    cfg = method_config("sac", total_steps=steps, chunk=starts, eval_every=steps, eval_episodes=1, sac=sac)
    train(
        world,
        method_config("sac", total_steps=2 * starts, chunk=starts, eval_every=2 * starts, eval_episodes=1, sac=sac),
        progress=False,
    )  # compile
    t = time.perf_counter()
    train(world, cfg, progress=False)
    return steps / (time.perf_counter() - t)


def theirs(env_id: str, steps: int, hidden, starts: int, batch: int) -> float:
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
    SAC("MlpPolicy", gymnasium.make(env_id), **kw).learn(2 * starts)  # compile
    model = SAC("MlpPolicy", gymnasium.make(env_id), **kw)
    t = time.perf_counter()
    model.learn(steps)
    return steps / (time.perf_counter() - t)


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
    mine = ours(*args)
    print(f"mindgap host loop: {mine:.0f} steps/s ({a.env}, {a.steps} steps, {a.hidden}, batch {a.batch})")
    try:
        import sbx  # noqa: F401
    except ImportError:
        print("sbx is not installed (pip install -e '.[bench]'): no comparison")
        return
    other = theirs(*args)
    print(f"sbx SAC:           {other:.0f} steps/s")
    print(f"ratio (mindgap / sbx): {mine / other:.2f}")


if __name__ == "__main__":
    main()
