"""The transition model of a terrain world and its exact density (§3.2).

One step from position ``s`` (cell ``(r, c)``) with action ``a ∈ [−1, 1]²``:

1. With probability ``stuck[terrain(s)]`` the agent does not move.
2. Otherwise it proposes ``s̃ = s + 0.5 · speed · a + σ(s) ε``, ``ε ~ N(0, I₂)``, with
   ``σ(s) = noise[terrain(s)] + pit_noise · exp(−d_pit(s) / pit_scale)``.
3. The proposal is taken if it lands in the 3×3 block of cells around ``(r, c)``, in a cell
   that is not a wall, and — for a diagonal neighbour — not through a corner closed by two
   walls. Otherwise, by the table's wall rule (``Dynamics.slide``):

   * ``walls = "bump"`` (default): the agent bumps and stays where it was.
   * ``walls = "slide"``: the proposal is drawn again from the Gaussian *truncated to the
     allowed cells*. A push into a wall then ends at the wall's face and keeps its motion
     along it (the truncated Gaussian's mass sits within about σ²/d of the face when its
     mean is d inside the wall), so a diagonal push into a wall no longer freezes the agent.

The next position therefore has a mixed distribution: a point mass at ``s`` (stuck, or
bumped under the bump rule) and a Gaussian density restricted to the allowed cells —
renormalised by the allowed mass under the slide rule. :func:`log_prob_pos` returns the
log of that point mass when ``s' = s`` and the log density elsewhere; both are exact,
because every region involved is an axis-aligned rectangle and the noise is isotropic, so
its mass is a product of normal CDF differences (computed in log space so that tails far
below float32's range stay finite).

Written by hand: no distribution library has this wall-and-bump mixture.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.scipy.special import log_ndtr, logsumexp, ndtr

from ...data.stays import is_stay
from .layout import PIT, WALL
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
    k_stuck, k_noise = jax.random.split(key)  # as before the slide rule: bump worlds draw the same
    mean, sigma, stuck = move_model(params, pos, action)
    proposal = mean + sigma * jax.random.normal(k_noise, (2,), pos.dtype)
    taken = landing_allowed(params, pos, proposal)
    # a real branch where the world is not batched, so bump worlds never pay for the redraw
    redraw = jax.lax.cond(
        _slides(params),
        lambda: _sample_allowed(jax.random.fold_in(k_noise, 1), params, pos, mean, sigma),
        lambda: proposal,
    )
    proposal = jnp.where(taken, proposal, redraw)
    move = (jax.random.uniform(k_stuck) >= stuck) & (taken | _slides(params))
    return jnp.where(move, proposal, pos)


def _sample_allowed(key: jax.Array, params: TerrainParams, pos: jax.Array, mean: jax.Array, sigma: jax.Array):
    """A draw of the proposal truncated to the allowed cells: a cell by its mass, then each
    axis from the normal truncated to that cell (the slide rule's redraw)."""
    k_cell, k_x, k_y = jax.random.split(key, 3)
    off = OFFSETS[jax.random.categorical(k_cell, _log_allowed_cells(params, pos, mean, sigma))]
    lo = cell_of(pos)[::-1].astype(pos.dtype) + off[::-1].astype(pos.dtype)  # (x, y) corner of that cell
    z = jnp.stack(
        [
            _truncated_normal(k, (lo[i] - mean[i]) / sigma, (lo[i] + 1 - mean[i]) / sigma)
            for i, k in enumerate((k_x, k_y))
        ]
    )
    # keep the draw inside its cell where float32 rounding would put it on the far edge
    return jnp.clip(mean + sigma * z, lo, jnp.nextafter(lo + 1, lo))


def _truncated_normal(key: jax.Array, a: jax.Array, b: jax.Array) -> jax.Array:
    """A standard normal draw truncated to ``[a, b]``, exact far into the tails.

    ``jax.random.truncated_normal`` inverts the CDF in linear space and, in float32, returns
    the wrong edge once both bounds lie beyond about 5σ on the same side — which is where
    the slide rule needs it (a mean inside a wall, far from the face). Here an interval on
    one side of 0 is mirrored to the right and the log survival function
    ``log S(x) = log Φ(−x)`` is inverted by Newton's method from ``x = a``; an interval
    around 0 has no such tail and goes to JAX's sampler.
    """
    k_u, k_mid = jax.random.split(key)
    flip = a + b < 0
    lo, hi = jnp.where(flip, -b, a), jnp.where(flip, -a, b)
    lo_pos = jnp.maximum(lo, 0.0)
    log_sa, log_sb = log_ndtr(-lo_pos), log_ndtr(-jnp.maximum(hi, lo_pos))
    u = jax.random.uniform(k_u, (), lo.dtype)
    target = log_sa + jnp.log1p(-u * -jnp.expm1(log_sb - log_sa))  # log S(x) at the draw

    def newton(_, x):
        g = log_ndtr(-x)
        log_pdf = -0.5 * x * x - 0.5 * jnp.log(2 * jnp.pi)
        return jnp.clip(x + (g - target) * jnp.exp(g - log_pdf), lo_pos, hi)

    tail = jax.lax.fori_loop(0, 40, newton, lo_pos)
    mid = jax.random.truncated_normal(k_mid, a, b, (), a.dtype)
    return jnp.where(lo >= 0, jnp.where(flip, -tail, tail), mid)


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


def log_cell_masses(pos: jax.Array, mean: jax.Array, sigma: jax.Array) -> jax.Array:
    """[9] log of the proposal's mass in each cell of the 3×3 block around ``pos`` (order of :data:`OFFSETS`)."""
    corner = cell_of(pos)[::-1].astype(pos.dtype)  # (x, y) of the current cell's corner
    cell_x = corner[0] + OFFSETS[:, 1]
    cell_y = corner[1] + OFFSETS[:, 0]
    return log_normal_mass((cell_x - mean[0]) / sigma, (cell_x + 1 - mean[0]) / sigma) + log_normal_mass(
        (cell_y - mean[1]) / sigma, (cell_y + 1 - mean[1]) / sigma
    )


def _log_allowed_cells(params: TerrainParams, pos: jax.Array, mean: jax.Array, sigma: jax.Array) -> jax.Array:
    """[9] :func:`log_cell_masses`, −inf in the refused cells."""
    return jnp.where(allowed_offsets(params, pos), log_cell_masses(pos, mean, sigma), -jnp.inf)


def log_allowed_mass(params: TerrainParams, pos: jax.Array, mean: jax.Array, sigma: jax.Array) -> jax.Array:
    """log P(the proposal is taken) = log of its mass in the allowed cells (rule 3).

    Never −inf in practice: the current cell is always allowed, and in log space its mass
    stays finite however far the mean lies from it.
    """
    return logsumexp(_log_allowed_cells(params, pos, mean, sigma))


def log_bump_mass(params: TerrainParams, pos: jax.Array, mean: jax.Array, sigma: jax.Array) -> jax.Array:
    """log P(the proposal is refused) = log P(outside the 3×3 block or in a refused cell)."""
    corner = cell_of(pos)[::-1].astype(pos.dtype)  # (x, y) of the current cell's corner
    lo, hi = (corner - 1.0 - mean) / sigma, (corner + 2.0 - mean) / sigma
    log_t = jnp.logaddexp(log_ndtr(lo), log_ndtr(-hi))  # [2] per axis: outside the block
    log_out = jnp.logaddexp(log_t[0], log_t[1] + _log1mexp(log_t[0]))  # tx + ty (1 − tx)
    refused = jnp.where(allowed_offsets(params, pos), -jnp.inf, log_cell_masses(pos, mean, sigma))
    return logsumexp(jnp.concatenate([log_out[None], refused]))


def _slides(params: TerrainParams) -> jax.Array:
    return params.dynamics.slide > 0.5


def log_prob_pos(params: TerrainParams, pos: jax.Array, action: jax.Array, next_pos: jax.Array) -> jax.Array:
    """Exact log p(s' | s, a) of the mixed next-position distribution.

    Returns the log probability of the point mass when ``next_pos`` is ``pos`` (stuck or
    bumped; up to float rounding, :func:`~mindgap.data.stays.is_stay`: positions read back from
    observations may differ in the last bit) and the log density (per cell²) otherwise; −inf for positions the model cannot
    produce. Shapes: ``pos, action, next_pos`` [2] → scalar (vmap for batches).
    """
    mean, sigma, stuck = move_model(params, pos, action)
    log_go = jnp.log1p(-stuck)
    slide = _slides(params)
    log_stay = jax.lax.cond(  # a bump adds the refused mass to the stay only under the bump rule
        slide,
        lambda: jnp.log(stuck),
        lambda: jnp.logaddexp(jnp.log(stuck), log_go + log_bump_mass(params, pos, mean, sigma)),
    )
    z = (next_pos - mean) / sigma
    log_density = log_go - jnp.log(2 * jnp.pi * sigma**2) - 0.5 * jnp.sum(z**2)
    log_z = jax.lax.cond(slide, lambda: log_allowed_mass(params, pos, mean, sigma), lambda: jnp.zeros((), mean.dtype))
    log_density = log_density - log_z
    moved = jnp.where(landing_allowed(params, pos, next_pos), log_density, -jnp.inf)
    same = is_stay(pos, next_pos)
    log_p = jnp.where(same, log_stay, moved)
    stays = jnp.where(same, 0.0, -jnp.inf)
    return jnp.where(trapped(params, pos), stays, log_p)


def trapped(params: TerrainParams, pos: jax.Array) -> jax.Array:
    """Whether ``pos`` is in a pit of a fixed-horizon world (``params.fixed_horizon``): it cannot move."""
    return (params.fixed_horizon > 0.5) & (terrain_at(params, pos) == PIT)


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
    allowed = jnp.repeat(jnp.repeat(allowed_offsets(params, pos).reshape(3, 3), n, 0), n, 1)
    zx, zy = (corner[0] + edges - mean[0]) / sigma, (corner[1] + edges - mean[1]) / sigma
    # bump rule: the plain rectangle masses, the refused rest joins the stay mass
    px, py = jnp.diff(ndtr(zx)), jnp.diff(ndtr(zy))
    bump = jnp.where(allowed, py[:, None] * px[None, :], 0.0)
    # slide rule: the same masses renormalised over the allowed sub-cells, in log space
    # (the mean may sit so deep in a wall that every allowed mass underflows float32)
    log_px, log_py = log_normal_mass(zx[:-1], zx[1:]), log_normal_mass(zy[:-1], zy[1:])
    log_sub = jnp.where(allowed, log_py[:, None] + log_px[None, :], -jnp.inf)
    slid = jnp.exp(log_sub - logsumexp(log_sub))
    probs = (1 - stuck) * jnp.where(_slides(params), slid, bump)
    probs = jnp.where(trapped(params, pos), 0.0, probs)
    return jnp.clip(1.0 - probs.sum(), 0.0, 1.0), probs
