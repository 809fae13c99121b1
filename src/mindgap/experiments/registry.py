"""The named experiments of ``mindgap reproduce``: their modules, presets and rerun commands.

A run folder's ``config.json`` is the experiment's configuration as written by
:class:`~._runfolder.RunFolder`. :func:`preset_of` tells which preset it is (``full``,
``fast``, or ``custom`` when it is neither, up to the options the command line lets one
change) and :func:`command` the ``mindgap reproduce`` line that makes (or finishes) it.
"""

from __future__ import annotations

import importlib
import json
import shlex
from pathlib import Path

from ._runfolder import same_config, to_jsonable

MODULES = {
    "table1": "table1",
    "coffee": "coffee",
    "nav": "prefbias_nav",
    "priors": "prefbias_priors",
    "sampling": "prefbias_sampling",
    "eps": "eps_table",
    "lambda": "eps_lambda",
    "gym": "prefbias_gym",
    "driving": "driving",
}
"""Experiment name → module under :mod:`mindgap.experiments` (each has ``preset(name)``)."""

NAMES = tuple(MODULES)

# the configuration fields the command line may change without leaving the preset
_OPTIONS = {
    "table1": ("seeds", "demo_count_seeds"),
    "coffee": ("participants",),
    "driving": ("seeds", "sleet", "traffic", "sanity", "importance", "answers_by"),
    "nav": ("seeds", "worlds", "methods"),
    "gym": ("seeds", "worlds", "methods", "levels"),
}
_TERRAIN_OPTIONS = ("seeds", "worlds")


def module(name: str):
    """The module of the named experiment."""
    if name not in MODULES:
        raise ValueError(f"unknown experiment {name!r}: choose from {', '.join(NAMES)}")
    return importlib.import_module(f".{MODULES[name]}", __package__)


def configure(
    name: str,
    preset: str = "full",
    *,
    seeds: int | None = None,
    worlds: tuple[str, ...] | None = None,
    participants: int | None = None,
    methods: tuple[str, ...] | None = None,
    levels: bool | None = None,
):
    """The configuration ``mindgap reproduce NAME`` runs: the ``preset`` with the command line's options.

    ``seeds`` (table1 and the terrain experiments; table1's data-efficiency sweep keeps at most
    that many), ``worlds`` (the terrain experiments: named worlds, world files or factories),
    ``participants`` (coffee), ``methods`` (nav, gym: registered preference learners run beside PEBBLE), ``levels`` (gym: SAC's
    level runs too).
    An option the experiment does not take is refused.
    """
    from dataclasses import replace

    cfg = module(name).preset(preset)
    given = {"seeds": seeds, "worlds": worlds, "participants": participants, "methods": methods, "levels": levels}
    for option, value in given.items():
        if value is not None and option not in options(name):
            raise ValueError(f"{name} does not take {option} (it takes {', '.join(options(name))})")
    if seeds is not None:
        if seeds < 1:
            raise ValueError("seeds must be at least 1")
        cfg = replace(cfg, seeds=seeds)
        if name == "table1":
            cfg = replace(cfg, demo_count_seeds=min(cfg.demo_count_seeds, seeds))
    if worlds is not None:
        if not worlds or any(not w for w in worlds):
            raise ValueError("worlds needs at least one world")
        cfg = replace(cfg, worlds=tuple(worlds))
    if participants is not None:
        cfg = replace(cfg, participants=participants)
    if methods:
        cfg = replace(cfg, methods=tuple(methods))
    if levels is not None:
        cfg = replace(cfg, levels=bool(levels))
    return cfg


def jobs(name: str, config) -> list[tuple[str, tuple[str, ...]]]:
    """The jobs of the named experiment under ``config``, in order: ``(key, keys of the jobs it reads)``.

    Each runs alone as ``mindgap reproduce NAME --job KEY`` (``module(name).run(..., only=KEY)``)
    and writes its record; the experiment's outputs are assembled from the records after.
    """
    mod = module(name)
    if hasattr(mod, "job_keys"):
        return [(key, ()) for key in mod.job_keys(config)]
    needs = mod.job_needs(config) if hasattr(mod, "job_needs") else {}
    return [
        (job.key, tuple(job.cfg) if job.method == "shaping" else needs.get(job.key, ())) for job in mod.jobs(config)
    ]


def options(name: str) -> tuple[str, ...]:
    """The configuration fields ``mindgap reproduce NAME`` sets from its flags."""
    return _OPTIONS.get(name, _TERRAIN_OPTIONS)


def preset_of(name: str, config) -> str:
    """``full``, ``fast`` or ``custom``: which preset ``config`` (a dataclass or its JSON) is."""
    cfg = _plain(config)
    for preset in ("full", "fast"):
        if same_config(cfg, module(name).preset(preset), ignore=options(name)):
            return preset
    return "custom"


def command(name: str, config, out: str | Path) -> str:
    """The ``mindgap reproduce`` line that runs (or resumes) this configuration into ``out``.

    For a ``custom`` configuration (not reachable from the command line) it is the nearest
    preset's line and says so.
    """
    cfg = _plain(config)
    preset = preset_of(name, cfg)
    ref = _plain(module(name).preset("fast" if preset == "fast" else "full"))
    words = ["mindgap", "reproduce", name]
    if preset == "fast":
        words.append("--fast")
    if cfg.get("seeds") is not None and "seeds" in options(name) and cfg["seeds"] != ref.get("seeds"):
        words += ["--seeds", str(cfg["seeds"])]
    if name == "coffee" and cfg.get("participants") != ref.get("participants"):
        words += ["--participants", str(cfg["participants"])]
    if name == "driving" and cfg.get("sleet") != ref.get("sleet"):
        words += ["--sleet", f"{cfg['sleet']:g}"]
    if name == "driving" and cfg.get("traffic", 0) != ref.get("traffic"):
        words += ["--traffic", str(cfg.get("traffic", 0))]
    if name == "driving" and cfg.get("sanity", "expectation") != ref.get("sanity"):
        words += ["--sanity", str(cfg.get("sanity", "expectation"))]
    if name == "driving" and cfg.get("importance") != ref.get("importance"):
        words += ["--importance", ",".join(f"{v:g}" for v in cfg["importance"])]
    if name == "driving" and _answers_by(cfg) != ref.get("answers_by"):
        words += ["--answers-by", _answers_by(cfg)]
    worlds = cfg.get("worlds")
    if "worlds" in options(name) and worlds is not None and list(worlds) != list(ref.get("worlds") or []):
        if any("," in w for w in worlds):
            for w in worlds:
                words += ["--env", w]
        else:
            words += ["--worlds", ",".join(worlds)]
    for method in cfg.get("methods") or ():
        words += ["--method", method]
    if "levels" in options(name) and cfg.get("levels", True) and not ref.get("levels"):
        words.append("--levels")
    words += ["--out", str(out)]
    line = shlex.join(words)
    return line if preset != "custom" else line + "  # nearest preset: this folder's config.json differs"


def _answers_by(cfg: dict) -> str:
    """A driving run's ``answers_by``; a run from before the field answered by its states, log T_H left
    out when its teacher's ``use_belief`` was off (``--answers-by decisions`` then)."""
    if "answers_by" in cfg:
        return cfg["answers_by"]
    return "expectation" if (cfg.get("teacher") or {}).get("use_belief", True) else "decisions"


def _plain(config) -> dict:
    return json.loads(json.dumps(to_jsonable(config)))
