"""Imports inside ``mindgap`` go down its layers, never up.

The top-level modules and subpackages of ``mindgap`` sit in layers, lowest first:

0. ``data``, ``rng``, ``_io``, ``checkpoint``
1. ``models``, ``envs``, ``feedback`` (``models`` and ``envs`` do not import each other)
2. ``teachers``, ``planning``, ``plotting``
3. ``metrics``, ``algorithms``, ``design``
4. ``experiments``, ``study``; the public method modules ``sac``, ``pebble``, ``drlhp``,
   ``prefbias``, ``eps`` and their shared ``_api``
5. ``sweeps`` (many experiments' jobs on workers or Ray)
6. ``commands``
7. ``cli``

A module may import only from its own layer or a lower one; imports inside functions
count too. The package's own ``__init__`` re-exports from every layer and is not checked.
Within a layer, no two packages import each other (a cycle, even through other packages of
the layer, is an order the layers do not state). Separately, no two modules of
``mindgap.experiments`` import each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "mindgap"

# The layers described in this module's docstring.
RANK = {
    "data": 0,
    "rng": 0,
    "_io": 0,
    "checkpoint": 0,
    "models": 1,
    "envs": 1,
    "feedback": 1,
    "teachers": 2,
    "planning": 2,
    "plotting": 2,
    "metrics": 3,
    "algorithms": 3,
    "design": 3,
    "experiments": 4,
    "study": 4,
    "_api": 4,
    "sac": 4,
    "pebble": 4,
    "drlhp": 4,
    "prefbias": 4,
    "eps": 4,
    "sweeps": 5,
    "commands": 6,
    "cli": 7,
}


def _modules(root: Path) -> dict[str, Path]:
    """Dotted module name of every ``.py`` file under the package directory ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imported(module: str, path: Path) -> set[str]:
    """Dotted names a module imports, relative imports resolved (``from a import b`` gives ``a.b``)."""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            if node.module:
                base = base + node.module.split(".")
            names.update(".".join(base + [alias.name]) for alias in node.names)
    return names


def _layer(name: str) -> str | None:
    """The layer key of a dotted name inside ``mindgap``, None for anything else."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "mindgap" else None


def _layer_imports(root: Path):
    """``(module, its layer, the layer it imports)`` for every import between layered packages under ``root``."""
    for module, path in _modules(root).items():
        me = _layer(module)
        if me not in RANK:
            continue
        for name in _imported(module, path):
            other = _layer(name)
            if other in RANK:
                yield module, me, other


def upward_imports(root: Path) -> list[str]:
    """``"module (layer -> higher layer)"`` for each import under ``root`` that goes up a layer."""
    bad = {
        f"{module} ({me} -> {other})"
        for module, me, other in _layer_imports(root)
        if RANK[other] > RANK[me] or {me, other} == {"models", "envs"}
    }
    return sorted(bad)


def package_cycles(root: Path) -> list[str]:
    """``"a -> b -> … -> a"`` for each cycle among the top-level packages of ``root`` (one per set of
    packages that reach each other), imports inside functions included."""
    edges: dict[str, set[str]] = {}
    for _, me, other in _layer_imports(root):
        if other != me:
            edges.setdefault(me, set()).add(other)

    def path_back(start: str, node: str, seen: tuple) -> tuple | None:
        for nxt in sorted(edges.get(node, ())):
            if nxt == start:
                return (*seen, start)
            if nxt not in seen:
                found = path_back(start, nxt, (*seen, nxt))
                if found:
                    return found
        return None

    cycles = {}
    for start in sorted(edges):
        found = path_back(start, start, (start,))
        if found and frozenset(found) not in cycles:
            cycles[frozenset(found)] = " -> ".join(found)
    return sorted(cycles.values())


def mutual_imports(root: Path, package: str) -> list[str]:
    """``"a <-> b"`` for each pair of modules in ``package`` that import each other directly."""
    modules = _modules(root)
    inside = [m for m in modules if m.startswith(package + ".")]
    edges = {}
    for module in inside:
        targets = set()
        for name in _imported(module, modules[module]):
            parts = name.split(".")
            # The longest prefix that is a module: "pkg.mod.func" is "pkg.mod".
            found = next((".".join(parts[:k]) for k in range(len(parts), 0, -1) if ".".join(parts[:k]) in inside), None)
            if found is not None and found != module:
                targets.add(found)
        edges[module] = targets
    return sorted(f"{a} <-> {b}" for a in edges for b in edges[a] if a < b and a in edges.get(b, ()))


def test_no_module_imports_from_a_higher_layer():
    assert upward_imports(SRC) == []


def test_no_two_packages_import_each_other():
    assert package_cycles(SRC) == []


def test_the_checks_catch_an_upward_import_and_a_cycle(tmp_path):
    """A planted package: ``teachers`` importing ``algorithms`` (a floor up), ``envs`` and ``feedback``
    importing each other (one floor), ``planning`` importing ``teachers`` and back (one floor)."""
    pkg = tmp_path / "mindgap"
    files = {
        "teachers/a.py": "from ..algorithms import engine\nfrom ..planning import b\n",
        "algorithms/engine.py": "",
        "planning/b.py": "def f():\n    from ..teachers import a\n",
        "envs/c.py": "from ..feedback.d import x\n",
        "feedback/d.py": "from ..envs import c\nx = 1\n",
    }
    for name, text in files.items():
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (pkg / name).write_text(text)
    assert upward_imports(pkg) == ["mindgap.teachers.a (teachers -> algorithms)"]
    assert package_cycles(pkg) == ["envs -> feedback -> envs", "planning -> teachers -> planning"]


def test_every_top_level_module_has_a_layer():
    tops = {
        p.stem if p.is_file() else p.name for p in SRC.iterdir() if p.suffix == ".py" or (p / "__init__.py").is_file()
    }
    assert sorted(tops - {"__init__"} - set(RANK)) == []


def test_experiment_modules_do_not_import_each_other_back():
    assert mutual_imports(SRC, "mindgap.experiments") == []


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / "mindgap" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root / "mindgap"


def test_the_walker_reports_exactly_the_upward_import(tmp_path):
    root = _write(
        tmp_path,
        {
            "envs/good.py": "from ..data import batch\nfrom . import tabular\nimport mindgap.rng\n",
            "envs/bad.py": "import numpy\n\n\ndef f():\n    from .. import planning\n\n    return planning\n",
        },
    )
    assert upward_imports(root) == ["mindgap.envs.bad (envs -> planning)"]


def test_the_walker_reports_models_and_envs_importing_each_other(tmp_path):
    root = _write(tmp_path, {"models/m.py": "from mindgap.envs.grid import move_targets\n"})
    assert upward_imports(root) == ["mindgap.models.m (models -> envs)"]


def test_mutual_imports_are_found(tmp_path):
    root = _write(
        tmp_path,
        {
            "experiments/__init__.py": "",
            "experiments/a.py": "from .b import run\n",
            "experiments/b.py": "def run():\n    from . import a\n",
            "experiments/c.py": "from .a import x\n",
        },
    )
    assert mutual_imports(root, "mindgap.experiments") == ["mindgap.experiments.a <-> mindgap.experiments.b"]
