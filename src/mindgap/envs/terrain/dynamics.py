"""The transition model of a terrain world and its exact density (§3.2).

One step from position ``s`` (cell ``(r, c)``) with action ``a ∈ [−1, 1]²``:

1. With probability ``stuck[terrain(s)]`` the agent does not move.
2. Otherwise it proposes ``s̃ = s + 0.5 · speed · a + σ(s) ε``, ``ε ~ N(0, I₂)``, with
   ``σ(s) = noise[terrain(s)] + pit_noise · exp(−d_pit(s) / pit_scale)``.
3. The proposal is taken if it lands in the 3×3 block of cells around ``(r, c)``, in a cell
   that is not a wall, and — for a diagonal neighbour — not through a corner closed by two
   walls. Otherwise the agent bumps and stays where it was.

The next position therefore has a mixed distribution: a point mass at ``s`` (stuck or
bumped) and a Gaussian density restricted to the allowed cells. :func:`log_prob_pos`
returns the log of that point mass when ``s' = s`` and the log density elsewhere; both
are exact, because every region involved is an axis-aligned rectangle and the noise is
isotropic, so its mass is a product of normal CDF differences (computed in log space so
that tails far below float32's range stay finite).

Written by hand: no distribution library has this wall-and-bump mixture.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.scipy.special import log_ndtr, logsumexp, ndtr

from .layout import WALL
from .params import TerrainParams

OFFSETS = jnp.array([(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)], jnp.int32)  # [9, 2] (row, col)
MAX_STEP = 0.5  # cells per axis at full speed


def cell_of(pos: jax.Array) -> jax.Array:
    """[..., 2] (x, y) → [..., 2] int32 (row, col)."""
    return jnp.floor(pos[..., ::-1]).astype(jnp.int32)


def is_wall(params: TerrainParams, row: jax.Array, col: jax.Array) -> jax.Array:
    """Wall or outside the map."""
    h, w = params.grid.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    return ~inside | (params.grid[jnp.clip(row, 0, h - 1), jnp.clip(col, 0, w - 1)] == WALL)


def terrain_at(params: TerrainParams, pos: jax.Array) -> jax.Array:
    """Terrain code of the cell holding ``pos`` (WALL outside the map)."""
    h, w = params.grid.shape
    rc = cell_of(pos)
    inside = (rc[0] >= 0) & (rc[0] < h) & (rc[1] >= 0) & (rc[1] < w)
    code = params.grid[jnp.clip(rc[0], 0, h - 1), jnp.clip(rc[1], 0, w - 1)]
    return jnp.where(inside, code, WALL)


def pit_distance(params: TerrainParams, pos: jax.Array) -> jax.Array:
    """Euclidean distance (cells) from ``pos`` to the nearest pit cell; about 1e6 without pits."""
    top_left = params.pits[:, ::-1]  # (x, y) of each pit's corner
    gap = jnp.maximum(jnp.maximum(top_left - pos, 0.0), pos - (top_left + 1.0))
    return jnp.sqrt(jnp.min(jnp.sum(gap**2, axis=-1)))


def move_model(params: TerrainParams, pos: jax.Array, action: jax.Array):
    """Mean, noise scale and stuck probability of one step (steps 1–2 above).

    Returns:
        (mean [2], sigma scalar, stuck scalar).
    """
    dyn = params.dynamics
    terr = jnp.minimum(terrain_at(params, pos), dyn.speed.shape[-1] - 1)
    a = jnp.clip(action, -1.0, 1.0)
    mean = pos + MAX_STEP * dyn.speed[terr] * a
    sigma = dyn.noise[terr] + dyn.pit_noise * jnp.exp(-pit_distance(params, pos) / dyn.pit_scale)
    return mean, sigma, dyn.stuck[terr]


def allowed_offsets(params: TerrainParams, pos: jax.Array) -> jax.Array:
    """[9] bool: may a proposal land in each cell of the 3×3 block around ``pos`` (rule 3)."""
    rc = cell_of(pos)
    tr, tc = rc[0] + OFFSETS[:, 0], rc[1] + OFFSETS[:, 1]
    diagonal = (OFFSETS[:, 0] != 0) & (OFFSETS[:, 1] != 0)
    corner_closed = is_wall(params, rc[0], tc) & is_wall(params, tr, rc[1])
    return ~is_wall(params, tr, tc) & ~(diagonal & corner_closed)


def landing_allowed(params: TerrainParams, pos: jax.Array, target: jax.Array) -> jax.Array:
    """Whether a proposal at ``target`` is taken from ``pos`` (rule 3)."""
    d = cell_of(target) - cell_of(pos)
    near = jnp.all(jnp.abs(d) <= 1)
    idx = jnp.clip(d[0] + 1, 0, 2) * 3 + jnp.clip(d[1] + 1, 0, 2)
    return near & allowed_offsets(params, pos)[idx]


def sample_next(key: jax.Array, params: TerrainParams, pos: jax.Array, action: jax.Array) -> jax.Array:
    """Draw the next position (before any termination logic)."""
    k_stuck, k_noise = jax.random.split(key)
    mean, sigma, stuck = move_model(params, pos, action)
    proposal = mean + sigma * jax.random.normal(k_noise, (2,), pos.dtype)
    move = (jax.random.uniform(k_stuck) >= stuck) & landing_allowed(params, pos, proposal)
    return jnp.where(move, proposal, pos)


def _log1mexp(x: jax.Array) -> jax.Array:
    """log(1 − eˣ) for x ≤ 0, accurate at both ends."""
    x = jnp.minimum(x, 0.0)
    return jnp.where(x > -0.6931472, jnp.log(-jnp.expm1(x)), jnp.log1p(-jnp.exp(x)))


def log_normal_mass(lo: jax.Array, hi: jax.Array) -> jax.Array:
    """log(Φ(hi) − Φ(lo)) for lo ≤ hi, stable in both tails."""
    flip = lo > 0
    a, b = jnp.where(flip, -hi, lo), jnp.where(flip, -lo, hi)
    lb = log_ndtr(b)
    return lb + _log1mexp(log_ndtr(a) - lb)


def log_bump_mass(params: TerrainParams, pos: jax.Array, mean: jax.Array, sigma: jax.Array) -> jax.Array:
    """log P(the proposal is refused) = log P(outside the 3×3 block or in a refused cell)."""
    corner = cell_of(pos)[::-1].astype(pos.dtype)  # (x, y) of the current cell's corner
    lo, hi = (corner - 1.0 - mean) / sigma, (corner + 2.0 - mean) / sigma
    log_t = jnp.logaddexp(log_ndtr(lo), log_ndtr(-hi))  # [2] per axis: outside the block
    log_out = jnp.logaddexp(log_t[0], log_t[1] + _log1mexp(log_t[0]))  # tx + ty (1 − tx)
    cell_x = corner[0] + OFFSETS[:, 1]
    cell_y = corner[1] + OFFSETS[:, 0]
    log_cell = log_normal_mass((cell_x - mean[0]) / sigma, (cell_x + 1 - mean[0]) / sigma) + log_normal_mass(
        (cell_y - mean[1]) / sigma, (cell_y + 1 - mean[1]) / sigma
    )
    refused = jnp.where(allowed_offsets(params, pos), -jnp.inf, log_cell)
    return logsumexp(jnp.concatenate([log_out[None], refused]))


def log_prob_pos(params: TerrainParams, pos: jax.Array, action: jax.Array, next_pos: jax.Array) -> jax.Array:
    """Exact log p(s' | s, a) of the mixed next-position distribution.

    Returns the log probability of the point mass when ``next_pos == pos`` (stuck or
    bumped) and the log density (per cell²) otherwise; −inf for positions the model cannot
    produce. Shapes: ``pos, action, next_pos`` [2] → scalar (vmap for batches).
    """
    mean, sigma, stuck = move_model(params, pos, action)
    log_go = jnp.log1p(-stuck)
    log_stay = jnp.logaddexp(jnp.log(stuck), log_go + log_bump_mass(params, pos, mean, sigma))
    z = (next_pos - mean) / sigma
    log_density = log_go - jnp.log(2 * jnp.pi * sigma**2) - 0.5 * jnp.sum(z**2)
    moved = jnp.where(landing_allowed(params, pos, next_pos), log_density, -jnp.inf)
    return jnp.where(jnp.all(next_pos == pos), log_stay, moved)


def subcell_probs(params: TerrainParams, pos: jax.Array, action: jax.Array, n: int):
    """Probability of landing in each of the (3n)² sub-cells of the 3×3 block around ``pos``.

    Each cell is split into n×n equal squares; the masses are exact rectangle integrals of
    the proposal density, zero in refused cells. Used to discretise a world for planning
    and to test :func:`sample_next` and :func:`log_prob_pos` against each other.

    Returns:
        (stay probability scalar, probs [3n, 3n] indexed (row, col) from the block's top-left).
    """
    mean, sigma, stuck = move_model(params, pos, action)
    corner = cell_of(pos)[::-1].astype(pos.dtype)
    edges = jnp.arange(3 * n + 1, dtype=pos.dtype) / n - 1.0
    px = jnp.diff(ndtr((corner[0] + edges - mean[0]) / sigma))
    py = jnp.diff(ndtr((corner[1] + edges - mean[1]) / sigma))
    allowed = jnp.repeat(jnp.repeat(allowed_offsets(params, pos).reshape(3, 3), n, 0), n, 1)
    probs = (1 - stuck) * jnp.where(allowed, py[:, None] * px[None, :], 0.0)
    return jnp.clip(1.0 - probs.sum(), 0.0, 1.0), probs
