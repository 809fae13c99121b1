"""Where the default suite's compile time goes: a pytest plugin, and the summary of what it logged.

As a plugin (``PYTHONPATH=scripts pytest -p compile_profile …`` with ``MINDGAP_COMPILE_LOG=FILE``)
it listens to JAX's monitoring events (tracing, lowering to MLIR, XLA's compilation, each with the
function's name) and appends one JSON line per test to ``FILE``: the test's id and, per function,
the seconds of each stage and how many programs it compiled. A cache hit costs
no compile event, so a cold cache (``MINDGAP_JAX_CACHE=$(mktemp -d)``) shows what compiling costs.

As a script (``python scripts/compile_profile.py FILE [--top N]``) it prints the functions that
cost the most compile seconds (with how many distinct programs and which test files compiled
them) and the tests that cost the most: which programs to share between tests, and which tests
compile programs no other test needs. A program's seconds land on the first test that compiles
it: a later test of the same file (or, through the disk cache, of another) that shares it shows
nothing, so what removing a test saves is its file's time measured cold without it.

No library records compile time per test; this is the few lines that join JAX's own events to
pytest's hooks.
"""

from __future__ import annotations

import argparse
import collections
import json
import os

STAGES = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "compile",
}

_current: dict = {"funs": None}


def _listen(event: str, seconds: float, **kw) -> None:
    stage, funs = STAGES.get(event), _current["funs"]
    if stage is None or funs is None:
        return
    name = str(kw.get("fun_name", "?"))
    name = name[4:-1] if name.startswith("jit(") else name  # tracing names the function bare, the rest as jit(f)
    row = funs[name]
    row[stage] += seconds
    row["programs"] += stage == "compile"


def pytest_configure(config) -> None:
    import jax

    jax.monitoring.register_event_duration_secs_listener(_listen)


def pytest_runtest_logstart(nodeid, location):
    _current["funs"] = collections.defaultdict(lambda: {"trace": 0.0, "lower": 0.0, "compile": 0.0, "programs": 0})


def pytest_runtest_logfinish(nodeid, location):
    log, funs = os.environ.get("MINDGAP_COMPILE_LOG"), _current["funs"]
    if not log or funs is None:
        return
    line = {"test": nodeid, "funs": {k: {s: round(v, 4) for s, v in r.items()} for k, r in funs.items()}}
    with open(log, "a") as f:
        f.write(json.dumps(line) + "\n")
    _current["funs"] = None


def _seconds(r: dict) -> float:
    return r["trace"] + r["lower"] + r["compile"]


def summary(path: str, top: int) -> None:
    """Print the costliest functions and tests of the log at ``path``."""
    per_fun = collections.defaultdict(
        lambda: {"trace": 0.0, "lower": 0.0, "compile": 0.0, "programs": 0, "files": set()}
    )
    per_test = []
    for raw in open(path):
        rec = json.loads(raw)
        spent = 0.0
        for name, r in rec["funs"].items():
            row = per_fun[name]
            for s in ("trace", "lower", "compile", "programs"):
                row[s] += r[s]
            row["files"].add(rec["test"].split("::")[0])
            spent += _seconds(r)
        per_test.append((spent, rec["test"]))
    total = sum(_seconds(r) for r in per_fun.values())
    print(f"{path}: {len(per_test)} tests, {total:.0f} s tracing + lowering + compiling in all")
    print(f"\nfunctions by their seconds (trace + lower + compile), top {top}:")
    rows = sorted(per_fun.items(), key=lambda kv: -_seconds(kv[1]))
    for name, r in rows[:top]:
        s = _seconds(r)
        print(f"{s:8.1f} s  {r['programs']:5d} programs  {len(r['files']):3d} files  {name}")
    print(f"\ntests by their seconds, top {top}:")
    for s, test in sorted(per_test, reverse=True)[:top]:
        print(f"{s:8.1f} s  {test}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("log")
    p.add_argument("--top", type=int, default=30)
    args = p.parse_args()
    summary(args.log, args.top)


if __name__ == "__main__":
    main()
