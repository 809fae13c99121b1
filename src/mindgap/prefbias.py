"""PrefBias (Algorithm 2): learn the person's reward and their belief about the dynamics together from preferences.

Example::

    import mindgap.prefbias as prefbias
    from mindgap import load_world

    result = prefbias.train(load_world("nav1"), prefbias.fast(), teacher="biased", seeds=2)
    posterior = result["carry"].model.posterior  # q(w) and q(φ), a leading seed axis
"""

from __future__ import annotations

from pathlib import Path

from ._api import RunResult
from .algorithms.prefbias import PrefBiasLoopConfig as Config
from .algorithms.prefbias import prefbias_config
from .algorithms.prefbias import train as _train
from .envs.interface import World
from .teachers.host import HostTeacher

__all__ = ["Config", "fast", "full", "train"]


def full(**overrides) -> Config:
    """The preset of the experiments (50 000 steps, 800 queries), with ``overrides``."""
    return prefbias_config("full", **overrides)


def fast(**overrides) -> Config:
    """A seconds-long preset for tests and dry runs (its numbers mean nothing), with ``overrides``."""
    return prefbias_config("fast", **overrides)


def train(
    world: World,
    config: Config | None = None,
    *,
    teacher: str | HostTeacher = "biased",
    belief: str | None = None,
    seeds: int = 1,
    out: str | Path | None = None,
    progress: bool = True,
    fresh: bool = False,
) -> RunResult:
    """Train ``seeds`` seeds (vmapped) on ``world``; checkpoint to and resume from ``out``.

    Args:
        teacher: ``"biased"`` (belief ``belief``, default the world's first), ``"true"`` or a host teacher.
    """
    cfg = config or full()
    return _train(world, cfg, seeds=seeds, teacher=teacher, belief=belief, out=out, progress=progress, fresh=fresh)
