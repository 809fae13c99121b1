"""Saving and restoring pytrees of arrays (training state) atomically, typed PRNG keys included."""

from __future__ import annotations

import io
from pathlib import Path

import jax
import numpy as np

from ._io import atomic_write


def _is_key(x) -> bool:
    return hasattr(x, "dtype") and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)


def save_pytree(path: Path, tree, **extra) -> None:
    """Write every leaf of ``tree`` (and ``extra`` arrays) to an ``.npz`` through a rename."""
    leaves = jax.tree.leaves(tree)
    arrays = {f"leaf{i}": np.asarray(jax.random.key_data(x) if _is_key(x) else x) for i, x in enumerate(leaves)}
    arrays.update({f"extra_{k}": np.asarray(v) for k, v in extra.items()})
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write(path, buf.getvalue())


def load_pytree(path: Path, template):
    """Read a tree saved by :func:`save_pytree` into the structure (and key types) of ``template``.

    Returns:
        (tree, extra dict).

    Raises:
        ValueError: the file does not match the template's structure.
    """
    leaves, treedef = jax.tree.flatten(template)
    with np.load(path) as f:
        stored = [k for k in f.files if k.startswith("leaf")]
        if len(stored) != len(leaves):
            raise ValueError(f"{path}: {len(stored)} arrays, the run expects {len(leaves)}; start afresh with --fresh")
        out = []
        for i, t in enumerate(leaves):
            a = f[f"leaf{i}"]
            if _is_key(t):
                out.append(jax.random.wrap_key_data(a, impl=jax.random.key_impl(t)))
            else:
                if a.shape != np.shape(t):
                    raise ValueError(f"{path}: array {i} has shape {a.shape}, expected {np.shape(t)}; use --fresh")
                out.append(jax.numpy.asarray(a, dtype=t.dtype))
        extra = {k[len("extra_") :]: f[k] for k in f.files if k.startswith("extra_")}
    return jax.tree.unflatten(treedef, out), extra
