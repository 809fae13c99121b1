"""Benchmark: the learner commands' derived flags (:mod:`mindgap.commands.config_flags`) against tyro.

Side by side in one process, on PEBBLE's full config with three flags (a float, a nested tuple, an int):
the time of the first parse (the builder reads the config classes' field docstrings once; tyro is
imported first, its import timed apart) and of a parse after it, the best of ``--repeats``. Both
must give the same config. tyro is not a dependency: ``pip install tyro`` to compare.

    python benchmarks/config_flags.py [--repeats 20]
"""

from __future__ import annotations

import argparse
import time

from mindgap.algorithms import methods
from mindgap.algorithms.pbrl import PbRLConfig
from mindgap.commands.config_flags import add_config_flags, with_flags

ARGV = ["--sac.lr", "0.001", "--reward.hidden", "32,32", "--queries", "400"]
TYRO_ARGV = ["--sac.lr", "0.001", "--reward.hidden", "32", "32", "--queries", "400"]


def ours(cfg):
    p = argparse.ArgumentParser()
    add_config_flags(p, cfg, skip=("method",))
    return with_flags(cfg, p.parse_args(ARGV))


def timed(fn, repeats: int):
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return out, first, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args()
    cfg = methods.PEBBLE.preset("full")
    mine, first, best = timed(lambda: ours(cfg), args.repeats)
    print(f"{'':24s}{'import':>10s}{'first parse':>14s}{'a parse':>10s}")
    print(f"{'mindgap config_flags':24s}{'–':>10s}{1e3 * first:12.1f}ms{1e3 * best:8.2f}ms")
    try:
        t0 = time.perf_counter()
        import tyro
    except ImportError:
        print("tyro: not installed (pip install tyro)")
        return
    imported = time.perf_counter() - t0
    theirs, t_first, t_best = timed(lambda: tyro.cli(PbRLConfig, args=TYRO_ARGV, default=cfg), args.repeats)
    print(f"{'tyro ' + tyro.__version__:24s}{1e3 * imported:8.1f}ms{1e3 * t_first:12.1f}ms{1e3 * t_best:8.2f}ms")
    print(f"ratio (tyro / ours), a parse: {t_best / best:.1f}x; same config: {mine == theirs}")


if __name__ == "__main__":
    main()
