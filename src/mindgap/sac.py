"""SAC on the world's own reward: the oracle every preference learner is measured against (Haarnoja et al. 2018).

Example::

    import mindgap.sac as sac
    from mindgap import load_world

    result = sac.train(load_world("nav1"), sac.fast(), seeds=2)
    print(result["final_returns"].mean(1))
"""

from __future__ import annotations

from pathlib import Path

from ._api import RunResult
from .algorithms.pbrl import PbRLConfig as Config
from .algorithms.pbrl import fast_config, method_config
from .algorithms.pbrl import train as _train
from .envs.interface import World

__all__ = ["Config", "fast", "full", "train"]


def full(**overrides) -> Config:
    """The preset of the experiments (40 000 steps, 64×64 networks), with ``overrides``."""
    return method_config("sac", **overrides)


def fast(**overrides) -> Config:
    """A seconds-long preset for tests and dry runs (its numbers mean nothing), with ``overrides``."""
    return fast_config("sac", **overrides)


def train(
    world: World,
    config: Config | None = None,
    *,
    seeds: int = 1,
    out: str | Path | None = None,
    progress: bool = True,
    fresh: bool = False,
) -> RunResult:
    """Train ``seeds`` seeds (vmapped) on ``world``'s own reward; checkpoint to and resume from ``out``."""
    return _train(world, config or full(), seeds=seeds, out=out, progress=progress, fresh=fresh)
