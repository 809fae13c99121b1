"""Files: writing them so that a crash leaves either the old file or the new one, and the caches
on disk (trained-once artefacts, compiled XLA programs)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def atomic_write(path: Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
        f.write(data)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 would hide results from other readers
    os.replace(tmp, path)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def cache_root(cache_dir: str | Path | None = None) -> Path:
    """Where trained-once artefacts are cached: ``cache_dir``, else ``$MINDGAP_CACHE``, else ``~/.cache/mindgap``."""
    if cache_dir is not None:
        return Path(cache_dir)
    return Path(os.environ.get("MINDGAP_CACHE", Path.home() / ".cache" / "mindgap")).expanduser()


def compilation_cache_dir() -> str:
    """The persistent XLA cache: ``$MINDGAP_JAX_CACHE``, else ``~/.cache/mindgap/jax`` (empty: none)."""
    return os.environ.get("MINDGAP_JAX_CACHE", str(Path.home() / ".cache" / "mindgap" / "jax"))


def use_compilation_cache(path: str | None = None) -> None:
    """Keep every compiled XLA program on disk in ``path`` (default :func:`compilation_cache_dir`;
    empty: leave JAX's configuration alone), so a rerun loads what it compiled before.

    Every program is kept, not only those that took long to compile: a run makes hundreds of
    small ones (one per eager operation and shape, about 20 ms of compiling each on the CPU
    against a millisecond or two to load), and a threshold (JAX's default keeps only programs
    that took 1 s to compile) recompiles them all on every run (docs/development.md). The cache
    has no size cap: JAX's cap
    (``jax_compilation_cache_max_size``) rescans the whole folder on every write, which made the
    test suite's thousands of small programs slower than compiling them; delete the folder to
    reclaim its space.
    """
    import jax

    path = compilation_cache_dir() if path is None else path
    if path:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
