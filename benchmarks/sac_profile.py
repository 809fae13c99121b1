"""Benchmark: where a SAC step's time goes on the jitted loop, at given network sizes.

On terrain world d1 (batch 256, one update a step, auto α), each part timed alone in a jitted
``lax.scan`` of ``--steps`` iterations, best of 5, in microseconds per step:

* the whole training step (:func:`~mindgap.algorithms.sac_loop.run_chunk`, ``train`` phase);
* the step without its update (the ``random`` phase: act, step the world, store);
* one minibatch draw (:func:`~mindgap.data.replay.replay_sample`);
* one update on a fixed batch (:func:`~mindgap.algorithms.sac.sac_update`, its state carried, so
  nothing is hoisted out of the scan);
* the same update with the three Adam optimisers on one flat vector each (``optax.flatten``),
  and whether its result is bit-for-bit the tree optimisers';
* the sum of the parameters' magnitudes after the scanned updates, so that runs under other
  ``XLA_FLAGS`` show whether they compute the same numbers.

    python benchmarks/sac_profile.py [--sizes 64 128] [--steps 500]
"""

from __future__ import annotations

import argparse
import time

import jax
import optax

import mindgap.algorithms.sac as sac_mod
from mindgap import rng
from mindgap.algorithms.sac import SACConfig, sac_init, sac_update
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.data.replay import replay_sample
from mindgap.envs.terrain import TERRAIN_ENV, load_world


def per_step(f, *args, n: int, reps: int = 5) -> float:
    """Microseconds per scan iteration of ``f(*args)``: best of ``reps`` after a compiling call."""
    jax.block_until_ready(f(*args))
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e6


def updates(cfg: SACConfig, n: int):
    keys = jax.random.split(rng.key(2), n)
    return jax.jit(lambda s, b: jax.lax.scan(lambda s, k: (sac_update(s, b, k, cfg)[0], None), s, keys)[0])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    p.add_argument("--steps", type=int, default=500)
    args = p.parse_args()
    n, wp = args.steps, load_world("d1").params
    for h in args.sizes:
        cfg = SACConfig(hidden=(h, h))
        ls = loop_init(rng.key(0), TERRAIN_ENV, wp, cfg, 1000 + 20 * n)
        ls = run_chunk(ls, TERRAIN_ENV, wp, None, n_steps=1000, cfg=cfg, phase="random")

        def chunk(phase):
            return jax.jit(lambda s: run_chunk(s, TERRAIN_ENV, wp, None, n_steps=n, cfg=cfg, phase=phase))

        full, bare = per_step(chunk("train"), ls, n=n), per_step(chunk("random"), ls, n=n)
        keys = jax.random.split(rng.key(3), n)
        draw = jax.jit(
            lambda r: jax.lax.scan(lambda c, k: (c + replay_sample(r, k, 256).obs.sum(), None), 0.0, keys)[0]
        )
        sample = per_step(draw, ls.replay, n=n)
        batch, state = replay_sample(ls.replay, rng.key(1), 256), sac_init(rng.key(5), 2, 2, cfg)
        tree = per_step(updates(cfg, n), state, batch, n=n)
        out_tree = updates(cfg, n)(state, batch)
        original = sac_mod._optimiser
        sac_mod._optimiser = lambda c: optax.flatten(optax.adam(c.lr))
        try:
            flat_state = sac_init(rng.key(5), 2, 2, cfg)
            flat = per_step(updates(cfg, n), flat_state, batch, n=n)
            out_flat = updates(cfg, n)(flat_state, batch)
        finally:
            sac_mod._optimiser = original
        same = all(
            bool((a == b).all()) for a, b in zip(jax.tree.leaves(out_tree.params), jax.tree.leaves(out_flat.params))
        )
        checksum = sum(float(abs(x).sum()) for x in jax.tree.leaves(out_tree.params))
        print(
            f"{h}×{h}: step {full:.0f} µs ({1e6 / full:,.0f} steps/s); without the update {bare:.0f}; "
            f"a minibatch draw {sample:.0f}; the update {tree:.0f} ({tree / full:.0%} of the step); "
            f"with flat optimisers {flat:.0f} (bit-identical: {same}); Σ|θ| after the updates {checksum:.6f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
