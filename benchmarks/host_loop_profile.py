"""Benchmark: where a SAC step's time goes on the host loop (gymnasium envs), at given network sizes.

The host loop (:mod:`~mindgap.algorithms.host_loop`) steps one gymnasium env per seed in Python
and makes one compiled dispatch a step (:func:`~mindgap.algorithms.host_loop.advance`: store the
transition, update SAC, draw the next action). This times, per environment step of one seed in the
``train`` phase (the SAC oracle's plain update: white noise, no entropy bonus, batch 256, one update
a step, the settings of ``host_loop_sbx.py``), best of ``--reps`` runs of ``--steps`` steps each:

* the whole host step (the env's step with the action copied to the host, then ``advance``);
* the env alone (``env.step`` on the same actions, already on the host);
* ``advance`` without its update (``update=False``: dispatch, store, act, the copies in and out);
* the update alone as the jitted loop runs it: :func:`~mindgap.algorithms.sac_loop.sac_updates` (the
  minibatch draw with n-step targets, the novelty bonus, one SAC update) in a ``lax.scan`` of
  ``--steps`` iterations on the host loop's own buffer — a lower bound of the jitted loop's step at
  these shapes (its acting, stepping and storing cost about 25 µs more, docs/benchmarks.md).

The host step's rate against that bound is the issue's aim (≥ 0.85: the host loop within 15% of the
jitted loop's steps per second). Two more figures say where a dispatch's cost comes from: the same
update dispatched once per step (its state donated) instead of scanned, and the loop state passed
through a program that does nothing (the cost of handing over its arrays).

    python benchmarks/host_loop_profile.py [--env Pendulum-v1] [--sizes 64 128 256] [--steps 500]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from mindgap import rng
from mindgap.algorithms import engine
from mindgap.algorithms import host_loop as hl
from mindgap.algorithms.methods import SAC
from mindgap.algorithms.pbrl import method_config
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import sac_updates
from mindgap.envs.gym_world import make_gym_world


def best_of(run, reps: int) -> float:
    """Seconds of the fastest of ``reps`` calls of ``run`` (which blocks on its result)."""
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def host_loop(world, hidden: int, steps: int, reps: int, starts: int = 1000):
    """One seed's host loop for ``hidden`` × ``hidden`` networks, ready to step: ``host_steps(n, phase,
    update=True, env_only=False)`` runs ``n`` host steps (the env's step, then ``advance``), and the
    state it keeps (``state["loop"]``, the learner's ``sac_cfg`` and ``knn``) for the figures built
    beside it."""
    sac = SACConfig(hidden=(hidden, hidden), batch_size=256, learning_starts=starts)
    cfg = method_config("sac", total_steps=starts + (2 * reps + 2) * steps, chunk=steps, sac=sac)
    learner = SAC.learner(cfg)
    env, w, sac_cfg = world.env, engine.WorldArgs(world.params, world.obs_units(), None), learner.agent_sac(cfg)
    d = env.observation_space.dim
    carry = engine.init_carry(engine.seed_keys(0, 1), learner, env, None, cfg, start=lambda k: jnp.zeros(d))
    envs = hl._Envs(world, (0,), 0)
    state = {"loop": carry.loop._replace(env=jnp.asarray(envs.obs), t=jnp.zeros(1, jnp.int32))}
    state["loop"], state["act"] = hl.first_action(state["loop"], sac_cfg, "random")
    state.update(sac_cfg=sac_cfg, knn=cfg.knn)

    def host_steps(n: int, phase: str, update: bool = True, env_only: bool = False):
        act = state["act"]
        for _ in range(n):
            nxt, rew, term, trunc, start = envs.step(np.asarray(act))
            if env_only:
                continue
            state["loop"], act = hl.advance(
                state["loop"], carry.model, w, act, nxt, rew, term, trunc, start,
                learner=learner, env=env, cfg=cfg, phase=phase, next_phase=phase, update=update,
            )  # fmt: skip
        state["act"] = jax.block_until_ready(act)

    host_steps(starts, "random")  # fill the buffer past a batch
    host_steps(2, "train")  # compile the training step
    return host_steps, state


def host_step_seconds(world, hidden: int, steps: int, reps: int, starts: int = 1000) -> float:
    """Seconds of one whole host step in the ``train`` phase (one seed): best of ``reps`` runs of ``steps``."""
    host_steps, _ = host_loop(world, hidden, steps, reps, starts)
    return best_of(lambda: host_steps(steps, "train"), reps) / steps


def profile(world, hidden: int, steps: int, reps: int, starts: int = 1000) -> dict:
    """Microseconds per step of each part (module docstring) for ``hidden`` × ``hidden`` networks."""
    host_steps, state = host_loop(world, hidden, steps, reps, starts)
    sac_cfg, knn = state["sac_cfg"], state["knn"]
    host_steps(2, "train", update=False)  # compile the step without its update
    whole = best_of(lambda: host_steps(steps, "train"), reps)
    bare = best_of(lambda: host_steps(steps, "train", update=False), reps)
    env_alone = best_of(lambda: host_steps(steps, "train", env_only=True), reps)
    one = jax.tree.map(lambda x: x[0], state["loop"])  # the seed's loop state, unbatched
    keys = jax.random.split(rng.key(3), steps)

    def updates(sac_state, replay):
        def body(c, k):
            return sac_updates(c, replay, k, one.steps, sac_cfg, "train", knn), None

        return jax.lax.scan(body, sac_state, keys)[0]

    scan = jax.jit(updates)
    jax.block_until_ready(scan(one.sac, one.replay))
    update = best_of(lambda: jax.block_until_ready(scan(one.sac, one.replay)), reps)
    single = jax.jit(lambda c, replay, k: sac_updates(c, replay, k, one.steps, sac_cfg, "train", knn), donate_argnums=0)
    held = {"sac": jax.tree.map(jnp.array, one.sac)}  # own buffers: donated every call

    def dispatched():
        for k in keys:
            held["sac"] = single(held["sac"], one.replay, k)
        jax.block_until_ready(held["sac"])

    dispatched()
    per_dispatch = best_of(dispatched, reps)
    ident = jax.jit(lambda loop: loop, donate_argnums=0)
    held["loop"] = jax.tree.map(jnp.array, state["loop"])

    def passed():
        for _ in range(steps):
            held["loop"] = ident(held["loop"])
        jax.block_until_ready(held["loop"])

    passed()
    handling = best_of(passed, reps)
    times = {"whole": whole, "bare": bare, "env": env_alone, "update": update, "dispatched": per_dispatch}
    return {**{k: v / steps * 1e6 for k, v in times.items()}, "handling": handling / steps * 1e6,
            "leaves": len(jax.tree.leaves(state["loop"]))}  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="Pendulum-v1")
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256])
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--reps", type=int, default=3)
    args = p.parse_args()
    world = make_gym_world(args.env)
    print(f"{args.env}, one seed, batch 256, one update a step; µs per step (best of {args.reps} × {args.steps} steps)")
    for h in args.sizes:
        t = profile(world, h, args.steps, args.reps)
        dispatch = t["bare"] - t["env"]
        print(
            f"{h}×{h}: host step {t['whole']:.0f} ({1e6 / t['whole']:,.0f} steps/s) = env {t['env']:.0f} "
            f"+ advance without its update {dispatch:.0f} + the rest {t['whole'] - t['bare']:.0f}; "
            f"the update alone, jitted {t['update']:.0f}; host step rate / jitted bound {t['update'] / t['whole']:.2f}; "
            f"one update per dispatch {t['dispatched']:.0f}; passing the loop state ({t['leaves']} arrays, donated) "
            f"through an empty program {t['handling']:.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
