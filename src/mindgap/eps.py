"""EPS (Algorithm 3): reconcile the task's reward with what a person expects the agent to do.

The person says which of two segments is *more expected*; by default a simulated person with
the world's belief and an expected policy π_H trained once in it (cached). Example::

    import mindgap.eps as eps
    from mindgap import load_world

    world = load_world("d3")
    result = eps.train(world, eps.fast(), person=eps.person(world, fast=True), seeds=2)
"""

from __future__ import annotations

from pathlib import Path

from ._api import RunResult
from .algorithms.eps import train as _train
from .algorithms.eps_config import EPSConfig as Config
from .algorithms.eps_config import eps_config
from .algorithms.expected_policy import ExpectedPolicyConfig, expectation_teacher
from .algorithms.explicability import explicability_scores as explicability_scores
from .envs.interface import World
from .teachers.expectation import ExpectationTeacher
from .teachers.host import HostTeacher

__all__ = ["Config", "explicability_scores", "fast", "full", "person", "train"]


def full(**overrides) -> Config:
    """The preset of the experiments (60 000 steps, λ = 2), with ``overrides``."""
    return eps_config("full", **overrides)


def fast(**overrides) -> Config:
    """A seconds-long preset for tests and dry runs (its numbers mean nothing), with ``overrides``."""
    return eps_config("fast", **overrides)


def person(
    world: World, belief: str | None = None, *, unbiased: bool = False, fast: bool = False, cache_dir=None
) -> ExpectationTeacher:
    """The simulated person of ``world``: belief ``belief`` (or the true dynamics), π_H from the cache or trained."""
    cfg = ExpectedPolicyConfig.fast() if fast else ExpectedPolicyConfig()
    return expectation_teacher(world, belief, unbiased=unbiased, policy_cfg=cfg, cache_dir=cache_dir)


def train(
    world: World,
    config: Config | None = None,
    *,
    person: ExpectationTeacher | HostTeacher,
    seeds: int = 1,
    out: str | Path | None = None,
    progress: bool = True,
    fresh: bool = False,
) -> RunResult:
    """Train ``seeds`` seeds (vmapped) on ``world`` from ``person``'s expectation answers; checkpoint to ``out``."""
    return _train(world, config or full(), person, seeds=seeds, out=out, progress=progress, fresh=fresh)
