"""The learners of mindgap as values: one :class:`Method` record per method, and one :func:`train`.

A record holds everything the layers above the engine need to run a method without knowing
its name: its config class and presets, the engine's :class:`~mindgap.algorithms.engine.Learner`
for a config, who answers it (``prepare``: the engine's teacher, run record and oracle), and how
its learned reward is read from a model. Experiments and commands hold methods as records, so a
new method is a new record (:func:`register`), not a new branch in each of them.

The registry is written here by hand: it is the project's own glue between the engine and the
layers above, which no library supplies.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

from . import eps as eps_alg
from . import pbrl
from . import prefbias as prefbias_alg
from .engine import Learner, run
from .eps_config import EPSConfig, eps_config
from .prefbias import PrefBiasLoopConfig, prefbias_config

ANSWERS = ("nothing", "preferences", "expectations")
"""What a method asks its person: nothing (it optimises the world's reward), which of two
segments is better (preferences, Ch. 3), or which is more expected (Ch. 4)."""


@dataclasses.dataclass(frozen=True)
class Method:
    """One method as a value.

    Attributes:
        name: the name its configs carry (``cfg.method`` where the config has several) and the
            command line uses.
        label: how tables and legends name it.
        config: its config class (a :class:`~mindgap.algorithms.engine.Schedule`).
        preset: ``(preset, **overrides) → config``; ``preset`` is ``full`` or ``fast``.
        learner: ``config → Learner``.
        prepare: ``(world, cfg, seeds, **who) → (teacher, run record, oracle)`` for
            :func:`~mindgap.algorithms.engine.run`; ``who`` names the person (``teacher=``,
            ``belief=`` for preferences; ``person=``, ``person_name=`` for expectations).
        learned_reward: ``model → (reward_fn, params)``, the reward the method learned, or None
            when it learns none.
        answers: one of :data:`ANSWERS`.
        tag: the value of its configs' ``method`` field (default: ``name``), what the engine's
            run record and progress bar call it.
    """

    name: str
    label: str
    config: type
    preset: Callable
    learner: Callable[[object], Learner]
    prepare: Callable
    learned_reward: Callable | None
    answers: str
    tag: str = ""

    @property
    def learns_reward_from_preferences(self) -> bool:
        """Whether it learns a reward from preference answers (what an experiment's learners beside
        PEBBLE, and a plan on a learned reward, need)."""
        return self.answers == "preferences" and self.learned_reward is not None

    def __post_init__(self):
        if self.answers not in ANSWERS:
            raise ValueError(f"{self.name}: answers must be one of {', '.join(ANSWERS)}, got {self.answers!r}")
        if not self.tag:
            object.__setattr__(self, "tag", self.name)


METHODS: dict[str, Method] = {}
"""Every registered method by name."""


def register(method: Method) -> Method:
    """Add ``method`` to :data:`METHODS` (a name already taken is refused) and return it."""
    if method.name in METHODS and METHODS[method.name] != method:
        raise ValueError(f"a method named {method.name!r} is already registered")
    METHODS[method.name] = method
    return method


def get(method: str | Method) -> Method:
    """The record of ``method`` (a name or a record)."""
    if isinstance(method, Method):
        return method
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}: choose from {', '.join(METHODS)}")
    return METHODS[method]


def for_config(cfg) -> Method:
    """The record that runs ``cfg``: the one whose config class and tag it has."""
    for m in METHODS.values():
        if isinstance(cfg, m.config) and m.tag == cfg.method:
            return m
    raise ValueError(f"no method runs a {type(cfg).__name__} of method {cfg.method!r}")


def train(
    method: str | Method,
    world,
    cfg,
    seeds: int = 1,
    *,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
    seed_ids: tuple[int, ...] | None = None,
    **who,
) -> dict:
    """Run ``seeds`` seeds of ``method`` on ``world`` with ``cfg``; checkpoint to ``out``.

    ``who`` names the person (see :attr:`Method.prepare`); ``seed_ids`` trains only those of the
    ``seeds`` seeds, each as it trains in the whole run (a seed slice). Returns the dict of
    :func:`~mindgap.algorithms.engine.run`.
    """
    m = get(method)
    if not isinstance(cfg, m.config):
        raise ValueError(f"{m.name} takes a {m.config.__name__}, got a {type(cfg).__name__}")
    if cfg.method != m.tag:
        raise ValueError(f"{m.name} runs configs of method {m.tag!r}, got one of {cfg.method!r}")
    cfg.check()
    teacher, meta, oracle = m.prepare(world, cfg, seeds, **who)
    kw = dict(out=out, progress=progress, fresh=fresh, oracle=oracle, seed_ids=seed_ids)
    return run(world, m.learner(cfg), cfg, teacher, meta, seeds, **kw)


def learned_reward(method: str | Method, carry):
    """``(reward_fn, params)`` of the reward a run of ``method`` learned (leading seed axis on
    ``params``), read from its final ``carry``; None for a method that learns no reward."""
    m = get(method)
    return None if m.learned_reward is None else m.learned_reward(carry.model)


def _pbrl_preset(name: str):
    def preset(preset: str = "full", **overrides):
        if preset not in ("full", "fast"):
            raise ValueError(f"unknown preset {preset!r}: choose from full, fast")
        return (pbrl.fast_config if preset == "fast" else pbrl.method_config)(name, **overrides)

    return preset


def _eps_preset(name: str):
    def preset(preset: str = "full", **overrides):
        return eps_config(preset, **{"method": name, **overrides})

    return preset


SAC = register(
    Method(
        "sac", "SAC (oracle)", pbrl.PbRLConfig, _pbrl_preset("sac"), lambda cfg: pbrl.ORACLE_LEARNER,
        pbrl.prepare, None, "nothing",
    )
)  # fmt: skip
PEBBLE = register(
    Method(
        "pebble", "PEBBLE", pbrl.PbRLConfig, _pbrl_preset("pebble"), lambda cfg: pbrl.REWARD_LEARNER,
        pbrl.prepare, pbrl.learned_reward, "preferences",
    )
)  # fmt: skip
DRLHP = register(
    Method(
        "drlhp", "DRLHP", pbrl.PbRLConfig, _pbrl_preset("drlhp"), lambda cfg: pbrl.REWARD_LEARNER,
        pbrl.prepare, pbrl.learned_reward, "preferences",
    )
)  # fmt: skip
PREFBIAS = register(
    Method(
        "prefbias", "PrefBias", PrefBiasLoopConfig, prefbias_config, lambda cfg: prefbias_alg.LEARNER,
        prefbias_alg.prepare, prefbias_alg.learned_reward, "preferences",
    )
)  # fmt: skip
EPS = register(
    Method(
        "eps", "EPS", EPSConfig, _eps_preset("eps"), lambda cfg: eps_alg.EPS_LEARNER,
        eps_alg.prepare, eps_alg.learned_reward, "expectations",
    )
)  # fmt: skip
EXPECTATION_DRLHP = register(
    Method(
        "drlhp-expectations", "DRLHP (expectations)", EPSConfig, _eps_preset("drlhp"),
        lambda cfg: eps_alg.DRLHP_LEARNER, eps_alg.prepare, eps_alg.learned_reward, "expectations", tag="drlhp",
    )
)  # fmt: skip
