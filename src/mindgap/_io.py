"""Writing files so that a crash leaves either the old file or the new one."""

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
