"""Sweep files: what a sweep runs, read from TOML and checked whole before anything runs.

A sweep file holds an optional ``[sweep]`` table (where the store goes and how the jobs run),
any number of ``[[experiment]]`` tables (a named experiment of ``mindgap reproduce`` with its
options) and any number of ``[grid]``/``[[grid]]`` tables (learners × worlds ×
hyperparameters × seeds, :mod:`~.grid`)::

    [sweep]
    out = "runs/sweeps/demo"     # default: runs/sweeps/<file name>
    backend = "local"            # or "ray"; the command line's --backend wins
    workers = 2

    [[experiment]]
    name = "table1"
    preset = "fast"

    [grid]
    methods = ["pebble", "prefbias"]
    worlds = ["nav1", "examples/point_mass.py:make_world"]
    seeds = [0, 1]               # a job per seed; an integer N vmaps N seeds in each job
    [grid.params]
    queries = [30, 60]

Every problem (an unknown key or method, a missing field, a value of the wrong kind, a world
that cannot be imported or lacks what the learners need) is a :class:`SpecError` whose one
line names the file, the key and the problem. TOML because :mod:`tomllib` is in the standard
library; the checks are written by hand so that each message can name its key.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..experiments import registry
from ..experiments.world_measures import experiment_world
from . import grid as sweep_grid
from .jobs import BACKENDS
from .parts import Part

_SWEEP_KEYS = ("out", "backend", "workers", "address", "retries", "cpus", "gpus")
_EXPERIMENT_KEYS = ("name", "preset", "label", "seeds", "worlds", "participants")
_GRID_KEYS = ("label", "methods", "worlds", "preset", "seeds", "params")
PRESETS = ("fast", "full")


class SpecError(ValueError):
    """A sweep file that cannot run: ``FILE: KEY: problem``."""


@dataclass(frozen=True)
class Sweep:
    """A checked sweep file."""

    path: Path
    out: Path
    parts: tuple[Part, ...]
    backend: str = "local"
    workers: int | None = None
    address: str | None = None
    retries: int = 2
    cpus: float = 1.0
    gpus: float = 0.0


def load(path: str | Path) -> Sweep:
    """Read and check the sweep file at ``path`` (every part's worlds imported and checked).

    Raises:
        SpecError: the first problem found, naming the file and key.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise SpecError(f"{path}: cannot read it ({e.strerror or e})") from None
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{path}: not valid TOML ({e})") from None
    return check(data, path)


def check(data: dict, path: Path) -> Sweep:
    """A :class:`Sweep` from a parsed sweep file, or the :class:`SpecError` of its first problem."""

    def fail(key: str, problem: str):
        raise SpecError(f"{path}: {key}: {problem}")

    _known(data, ("sweep", "experiment", "grid"), "", fail)
    head = data.get("sweep", {})
    if not isinstance(head, dict):
        fail("sweep", "must be a table ([sweep])")
    _known(head, _SWEEP_KEYS, "sweep.", fail)
    backend = head.get("backend", "local")
    if backend not in BACKENDS:
        fail("sweep.backend", f"unknown backend {backend!r}: choose from {', '.join(BACKENDS)}")
    workers = _int(head, "workers", "sweep.", fail, minimum=1)
    retries = _int(head, "retries", "sweep.", fail, minimum=0)
    cpus, gpus = (_number(head, k, "sweep.", fail) for k in ("cpus", "gpus"))
    address = head.get("address")
    if address is not None and not isinstance(address, str):
        fail("sweep.address", "must be a string (host:port or ray://host:port)")
    out = head.get("out", str(Path("runs") / "sweeps" / path.stem))
    if not isinstance(out, str) or not out:
        fail("sweep.out", "must be a folder name")

    parts: list[Part] = []
    experiments = data.get("experiment", [])
    if not isinstance(experiments, list):
        fail("experiment", "write each experiment as an [[experiment]] table")
    for i, entry in enumerate(experiments):
        parts.append(_experiment(entry, f"experiment[{i}]", fail))
    grids = data.get("grid", [])
    grids = [grids] if isinstance(grids, dict) else grids
    if not isinstance(grids, list):
        fail("grid", "must be a [grid] table or [[grid]] tables")
    for i, entry in enumerate(grids):
        parts.append(_grid(entry, "grid" if len(grids) == 1 else f"grid[{i}]", fail, single=len(grids) == 1))
    if not parts:
        fail("experiment", "the file names no [[experiment]] and no [grid]: nothing to run")
    labels = [p.label for p in parts]
    for label in labels:
        if labels.count(label) > 1:
            fail("label", f"two parts write into the folder {label!r}: give one of them another label")
    return Sweep(
        path=path,
        out=Path(out),
        parts=tuple(parts),
        backend=backend,
        workers=workers,
        address=address,
        retries=2 if retries is None else retries,
        cpus=1.0 if cpus is None else cpus,
        gpus=0.0 if gpus is None else gpus,
    )


def _known(table: dict, keys, prefix: str, fail) -> None:
    for k in table:
        if k not in keys:
            fail(f"{prefix}{k}", f"unknown key (known: {', '.join(keys)})")


def _int(table: dict, key: str, prefix: str, fail, minimum: int) -> int | None:
    v = table.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        fail(f"{prefix}{key}", f"must be an integer of at least {minimum}, got {v!r}")
    return v


def _number(table: dict, key: str, prefix: str, fail) -> float | None:
    v = table.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 0:
        fail(f"{prefix}{key}", f"must be a number of at least 0, got {v!r}")
    return float(v)


def _strings(table: dict, key: str, where: str, fail) -> tuple[str, ...]:
    v = table[key]
    if not isinstance(v, list) or not v or not all(isinstance(x, str) and x.strip() for x in v):
        fail(where, f"must be a non-empty list of names, got {v!r}")
    return tuple(x.strip() for x in v)


def _worlds(worlds: tuple[str, ...], where: str, who: str, fail) -> None:
    for j, spec in enumerate(worlds):
        try:
            experiment_world(spec, who)
        except Exception as e:  # any import or check failure of a user's world is the file's problem
            fail(f"{where}[{j}]", f"{spec}: {str(e).splitlines()[0] if str(e) else type(e).__name__}")


def _experiment(entry, where: str, fail) -> Part:
    if not isinstance(entry, dict):
        fail(where, "must be a table")
    _known(entry, _EXPERIMENT_KEYS, f"{where}.", fail)
    if "name" not in entry:
        fail(f"{where}.name", f"missing: which experiment ({', '.join(registry.NAMES)})")
    name = entry["name"]
    if name not in registry.NAMES:
        fail(f"{where}.name", f"unknown experiment {name!r}: choose from {', '.join(registry.NAMES)}")
    preset = entry.get("preset", "full")
    if preset not in PRESETS:
        fail(f"{where}.preset", f"unknown preset {preset!r}: choose from {', '.join(PRESETS)}")
    for key in ("seeds", "worlds", "participants"):
        if key in entry and key not in registry.options(name):
            fail(f"{where}.{key}", f"{name} does not take {key} (it takes {', '.join(registry.options(name))})")
    seeds = _int(entry, "seeds", f"{where}.", fail, minimum=1)
    participants = _int(entry, "participants", f"{where}.", fail, minimum=2)
    worlds = _strings(entry, "worlds", f"{where}.worlds", fail) if "worlds" in entry else None
    if worlds is not None:
        _worlds(worlds, f"{where}.worlds", name, fail)
    try:
        cfg = registry.configure(name, preset, seeds=seeds, worlds=worlds, participants=participants)
    except ValueError as e:
        fail(where, str(e))
    label = entry.get("label", name + ("-fast" if preset == "fast" else ""))
    if not isinstance(label, str) or not label or "/" in label or label.startswith("."):
        fail(f"{where}.label", f"must be a folder name, got {label!r}")
    return Part(name, label, cfg)


def _grid(entry, where: str, fail, single: bool) -> Part:
    if not isinstance(entry, dict):
        fail(where, "must be a table")
    _known(entry, _GRID_KEYS, f"{where}.", fail)
    for key in ("methods", "worlds"):
        if key not in entry:
            fail(f"{where}.{key}", "missing")
    methods = _strings(entry, "methods", f"{where}.methods", fail)
    for j, m in enumerate(methods):
        if m not in sweep_grid.grid_methods():
            names = ", ".join(sweep_grid.grid_methods())
            fail(f"{where}.methods[{j}]", f"unknown method {m!r}: choose from {names}")
    preset = entry.get("preset", "fast")
    if preset not in PRESETS:
        fail(f"{where}.preset", f"unknown preset {preset!r}: choose from {', '.join(PRESETS)}")
    worlds = _strings(entry, "worlds", f"{where}.worlds", fail)
    _worlds(worlds, f"{where}.worlds", "a grid sweep", fail)
    seeds, seed_values = entry.get("seeds", 1), ()
    if isinstance(seeds, list):
        if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
            fail(f"{where}.seeds", f"a list of seeds must hold integers of at least 0, got {seeds!r}")
        if len(set(seeds)) != len(seeds):
            fail(f"{where}.seeds", f"names a seed twice: {seeds!r}")
        seeds, seed_values = 1, tuple(seeds)
    elif isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        fail(f"{where}.seeds", f"must be a number of seeds (at least 1) or a list of seeds, got {seeds!r}")
    params = entry.get("params", {})
    if not isinstance(params, dict):
        fail(f"{where}.params", "must be a table of hyperparameter = [values]")
    bases = sweep_grid.base_configs(preset)
    grid_params = []
    for key, values in params.items():
        at = f"{where}.params.{key}"
        if not isinstance(values, list) or not values:
            fail(at, f"must be a non-empty list of values, got {values!r}")
        takers = [m for m in methods if sweep_grid.takes(m, bases[m], key)]
        if not takers:
            fail(at, f"not a setting of {', '.join(methods)}")
        for v in values:
            problem = _kind(_get(bases[takers[0]], key), v)
            if problem:
                fail(at, problem)
        grid_params.append((key, tuple(tuple(v) if isinstance(v, list) else v for v in values)))
    grid = sweep_grid.GridConfig(methods, worlds, preset, seeds, seed_values, tuple(grid_params))
    for m in methods:
        try:
            sweep_grid.cells(grid, m)
        except (ValueError, TypeError) as e:
            fail(f"{where}.params", f"{m}: {e}")
    label = entry.get("label", "grid" if single else where.replace("[", "-").rstrip("]"))
    if not isinstance(label, str) or not label or "/" in label or label.startswith("."):
        fail(f"{where}.label", f"must be a folder name, got {label!r}")
    return Part("grid", label, grid)


def _get(cfg, path: str):
    for name in path.split("."):
        cfg = getattr(cfg, name)
    return cfg


def _kind(default, value) -> str:
    """Why ``value`` cannot replace ``default`` (empty when it can)."""
    if dataclasses.is_dataclass(default):
        return "names a group of settings; give one of its fields (a dotted name)"
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif isinstance(default, str):
        ok = isinstance(value, str)
    elif isinstance(default, tuple):
        ok = isinstance(value, list)
    else:
        ok = default is None or not isinstance(value, dict)
    if ok:
        return ""
    return f"expected {type(default).__name__} values like {default!r}, got {value!r}"
