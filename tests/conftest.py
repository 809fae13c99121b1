import os

import jax
import pytest

# Compiled programs persist between test runs (and the CLI's runs), which keeps the suite fast.
_cache = os.environ.get("MINDGAP_JAX_CACHE", os.path.expanduser("~/.cache/mindgap/jax"))
if _cache:
    jax.config.update("jax_compilation_cache_dir", _cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


@pytest.fixture
def key():
    from mindgap import rng

    return rng.key(0)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop each test file's compiled programs when it ends: a worker runs half the suite, and
    keeping every program in memory grew a worker past 7 GB (the persistent cache on disk still
    serves a program another file compiles again)."""
    yield
    jax.clear_caches()
