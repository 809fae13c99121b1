"""Short hashes of pytrees (a world with its beliefs, a simulated person, a configuration's arrays).

Run folders record the hash of what they were made with and refuse to resume with anything
else; caches (the expected policy π_H) key their files by it.
"""

from __future__ import annotations

import hashlib

import jax
import numpy as np

LATE_FIELDS = ("slide", "state_form", "fixed_horizon", "distance")
"""Fields added to a world's params after run folders and caches already existed (the terrain
worlds' wall rule, reward form and fixed horizon). A leaf of one of these names that holds 0, the default, is left out of the
hash, so a world that does not use the field keeps the fingerprint it had before the field."""


def identity_leaves(tree) -> list:
    """The array leaves of ``tree`` that identify it: every leaf in ``jax.tree.leaves`` order, except
    a :data:`LATE_FIELDS` attribute that holds 0."""
    leaves = []
    for path, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]:
        last = path[-1] if path else None
        late = isinstance(last, jax.tree_util.GetAttrKey) and last.name in LATE_FIELDS
        if late and not np.any(np.asarray(leaf)):
            continue
        leaves.append(leaf)
    return leaves


def fingerprint(tree) -> str:
    """16 hex digits of the SHA-256 of the identifying leaves' bytes."""
    h = hashlib.sha256()
    for leaf in identity_leaves(tree):
        h.update(np.asarray(leaf).tobytes())
    return h.hexdigest()[:16]
