"""Benchmark: one GeReL iteration with 64 Monte Carlo samples, mindgap vs NumPy, and its cost curve.

Both sides run the paper's score-function iteration (Algorithm 1, lines 4–13) on the
same 2000 rated demonstrations with a tied belief; the NumPy reference
(``_numpy_gerel.py``) loops over samples in Python and runs 100 dense Bellman sweeps
per sample. Ours runs as ``fit_gerel`` does: iterations inside one compiled chunk
(``lax.scan``), value iteration on the belief's successor form with the certified stop
(:mod:`mindgap.planning.sparse_value_iteration`).

1. Speed-up at ``--sizes`` (default 7 and 21): rounds alternate one NumPy iteration and
   one chunk of ours, so both see the same machine load; the medians are compared.
   "per call" is ours dispatched from Python one iteration at a time.
2. Cost curve at ``--curve`` sizes (default 7 to 41): ours per iteration, score and
   pathwise estimators, the mean Bellman sweeps per evaluation, and the NumPy
   reference (one iteration) up to ``--numpy-max``.

    python benchmarks/gerel_iteration.py [--sizes 7 21] [--curve 7 14 21 31 41] [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from _numpy_gerel import iteration as numpy_iteration
from mindgap import rng
from mindgap.algorithms.gerel import GeReLConfig, RatingData, init_states, make_step
from mindgap.algorithms.gerel_model import draw
from mindgap.envs.grid import move_targets
from mindgap.feedback.demos import random_demonstrations
from mindgap.models.belief import tied
from mindgap.planning.grid_task import make_grid
from mindgap.planning.sparse_value_iteration import sweeps_used
from mindgap.teachers.rating import RatingTeacher

SAMPLES = 64


def setup(size, n_demos):
    task = make_grid(size, "reversed", seed=0)
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    rated = teacher.rate(rng.key(1), random_demonstrations(rng.key(0), task.mdp, n_demos, 10))
    return task, rated, tied(move_targets(size), 4)


class Ours:
    """One restart of ``fit_gerel``'s step, compiled as a chunk of ``chunk`` iterations."""

    def __init__(self, task, rated, space, estimator, chunk):
        self.cfg = GeReLConfig(estimator=estimator, n_samples=SAMPLES, restarts=1, keep=1)
        step, init_opt = make_step(self.cfg)
        self.data = RatingData.build(task.mdp, space, rated)
        self.state = jax.tree_util.tree_map(lambda x: x[0], init_states(rng.key(2), 2, space, self.cfg, init_opt))
        self.chunk = chunk
        self.step = jax.jit(step)
        self.run = jax.jit(lambda s, keys, d: jax.lax.scan(lambda s, k: step(s, k, d), s, keys))
        self.calls = 0
        self.time_chunk()  # compile
        jax.block_until_ready(self.step(self.state, rng.key(3), self.data))

    def _keys(self):
        self.calls += 1
        return jax.random.split(jax.random.fold_in(rng.key(3), self.calls), self.chunk)

    def time_chunk(self) -> float:
        """Seconds per iteration inside one compiled chunk."""
        keys = self._keys()
        t0 = time.perf_counter()
        self.state, _ = jax.block_until_ready(self.run(self.state, keys, self.data))
        return (time.perf_counter() - t0) / self.chunk

    def time_per_call(self) -> float:
        """Seconds per iteration, one jitted call each."""
        keys = self._keys()
        t0 = time.perf_counter()
        for k in keys:
            self.state, _ = self.step(self.state, k, self.data)
        jax.block_until_ready(self.state)
        return (time.perf_counter() - t0) / self.chunk

    def mean_sweeps(self) -> float:
        """Bellman sweeps per value iteration at the current state (mean over 8 draws of 64 samples)."""
        space, mdp = self.data.space, self.data.mdp
        counts = []
        for i in range(8):
            w, log_theta = draw(rng.key(100 + i), self.state.mu, self.state.alpha, self.data, self.cfg)
            probs, successors = space.successor_form(jnp.exp(log_theta))
            counts.append(int(sweeps_used(probs, successors, mdp.reward(w), mdp.discount, self.cfg.vi_iterations)))
        return float(np.mean(counts))


class NumpyReference:
    def __init__(self, task, rated, space):
        self.data = (
            np.asarray(task.mdp.features, np.float64),
            float(task.mdp.discount),
            np.asarray(space.factor),
            np.asarray(space.targets),
            np.asarray(space.mask),
            np.asarray(rated.demos.states),
            np.asarray(rated.demos.actions),
            np.asarray(rated.ratings, np.float64),
        )
        alpha = np.full(np.asarray(space.mask).shape, 2.0)
        self.state = (np.zeros(2), alpha, np.zeros(2), np.zeros_like(alpha))
        self.gen = np.random.default_rng(0)

    def time(self) -> float:
        t0 = time.perf_counter()
        self.state = numpy_iteration(self.state, self.gen, self.data)
        return time.perf_counter() - t0


def speed_up(sizes, n_demos, rounds, chunk):
    print("\nspeed-up (score estimator, the reference's algorithm); medians over interleaved rounds")
    print(f"{'grid':>7} {'states':>7} {'numpy [s]':>10} {'ours [ms]':>10} {'ours per call [ms]':>19} {'speed-up':>9}")
    for size in sizes:
        task, rated, space = setup(size, n_demos)
        ours = Ours(task, rated, space, "score", chunk)
        ref = NumpyReference(task, rated, space)
        t_ref, t_ours, t_call = [], [], []
        for _ in range(rounds):
            t_ref.append(ref.time())
            t_ours.append(ours.time_chunk())
            t_call.append(ours.time_per_call())
        r, o, c = np.median(t_ref), np.median(t_ours), np.median(t_call)
        print(f"{size:>4}x{size:<2} {size * size:>7} {r:>10.4f} {o * 1e3:>10.2f} {c * 1e3:>19.2f} {r / o:>8.1f}x")


def cost_curve(sizes, n_demos, rounds, chunk, numpy_max):
    print("\ncost curve: ours per iteration (median of rounds), Bellman sweeps per evaluation, NumPy (one iteration)")
    print(
        f"{'grid':>7} {'states':>7} {'sweeps':>7} {'score [ms]':>11} {'pathwise [ms]':>14} {'numpy [s]':>10} {'speed-up':>9}"
    )
    for size in sizes:
        task, rated, space = setup(size, n_demos)
        row = []
        for est in ("score", "pathwise"):
            ours = Ours(task, rated, space, est, chunk)
            row.append(np.median([ours.time_chunk() for _ in range(rounds)]))
            if est == "score":
                sweeps = ours.mean_sweeps()
        ref = NumpyReference(task, rated, space).time() if size <= numpy_max else float("nan")
        ratio = f"{ref / row[0]:>8.1f}x" if np.isfinite(ref) else f"{'-':>9}"
        print(
            f"{size:>4}x{size:<2} {size * size:>7} {sweeps:>7.1f} {row[0] * 1e3:>11.2f} {row[1] * 1e3:>14.2f} "
            f"{ref:>10.3f} {ratio}"
        )


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sizes", type=int, nargs="*", default=[7, 21], help="grid sides of the speed-up table")
    p.add_argument("--curve", type=int, nargs="*", default=[7, 14, 21, 31, 41], help="grid sides of the cost curve")
    p.add_argument("--demos", type=int, default=2000)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--chunk", type=int, default=20, help="iterations per compiled chunk (and per-call round)")
    p.add_argument("--numpy-max", type=int, default=41, help="largest grid side the NumPy reference runs in the curve")
    args = p.parse_args()
    print(
        f"one GeReL iteration, {SAMPLES} Monte Carlo samples, {args.demos} rated demonstrations, tied belief; "
        f"{jax.devices()[0].platform}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}"
    )
    if args.sizes:
        speed_up(args.sizes, args.demos, args.rounds, args.chunk)
    if args.curve:
        cost_curve(args.curve, args.demos, args.rounds, args.chunk, args.numpy_max)


if __name__ == "__main__":
    main()
