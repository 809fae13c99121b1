"""Preferences files: recorded comparisons of segment pairs, enough to learn a reward offline.

A JSON document (``preferences.json``; what ``mindgap study export`` writes and
``mindgap pebble|drlhp --preferences FILE`` reads)::

    {
      "format": "mindgap-preferences", "version": 1,
      "protocol": "preference",                     # or "expectation"
      "domain": {"name": "terrain", "world": "nav1"},
      "segment": 10, "obs_dim": 2, "act_dim": 2,
      "records": [
        {"participant": "p-03", "item": "pair-04", "answer": "a", "label": 1.0, "seconds": 4.1,
         "a": {"obs": [[x, y], ...], "act": [[ax, ay], ...], "next_obs": [[x, y], ...], "mask": [true, ...]},
         "b": {...}}
      ]
    }

Each segment holds ``segment`` steps: ``obs``, ``next_obs`` ``[L, obs_dim]`` (terrain:
the position scaled to [−1, 1]², :func:`~mindgap.envs.terrain.observe`), ``act``
``[L, act_dim]`` and ``mask [L]`` (False after an episode ended). ``label`` is the
Bradley–Terry target of Eq. 3.1: 1 when ``a`` was chosen, 0 for ``b``, 0.5 for "can't
tell" (B-Pref's "equal"); ``answer`` says the same in words. Only ``a``, ``b`` and
``label`` are required; other keys are kept for the record.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..data.versioned_json import read_versioned

FORMAT = "mindgap-preferences"
VERSION = 1
ANSWERS = {"a": 1.0, "b": 0.0, "equal": 0.5}


class PreferencesFileError(ValueError):
    """A preferences file that cannot be read; the message names the record and the problem."""


@dataclasses.dataclass(frozen=True)
class Preferences:
    """A read preferences file: header fields and the checked records."""

    protocol: str
    domain: dict
    segment: int
    obs_dim: int
    act_dim: int
    records: list[dict]

    def arrays(self):
        """(seg_a, seg_b, labels): dicts of ``obs, act, next_obs [N, L, ·]``, ``mask [N, L]``; labels [N]."""

        def stack(side):
            return {
                k: np.asarray([r[side][k] for r in self.records], bool if k == "mask" else np.float32)
                for k in ("obs", "act", "next_obs", "mask")
            }

        return stack("a"), stack("b"), np.asarray([r["label"] for r in self.records], np.float32)


def preferences_document(protocol: str, domain: dict, records: list[dict]) -> dict:
    """The JSON document of a preferences file (dimensions read off the first record)."""
    first = records[0]["a"] if records else {"obs": [[0.0, 0.0]], "act": [[0.0, 0.0]]}
    return {
        "format": FORMAT,
        "version": VERSION,
        "protocol": protocol,
        "domain": domain,
        "segment": len(first["obs"]),
        "obs_dim": len(first["obs"][0]),
        "act_dim": len(first["act"][0]),
        "records": records,
    }


def read_preferences(path, *, require_labels: bool = True) -> Preferences:
    """Read and check a preferences file.

    Raises:
        PreferencesFileError: a missing file, invalid JSON, another format or version,
            a segment of the wrong shape, a non-finite number, a label that is not 0,
            0.5 or 1 — naming the record.
    """
    path = Path(path)
    doc = read_versioned(path, FORMAT, VERSION, "preferences file", PreferencesFileError)
    try:
        length, od, ad = int(doc["segment"]), int(doc["obs_dim"]), int(doc["act_dim"])
    except (KeyError, TypeError, ValueError):
        raise PreferencesFileError(f"{path}: segment, obs_dim and act_dim must be integers") from None
    records = doc.get("records")
    if not isinstance(records, list):
        raise PreferencesFileError(f"{path}: records must be a list")
    for i, r in enumerate(records):
        where = f"{path}, record {i}"
        if not isinstance(r, dict):
            raise PreferencesFileError(f"{where}: must be an object with a, b and label")
        for side in ("a", "b"):
            _check_segment(r.get(side), f"{where}, segment {side}", length, od, ad)
        if require_labels or "label" in r:
            label = r.get("label")
            if label not in (0, 0.5, 1) or isinstance(label, bool):
                raise PreferencesFileError(f"{where}: label {label!r} must be 1 (a), 0 (b) or 0.5 (can't tell)")
    if require_labels and not records:
        raise PreferencesFileError(f"{path}: no records")
    return Preferences(str(doc.get("protocol", "preference")), dict(doc.get("domain") or {}), length, od, ad, records)


def _check_segment(seg, where: str, length: int, od: int, ad: int) -> None:
    if not isinstance(seg, dict):
        raise PreferencesFileError(f"{where}: missing (need obs, act, next_obs, mask)")
    for key, dim in (("obs", od), ("act", ad), ("next_obs", od)):
        rows = seg.get(key)
        if (
            not isinstance(rows, list)
            or len(rows) != length
            or not all(isinstance(row, list) and len(row) == dim for row in rows)
        ):
            raise PreferencesFileError(f"{where}: {key} must be {length} rows of {dim} numbers")
        if not all(
            isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for row in rows for x in row
        ):
            raise PreferencesFileError(f"{where}: {key} holds a value that is not a finite number")
    mask = seg.get("mask")
    if not isinstance(mask, list) or len(mask) != length or not all(isinstance(m, bool) for m in mask):
        raise PreferencesFileError(f"{where}: mask must be {length} true/false values")
    if not mask[0]:
        raise PreferencesFileError(f"{where}: the first step must be a real step (mask[0] true)")
