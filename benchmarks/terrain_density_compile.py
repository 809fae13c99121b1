"""Benchmark: what the terrain's exact density costs XLA to compile, as written and with one normal CDF.

``log_prob_pos`` (:mod:`mindgap.envs.terrain.dynamics`) calls ``log_ndtr`` once per axis and per
end of every cell's mass, for the block's outside, and again inside each wall rule's branch. XLA's
CPU fusion copies ``log_ndtr``'s piecewise series into every consumer at small batches, so each
call site costs compile time. The **one-CDF** variant here computes every CDF the density needs in
one ``log_ndtr`` over their concatenation, and the block's masses once for both branches — the
same formulas, written once. For each batch size this prints the compile time and the optimised
HLO's length of the density, its gradient and its Hessian in the action (the belief fit's kind of
derivative), the two forms side by side, and how many of the values differ, bit for bit, on random
transitions of two named worlds.

The suite's XLA flags are the ones to compare under (``scripts/test.sh`` sets them):

    XLA_FLAGS="--xla_backend_optimization_level=1 --xla_cpu_use_fusion_emitters=false" \\
        python benchmarks/terrain_density_compile.py [--batches 64 4096] [--worlds d1 nav2-v1]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import log_ndtr, logsumexp

from mindgap.data.stays import is_stay
from mindgap.envs.resolve import resolve_env
from mindgap.envs.terrain import dynamics as d


def _one_cdf_masses(pos, mean, sigma):
    """[9] log cell masses and [2] log P(outside the block) per axis, through one ``log_ndtr``."""
    corner = d.cell_of(pos)[::-1].astype(pos.dtype)
    cells = corner[:, None] + d.OFFSETS.T[::-1].astype(pos.dtype)  # [2, 9]: x (row 0) and y (row 1)
    lo, hi = (cells - mean[:, None]) / sigma, (cells + 1 - mean[:, None]) / sigma
    flip = lo > 0
    a, b = jnp.where(flip, -hi, lo), jnp.where(flip, -lo, hi)
    out_lo, out_hi = (corner - 1.0 - mean) / sigma, (corner + 2.0 - mean) / sigma
    z = log_ndtr(jnp.concatenate([a.ravel(), b.ravel(), out_lo, -out_hi]))
    la, lb = z[:18].reshape(2, 9), z[18:36].reshape(2, 9)
    per_axis = lb + d._log1mexp(la - lb)
    return per_axis[0] + per_axis[1], jnp.logaddexp(z[36:38], z[38:40])


def log_prob_pos_one_cdf(params, pos, action, next_pos):
    """:func:`mindgap.envs.terrain.dynamics.log_prob_pos` with every normal CDF in one call."""
    mean, sigma, stuck = d.move_model(params, pos, action)
    log_go = jnp.log1p(-stuck)
    slide = d._slides(params)
    allowed, (cells, log_t) = d.allowed_offsets(params, pos), _one_cdf_masses(pos, mean, sigma)

    def bump():
        log_out = jnp.logaddexp(log_t[0], log_t[1] + d._log1mexp(log_t[0]))
        refused = jnp.where(allowed, -jnp.inf, cells)
        return jnp.logaddexp(jnp.log(stuck), log_go + logsumexp(jnp.concatenate([log_out[None], refused])))

    log_stay = jax.lax.cond(slide, lambda: jnp.log(stuck), bump)
    z = (next_pos - mean) / sigma
    log_density = log_go - jnp.log(2 * jnp.pi * sigma**2) - 0.5 * jnp.sum(z**2)
    log_z = jax.lax.cond(
        slide, lambda: logsumexp(jnp.where(allowed, cells, -jnp.inf)), lambda: jnp.zeros((), mean.dtype)
    )
    moved = jnp.where(d.landing_allowed(params, pos, next_pos), log_density - log_z, -jnp.inf)
    same = is_stay(pos, next_pos)
    log_p = jnp.where(same, log_stay, moved)
    return jnp.where(d.trapped(params, pos), jnp.where(same, 0.0, -jnp.inf), log_p)


FORMS = {"as written": d.log_prob_pos, "one CDF": log_prob_pos_one_cdf}
DERIVATIVES = {
    "density": lambda f: f,
    "gradient": lambda f: jax.grad(f, argnums=2),
    "Hessian": lambda f: jax.hessian(f, argnums=2),
}


def _transitions(key, n, size):
    k = jax.random.split(key, 4)
    pos = jax.random.uniform(k[0], (n, 2), minval=0.0, maxval=size)
    act = jax.random.uniform(k[1], (n, 2), minval=-1.0, maxval=1.0)
    nxt = pos + 0.5 * act + 0.4 * jax.random.normal(k[2], (n, 2))
    return pos, act, jnp.where(jax.random.uniform(k[3], (n, 1)) < 0.3, pos, nxt)  # 30% stays


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[64, 4096])
    ap.add_argument("--worlds", nargs="+", default=["d1", "nav2-v1"])
    ap.add_argument("--check", type=int, default=20_000, help="random transitions per world for the bit check")
    args = ap.parse_args()
    params = resolve_env(args.worlds[0]).params
    print(f"compile time (s) and optimised HLO lines, world {args.worlds[0]}")
    print(f"{'batch':>6} {'function':<9} " + " ".join(f"{name:>20}" for name in FORMS) + "   ratio")
    for n in args.batches:
        pos, act, nxt = _transitions(jax.random.key(0), n, 7.0)
        for what, wrap in DERIVATIVES.items():
            cells = []
            for f in FORMS.values():
                prog = jax.jit(jax.vmap(wrap(f), in_axes=(None, 0, 0, 0)))
                t = time.perf_counter()
                compiled = prog.lower(params, pos, act, nxt).compile()
                cells.append((time.perf_counter() - t, compiled.as_text().count("\n")))
            row = " ".join(f"{s:8.2f} s {lines:6d} ln" for s, lines in cells)
            print(f"{n:6d} {what:<9} {row}   {cells[1][0] / cells[0][0]:.2f}")
    print("\nvalues of the one-CDF form against the density as written (bit for bit)")
    for world in args.worlds:
        params = resolve_env(world).params
        pos, act, nxt = _transitions(jax.random.key(3), args.check, 7.0)
        stays = np.asarray(jnp.all(pos == nxt, axis=1))
        for what, wrap in DERIVATIVES.items():
            a, b = (
                np.asarray(jax.jit(jax.vmap(wrap(f), in_axes=(None, 0, 0, 0)))(params, pos, act, nxt))
                for f in FORMS.values()
            )
            differ = ~((a == b) | (np.isnan(a) & np.isnan(b)))
            differ = differ.reshape(len(a), -1).any(axis=1)
            print(
                f"{world:>8} {what:<9} {differ.sum():5d} of {len(a)} transitions differ"
                f" ({(differ & stays).sum()} of them stays)"
            )


if __name__ == "__main__":
    main()
