"""Benchmark: the host loop's update step with its transition stored inside the update's program or apart.

In one compiled program (:func:`~mindgap.algorithms.host_loop.advance`: store, update, act) XLA's CPU
compiler fuses the buffer's write into the gathers of the update's minibatch, and then copies the
columns those gathers read so that they can still see the rows the write replaced — twice each, every
update step, at a cost that grows with the buffer. Storing apart (:func:`~mindgap.algorithms.host_loop.store`,
then ``advance(stored=True)``) costs one dispatch more and no copy. This times both on the gym preset's
SAC job (``hopper-fixed``: 128 × 128, an update every second step, pink noise, the entropy bonus; the
``train`` phase, one seed) at several buffer capacities, counts the buffer-sized copies in each compiled
update step, and checks that both give the same networks bit for bit.

    python benchmarks/host_loop_store.py [--capacities 20000 60000 300000] [--steps 1000] [--reps 3]

Each row is the best of ``--reps`` runs of ``--steps`` host steps after 1000 random steps; the gym
preset's own capacity is its 300,000 steps.
"""

from __future__ import annotations

import argparse
import re
import time
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.algorithms import engine
from mindgap.algorithms import host_loop as hl
from mindgap.algorithms.methods import SAC
from mindgap.experiments import prefbias_gym as pg


def setup(capacity: int):
    """The gym preset's SAC job on ``hopper-fixed`` with a buffer of ``capacity`` transitions, after its random steps."""
    full = pg.preset("full")
    job = next(j for j in pg.jobs(replace(full, worlds=("hopper-fixed",))) if j.method == "sac")
    world, _ = pg.load_world("hopper-fixed", full)
    cfg = replace(job.cfg, total_steps=capacity)  # the buffer holds the run's steps
    learner = SAC.learner(cfg)
    env, w, sac_cfg = world.env, engine.WorldArgs(world.params, world.obs_units(), None), learner.agent_sac(cfg)
    d = env.observation_space.dim
    carry = engine.init_carry(engine.seed_keys(0, 1), learner, env, None, cfg, start=lambda k: jnp.zeros(d))
    envs = hl._Envs(world, (0,), 0)
    loop = carry.loop._replace(env=jnp.asarray(envs.obs), t=jnp.zeros(1, jnp.int32))
    loop, act = hl.first_action(loop, sac_cfg, "random")
    kw = dict(learner=learner, env=env, cfg=cfg)
    state = {"loop": loop, "act": act}

    def steps(n: int, phase: str, apart: bool):
        loop, act = state["loop"], state["act"]
        for i in range(n):
            nxt, rew, term, trunc, start = envs.step(np.asarray(act))
            update = (i + 1) % sac_cfg.train_every == 0
            if stored := apart and update and phase != "random":
                loop = hl.store(loop, carry.model, w, act, nxt, rew, term, phase=phase, **kw)
            loop, act = hl.advance(
                loop, carry.model, w, act, nxt, rew, term, trunc, start,
                phase=phase, next_phase=phase, update=update, stored=stored, **kw,
            )  # fmt: skip
        state["loop"], state["act"] = loop, jax.block_until_ready(act)

    def copies() -> int:
        """Buffer-sized copies in the compiled update step (stored inside it)."""
        nxt, rew, term, trunc, start = envs.step(np.asarray(state["act"]))
        lowered = hl.advance.lower(
            state["loop"], carry.model, w, state["act"], nxt, rew, term, trunc, start,
            phase="train", next_phase="train", update=True, **kw,
        )  # fmt: skip
        text = lowered.compile().as_text()
        return len(re.findall(rf"= \w+\[1,{capacity}[\],][^\n]* copy\(", text))

    steps(1000, "random", False)
    return steps, state, copies


def measure(capacity: int, n: int, reps: int) -> dict:
    out = {}
    for apart in (False, True):
        steps, state, copies = setup(capacity)
        steps(4, "train", apart)  # compile
        best = float("inf")
        for _ in range(reps):
            t0 = time.perf_counter()
            steps(n, "train", apart)
            best = min(best, time.perf_counter() - t0)
        params = [np.asarray(x) for x in jax.tree.leaves(state["loop"].sac.params)]
        out[apart] = (best / n * 1e6, params)
        if not apart:
            out["copies"] = copies()
    same = all(np.array_equal(a, b) for a, b in zip(out[False][1], out[True][1], strict=True))
    mib = sum(x.nbytes for x in jax.tree.leaves(state["loop"].replay)) / 2**20
    return {"inside": out[False][0], "apart": out[True][0], "copies": out["copies"], "same": same, "mib": mib}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--capacities", type=int, nargs="+", default=[20_000, 60_000, 300_000])
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--reps", type=int, default=3)
    a = p.parse_args()
    print("hopper-fixed, the gym preset's SAC (128×128, an update every second step), one seed, train phase")
    print(f"stored apart from {hl.STORE_APART_BYTES / 2**20:.0f} MiB of buffer in a run")
    print(
        "capacity  buffer MiB  copies in one program  µs/step stored inside  µs/step stored apart  speed-up  same networks"
    )
    for cap in a.capacities:
        r = measure(cap, a.steps, a.reps)
        print(
            f"{cap:>8,}  {r['mib']:>10.1f}  {r['copies']:>21}  {r['inside']:>21,.0f}  {r['apart']:>20,.0f}"
            f"  {r['inside'] / r['apart']:>7.2f}×  {r['same']}"
        )


if __name__ == "__main__":
    main()
