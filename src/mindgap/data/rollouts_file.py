"""Rollouts files: whole episodes of learned policies, recorded to be rated by people (§4.4.2's testing phase).

The testing phase of the driving study (Table 5, Figs. 34–36) shows new participants
rollouts of each method's policy and asks for a rating from 1 to 10. A rollouts file holds
those episodes exactly as the world produced them, so the study app shows them without
rerunning anything, and every rating can be traced to a method, a seed and an episode
(``mindgap reproduce driving`` writes ``rollouts.json`` in its run folder; ``mindgap study``
serves it with ``items: {source: file, path: rollouts.json}``)::

    {
      "format": "mindgap-rollouts", "version": 1,
      "domain": {"name": "driving", "sleet": 1.0},      # what draws the episodes
      "obs_dim": 11, "act_dim": 1,
      "records": [
        {"item": "eps-s0-e0", "method": "eps", "seed": 0, "episode": 0, "return": 11.2,
         "obs": [[...], ...],         # [T + 1, obs_dim]: the start, then each step's arrival
         "act": [[3.0], ...],         # [T, act_dim]
         "mask": [true, ...]},        # [T]: False after the episode ended
        {"item": "sanity", "method": "sanity", "seed": -1, "episode": 0, "sanity": "lowest", ...}
      ]
    }

``item`` names the rating page (unique; ``[a-z0-9_-]``); ``sanity`` (optional) is a sanity rule
of the study app for that episode (``lowest``: the participant's lowest rating).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from .versioned_json import read_versioned

FORMAT = "mindgap-rollouts"
VERSION = 1
_ITEM = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")


class RolloutsFileError(ValueError):
    """A rollouts file that cannot be read; the message names the record and the key."""


def rollout_record(item: str, method: str, seed: int, episode: int, obs, act, mask, ret=None, **extra) -> dict:
    """One record from arrays ``obs [T + 1, d]``, ``act [T, k]`` (or ``[T]``), ``mask [T]`` (rounded to 5 decimals)."""
    obs, mask = np.asarray(obs, np.float64), np.asarray(mask, bool)
    act = np.asarray(act, np.float64).reshape(len(mask), -1)
    rec = {
        "item": item,
        "method": method,
        "seed": int(seed),
        "episode": int(episode),
        "obs": np.round(obs, 5).tolist(),
        "act": np.round(act, 5).tolist(),
        "mask": [bool(m) for m in mask],
    }
    if ret is not None:
        rec["return"] = float(ret)
    return {**rec, **extra}


def rollouts_document(domain: dict, records: list[dict]) -> dict:
    first = records[0] if records else {"obs": [[0.0]], "act": [[0.0]]}
    return {
        "format": FORMAT,
        "version": VERSION,
        "domain": dict(domain),
        "obs_dim": len(first["obs"][0]),
        "act_dim": len(first["act"][0]),
        "records": records,
    }


def write_rollouts(path, domain: dict, records: list[dict]) -> Path:
    from .._io import atomic_write

    path = Path(path)
    atomic_write(path, json.dumps(rollouts_document(domain, records)))
    return path


def read_rollouts(path) -> dict:
    """Read and check a rollouts file; returns the document.

    Raises:
        RolloutsFileError: a missing file, invalid JSON, another format or version, a record
            of the wrong shape, a repeated or malformed item name, a non-finite number.
    """
    path = Path(path)
    doc = read_versioned(path, FORMAT, VERSION, "rollouts file", RolloutsFileError)
    try:
        od, ad = int(doc["obs_dim"]), int(doc["act_dim"])
    except (KeyError, TypeError, ValueError):
        raise RolloutsFileError(f"{path}: obs_dim and act_dim must be integers") from None
    records = doc.get("records")
    if not isinstance(records, list) or not records:
        raise RolloutsFileError(f"{path}: records must be a non-empty list")
    seen = set()
    for i, r in enumerate(records):
        where = f"{path}, record {i}"
        if not isinstance(r, dict):
            raise RolloutsFileError(f"{where}: must be an object")
        item = r.get("item")
        if not isinstance(item, str) or not _ITEM.match(item) or item in seen:
            raise RolloutsFileError(f"{where}: item {item!r} must be a unique name of [a-z0-9_-]")
        seen.add(item)
        for key in ("method",):
            if not isinstance(r.get(key), str):
                raise RolloutsFileError(f"{where}: {key} must be text")
        mask = r.get("mask")
        if not isinstance(mask, list) or not mask or not all(isinstance(m, bool) for m in mask) or not mask[0]:
            raise RolloutsFileError(f"{where}: mask must be true/false values, the first true")
        t = len(mask)
        for key, rows, dim in (("obs", t + 1, od), ("act", t, ad)):
            v = r.get(key)
            if not isinstance(v, list) or len(v) != rows or not all(isinstance(x, list) and len(x) == dim for x in v):
                raise RolloutsFileError(f"{where}: {key} must be {rows} rows of {dim} numbers")
            if not all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for row in v for x in row
            ):
                raise RolloutsFileError(f"{where}: {key} holds a value that is not a finite number")
        if r.get("sanity") not in (None, "lowest"):
            raise RolloutsFileError(f"{where}: sanity must be lowest (or absent)")
    return doc
