import json
import os
import resource
import time

import jax
import pytest

from mindgap._io import use_compilation_cache

# Compiled programs persist between test runs (and the CLI's runs), which keeps the suite fast.
use_compilation_cache()


@pytest.fixture
def key():
    from mindgap import rng

    return rng.key(0)


def _cpu_seconds() -> float:
    """CPU seconds of this process and of its finished children (a CLI run in a subprocess, sweep workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs(request):
    """Drop each test file's compiled programs when it ends: a worker runs half the suite, and
    keeping every program in memory grew a worker past 7 GB (the persistent cache on disk still
    serves a program another file compiles again).

    With ``MINDGAP_TEST_CPU_LOG`` set, also append the file's CPU seconds (this process, XLA's
    compiler threads and finished subprocesses included) and wall seconds to that file, one JSON line a test file: what
    ``scripts/test_budget.py`` holds against the budget per file in docs/development.md."""
    cpu, wall = _cpu_seconds(), time.perf_counter()
    yield
    jax.clear_caches()
    log = os.environ.get("MINDGAP_TEST_CPU_LOG")
    if log:
        path = os.path.relpath(str(request.path), start=os.path.dirname(os.path.dirname(__file__)))
        line = {"file": path, "cpu_s": round(_cpu_seconds() - cpu, 2), "wall_s": round(time.perf_counter() - wall, 2)}
        with open(log, "a") as f:  # one short line a write: workers' lines do not interleave
            f.write(json.dumps(line) + "\n")
