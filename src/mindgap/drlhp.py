"""DRLHP (Christiano et al. 2017): a reward ensemble learned from preferences, SAC as the policy optimiser.

The person compares segments through their belief (``teacher="biased"``: r_H + log T_H) or
by the true reward alone (``"true"``); people answer through the study app as a host teacher.
Example::

    import mindgap.drlhp as drlhp
    from mindgap import load_world

    result = drlhp.train(load_world("nav1"), drlhp.fast(), teacher="biased", seeds=2)
"""

from __future__ import annotations

from pathlib import Path

from ._api import RunResult
from .algorithms.pbrl import PbRLConfig as Config
from .algorithms.pbrl import fast_config, method_config
from .algorithms.pbrl import train as _train
from .envs.interface import World
from .teachers.host import HostTeacher

__all__ = ["Config", "fast", "full", "train"]


def full(**overrides) -> Config:
    """The preset of the experiments, with ``overrides``."""
    return method_config("drlhp", **overrides)


def fast(**overrides) -> Config:
    """A seconds-long preset for tests and dry runs (its numbers mean nothing), with ``overrides``."""
    return fast_config("drlhp", **overrides)


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
    """Train ``seeds`` seeds (vmapped) on ``world`` from ``teacher``'s answers; checkpoint to and resume from ``out``.

    Args:
        teacher: ``"biased"`` (belief ``belief``, default the world's first), ``"true"`` or a host teacher.
    """
    cfg = config or full()
    return _train(world, cfg, seeds=seeds, teacher=teacher, belief=belief, out=out, progress=progress, fresh=fresh)
