"""Benchmark (a) and (b): one GeReL iteration with 64 Monte Carlo samples, mindgap vs NumPy.

Both run the paper's score-function iteration (Algorithm 1, lines 4–13) on the same
rated demonstrations; the NumPy reference loops over samples in Python. Prints the
time per iteration of each and their ratio, for grid sizes given on the command line
(default 7; ``--sizes 7 11 15 21`` for the scaling table).

    python benchmarks/gerel_iteration.py [--sizes 7 11 15 21] [--demos 2000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from _numpy_gerel import iteration as numpy_iteration
from mindgap import rng
from mindgap.algorithms.gerel import GeReLConfig, RatingData, init_states, make_step
from mindgap.envs.grid import move_targets
from mindgap.feedback.demos import random_demonstrations
from mindgap.models.belief import tied
from mindgap.planning.grid_task import make_grid
from mindgap.teachers.rating import RatingTeacher


def setup(size, n_demos):
    task = make_grid(size, "reversed", seed=0)
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    rated = teacher.rate(rng.key(1), random_demonstrations(rng.key(0), task.mdp, n_demos, 10))
    return task, rated, tied(move_targets(size), 4)


def time_ours(task, rated, space, estimator, repeats):
    cfg = GeReLConfig(estimator=estimator, n_samples=64, restarts=1, keep=1)
    step, init_opt = make_step(cfg)
    data = RatingData.build(task.mdp, space, rated)
    state = jax.tree_util.tree_map(lambda x: x[0], init_states(rng.key(2), 2, space, cfg, init_opt))
    f = jax.jit(step)
    key = rng.key(3)
    state, _ = jax.block_until_ready(f(state, key, data))  # compile
    t0 = time.perf_counter()
    for i in range(repeats):
        state, _ = f(state, jax.random.fold_in(key, i), data)
    jax.block_until_ready(state)
    return (time.perf_counter() - t0) / repeats


def time_numpy(task, rated, space, repeats):
    data = (
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
    state = (np.zeros(2), alpha, np.zeros(2), np.zeros_like(alpha))
    gen = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(repeats):
        state = numpy_iteration(state, gen, data)
    return (time.perf_counter() - t0) / repeats


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sizes", type=int, nargs="+", default=[7])
    p.add_argument("--demos", type=int, default=2000)
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args()
    print(
        f"one GeReL iteration, 64 Monte Carlo samples, {args.demos} rated demonstrations, tied belief, "
        f"{jax.devices()[0].platform}"
    )
    print(
        f"{'grid':>6} {'states':>7} {'numpy [s]':>10} {'ours score [s]':>15} {'ours pathwise [s]':>18} {'speed-up':>9}"
    )
    for size in args.sizes:
        task, rated, space = setup(size, args.demos)
        ours = time_ours(task, rated, space, "score", args.repeats * 4)
        path = time_ours(task, rated, space, "pathwise", args.repeats * 4)
        ref = time_numpy(task, rated, space, max(1, args.repeats if size <= 11 else 1))
        print(f"{size:>4}x{size:<1} {size * size:>7} {ref:>10.4f} {ours:>15.5f} {path:>18.5f} {ref / ours:>8.1f}x")


if __name__ == "__main__":
    main()
