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
