"""Whether a transition is a stay: the next state equal to the state up to float rounding.

The terrain worlds (and any world with a stuck or bumped step) put a point mass at s' = s, and
the stay heads of f_ψ and f_φ (:mod:`~mindgap.models.gaussian_dynamics`) score such a step by
its probability instead of a density. A stay must be recognised from *observations*, and two
observations of one state need not be bitwise equal: the training loop computes ``observe(s_t)``
and ``observe(s_{t+1})`` in two places of one compiled program, which XLA may round differently
(on nav1's loop, 2,674 of 7,563 queried steps were stays whose observations differed in the last
bit: read as moves of 10⁻⁷, they were scored by the Gaussian's density at a zero displacement,
and f_φ could not hold the person's stay probability on them). A real move is many orders of
magnitude larger (the terrain worlds' noise is 0.05 cells, 0.007 observation units), so a
relative tolerance of a few float32 ulps separates the two without touching either.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

STAY_RTOL = 1e-6
"""Relative tolerance of :func:`is_stay`: about eight float32 ulps (ε = 1.19·10⁻⁷)."""


def is_stay(x: jax.Array, next_x: jax.Array) -> jax.Array:
    """``next_x`` equals ``x`` in every coordinate up to :data:`STAY_RTOL` relative (of ``max(|x|, 1)``):
    [..., d] → [...] bool."""
    scale = jnp.maximum(jnp.abs(x), 1.0)
    return jnp.all(jnp.abs(next_x - x) <= STAY_RTOL * scale, axis=-1)
