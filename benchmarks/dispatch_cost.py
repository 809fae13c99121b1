"""Benchmark: what one SAC update costs as its own dispatch against inside a scan, and with its state packed.

The host loop (:mod:`~mindgap.algorithms.host_loop`) runs each update as its own compiled call;
the jitted loop runs many in one ``lax.scan``. This times one SAC update (``sac_update`` on a fixed
minibatch of 256 drawn once, the SAC of ``host_loop_profile.py``: batch 256, Pendulum-v1's shapes)
three ways, per update, best of ``--reps`` runs of ``--steps`` updates, at each network size:

* **scanned**: ``--steps`` updates in one ``lax.scan`` (one call);
* **dispatched**: one call per update, its state (49 arrays: three networks, three Adam states, α)
  donated;
* **packed**: the same, but the state handed over as one float32 and one int32 array, sliced back
  into its arrays inside the program and concatenated again at its end (exact: the updates are
  bit-identical, which it checks);
* **callback**: the scan again, each iteration also stepping a real ``Pendulum-v1`` on the host
  through ``jax.experimental.io_callback`` (ordered) with the actor's mean action, and its next
  observation fed back into the carry: what a host loop that runs the env from inside one program
  would pay a step instead of a call.

It also checks whether the scanned updates end in the same state, bit for bit, as the dispatched
ones (``scan = dispatch``): whether a loop could move from one form to the other without changing
a run.

The difference between the first two is the price of a call, paid once a step by the host loop.
To see where a call's time goes, record the process with ``perf record -p PID`` while it runs the
dispatched case (``--only dispatched --steps 5000``): docs/benchmarks.md has what that showed.

    python benchmarks/dispatch_cost.py [--sizes 64 128 256] [--steps 300] [--reps 3] [--only CASE]
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from host_loop_profile import best_of
from mindgap import rng
from mindgap.algorithms.sac import SACConfig, sac_init, sac_update
from mindgap.data.batch import Batch

CASES = ("scanned", "dispatched", "packed", "callback")


def packer(tree):
    """``pack(tree) → {dtype: flat array}`` and ``unpack`` back, for trees shaped like ``tree`` (exact)."""
    leaves, treedef = jax.tree.flatten(tree)
    spec = [(str(x.dtype), x.shape) for x in leaves]
    dtypes = sorted({d for d, _ in spec})

    def pack(t):
        xs = jax.tree.leaves(t)
        return {d: jnp.concatenate([x.reshape(-1) for x in xs if str(x.dtype) == d]) for d in dtypes}

    def unpack(bufs):
        at, out = dict.fromkeys(dtypes, 0), []
        for d, shape in spec:
            n = int(np.prod(shape))
            out.append(bufs[d][at[d] : at[d] + n].reshape(shape))
            at[d] += n
        return jax.tree.unflatten(treedef, out)

    return pack, unpack


def _with_callback(state, batch: Batch, keys, cfg: SACConfig, reps: int) -> float:
    """Seconds for ``len(keys)`` scanned updates, each iteration stepping a host Pendulum-v1 (module docstring)."""
    import gymnasium as gym
    from jax.experimental import io_callback

    from mindgap.models.mlp import mlp

    env = gym.make("Pendulum-v1")
    env.reset(seed=0)
    shape = jax.ShapeDtypeStruct((batch.obs.shape[1] + 1,), jnp.float32)

    def host_step(action):
        obs, reward, terminated, truncated, _ = env.step(np.asarray(action))
        if terminated or truncated:
            obs, _ = env.reset()
        return np.concatenate([obs, [reward]]).astype(np.float32)

    def body(carry, kk):
        s, obs = carry
        action = jnp.tanh(mlp(s.params.actor, obs[None])[0, : batch.act.shape[1]])
        out = io_callback(host_step, shape, action, ordered=True)
        s = sac_update(s, batch, kk, cfg)[0]
        return (s, out[:-1]), None

    run = jax.jit(lambda s, o: jax.lax.scan(body, (s, o), keys)[0])
    obs0 = jnp.zeros(batch.obs.shape[1], jnp.float32)
    jax.block_until_ready(run(state, obs0))
    return best_of(lambda: jax.block_until_ready(run(state, obs0)), reps)


def measure(hidden: int, steps: int, reps: int, only: str | None) -> dict:
    """Microseconds per update of each case (module docstring) at ``hidden`` × ``hidden``."""
    cfg = SACConfig(hidden=(hidden, hidden), batch_size=256)
    obs_dim, act_dim = 3, 1  # Pendulum-v1
    state = sac_init(rng.key(0), obs_dim, act_dim, cfg)
    k = jax.random.split(rng.key(1), 4)
    n = cfg.batch_size
    batch = Batch(
        jax.random.normal(k[0], (n, obs_dim)),
        jnp.tanh(jax.random.normal(k[1], (n, act_dim))),
        jax.random.normal(k[2], (n,)),
        jax.random.normal(k[3], (n, obs_dim)),
        jnp.zeros(n),
    )
    keys = jax.random.split(rng.key(2), steps)
    listed = list(keys)
    out = {}
    if only in (None, "scanned"):
        scan = jax.jit(lambda s: jax.lax.scan(lambda c, kk: (sac_update(c, batch, kk, cfg)[0], None), s, keys)[0])
        jax.block_until_ready(scan(state))
        out["scanned"] = best_of(lambda: jax.block_until_ready(scan(state)), reps)
    one = jax.jit(lambda s, kk: sac_update(s, batch, kk, cfg)[0], donate_argnums=0)
    pack, unpack = packer(state)
    packed = jax.jit(lambda p, kk: pack(sac_update(unpack(p), batch, kk, cfg)[0]), donate_argnums=0)
    for name, fn, start in (
        ("dispatched", one, lambda: jax.tree.map(jnp.array, state)),
        ("packed", packed, lambda: jax.jit(pack)(state)),
    ):
        if only not in (None, name):
            continue
        held = {"s": start()}

        def run(fn=fn, held=held):
            for kk in listed:
                held["s"] = fn(held["s"], kk)
            jax.block_until_ready(held["s"])

        run()
        out[name] = best_of(run, reps)
    if only in (None, "callback"):
        out["callback"] = _with_callback(state, batch, keys, cfg, reps)
    if only is None:
        held = jax.tree.map(jnp.array, state)
        for kk in listed:
            held = one(held, kk)
        scanned = jax.jit(lambda s: jax.lax.scan(lambda c, kk: (sac_update(c, batch, kk, cfg)[0], None), s, keys)[0])
        out["scan_identical"] = all(
            bool((x == y).all()) for x, y in zip(jax.tree.leaves(held), jax.tree.leaves(scanned(state)))
        )
        a = one(jax.tree.map(jnp.array, state), listed[0])
        b = unpack(packed(jax.jit(pack)(state), listed[0]))
        out["identical"] = all(bool((x == y).all()) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))
    return {k: (v / steps * 1e6 if isinstance(v, float) else v) for k, v in out.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--only", choices=CASES, help="time one case only (to record it with perf)")
    args = p.parse_args()
    print(f"one SAC update (batch 256, Pendulum-v1's shapes), µs per update, best of {args.reps} × {args.steps}")
    for h in args.sizes:
        t = measure(h, args.steps, args.reps, args.only)
        parts = [f"{c} {t[c]:.0f}" for c in CASES if c in t]
        extra = ""
        if "scanned" in t and "dispatched" in t:
            extra = f"; a call costs {t['dispatched'] - t['scanned']:.0f}"
        if "callback" in t and "scanned" in t:
            extra += f"; a host step from inside the scan costs {t['callback'] - t['scanned']:.0f}"
        if "identical" in t:
            extra += f"; packed bit-identical: {t['identical']}; scan = dispatch: {t['scan_identical']}"
        print(f"{h}×{h}: " + ", ".join(parts) + extra, flush=True)


if __name__ == "__main__":
    main()
