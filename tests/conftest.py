import jax
import pytest

from mindgap._io import use_compilation_cache

# Compiled programs persist between test runs (and the CLI's runs), which keeps the suite fast.
use_compilation_cache()


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
