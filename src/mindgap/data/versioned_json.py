"""Reading a versioned JSON file format (``{"format": NAME, "version": N, ...}``) with one-line errors.

Shared by the preferences file (:mod:`mindgap.study.prefs_file`) and the rollouts file
(:mod:`mindgap.data.rollouts_file`): both refuse a missing file, invalid JSON, another format
and another version the same way, naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path


def read_versioned(path, fmt: str, version: int, kind: str, error: type[Exception]) -> dict:
    """The document in ``path`` if it is format ``fmt`` at ``version``; else ``error`` with one line.

    Args:
        kind: what the file is called in messages ("preferences file", "rollouts file").
        error: the exception class to raise (a ``ValueError`` subclass of the caller's).
    """
    path = Path(path)
    if not path.is_file():
        raise error(f"{kind} {path} does not exist")
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise error(f"{path}: not valid JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise error(f'{path}: not a {kind} (need "format": "{fmt}")')
    if doc.get("version") != version:
        raise error(f"{path}: version {doc.get('version')!r} is not supported (this mindgap reads {version})")
    return doc
