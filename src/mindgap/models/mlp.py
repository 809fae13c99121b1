"""Multi-layer perceptrons as plain pytrees.

Parameters are a tuple of ``(w, b)`` layers, so stacking them along a leading axis gives
twin critics or reward ensembles that ``jax.vmap`` evaluates in one call, and seeds vmap
the same way. Written by hand because it is a few lines; a module library would add a
layer of objects between the learners and ``jax.vmap`` without adding anything they need.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp

Params = tuple[tuple[jax.Array, jax.Array], ...]


def init_mlp(key: jax.Array, sizes: Sequence[int]) -> Params:
    """LeCun-uniform weights and zero biases for layer widths ``sizes`` (input first, output last)."""
    keys = jax.random.split(key, len(sizes) - 1)
    layers = []
    for k, n_in, n_out in zip(keys, sizes[:-1], sizes[1:]):
        bound = jnp.sqrt(3.0 / n_in)
        layers.append((jax.random.uniform(k, (n_in, n_out), minval=-bound, maxval=bound), jnp.zeros(n_out)))
    return tuple(layers)


def init_stack(key: jax.Array, n: int, sizes: Sequence[int]) -> Params:
    """``n`` independently initialised MLPs stacked along a leading axis."""
    return jax.vmap(lambda k: init_mlp(k, sizes))(jax.random.split(key, n))


def mlp(params: Params, x: jax.Array, activation: Callable = jax.nn.relu) -> jax.Array:
    """Apply the MLP to ``x [..., in]`` → ``[..., out]`` (no activation on the last layer)."""
    for w, b in params[:-1]:
        x = activation(x @ w + b)
    w, b = params[-1]
    return x @ w + b


def mlp_flops(sizes: Sequence[int], batch: int) -> int:
    """Floating-point operations of one forward pass (2 per multiply-add)."""
    return 2 * batch * sum(a * b for a, b in zip(sizes[:-1], sizes[1:]))
