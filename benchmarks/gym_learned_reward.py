"""Check: what a gym job's learned reward pays and what the person's answers carried, read from its seeds' checkpoints.

A learner trained on a learned reward with absorbing states (docs/methods/pbrl.md, "Absorbing
states") ends its episodes at once when a step alive earns less than the absorbing state it would
enter. For each seed of a finished job whose slice checkpoint is on this machine
(``ROOT/train/KEY/seed-I/checkpoint.npz``; folders under ``results/`` keep the records only) it
resumes the finished slice (nothing trains; about 25 s) and prints, over the replay buffer's 300,000
transitions, the learned reward's mean on the steps that did not end the episode (r_w at the
posterior mean, the reward SAC trained on), on the steps that ended it, and the absorbing states'
r_abs at the states ended in (worth γ r_abs / (1 − γ) on top of an ending step's reward),
the share of transitions that ended an episode in the last 50,000 (a hopper that falls at once ends
one in about seven), the correlation of r_w with the environment's reward r_H over the whole buffer
and over its last 50,000 transitions (what the final policy does: a learned reward that pays what
r_H charges shows as a negative one), and the two halves of each side's score of a step alive: for
PrefBias the learner's r_w and log f_φ (Eq. 3.5) and for the simulated person r_H and max(log T_H,
floor) (their absorbing steps score 0 and r_abs), with the spread of each of the person's two halves
over the buffer's steps and over its consecutive windows of a query segment's length (the person
scores sums over segments), and r_w's correlation with the second (which of the two the person's
answers follow, and whether r_w learned the belief's half instead of the reward's). For PrefBias also
whether its belief network learned the person's belief: the spread of Σ log f_φ over the same windows
(f_φ at the posterior mean, unfloored) and its windows' correlation with the person's Σ max(log T_H,
floor), beside the same correlation for f_ψ, the centre of its prior (what f_φ would say had the answers
taught it nothing). The seed's final greedy return is the record's.

    python benchmarks/gym_learned_reward.py --job hopper/prefbias-q200 [--root results/gym] [--seeds 0 1 2 3 4]
    python benchmarks/gym_learned_reward.py --job hopper-fixed/prefbias-q800 --root results/gym-hopper-fixed
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.algorithms import methods
from mindgap.experiments import prefbias_common as pc
from mindgap.experiments import prefbias_gym as gym
from mindgap.experiments._runfolder import partial_path
from mindgap.experiments._seed_slices import slice_dir
from mindgap.models.prefbias_nets import belief_log_prob

LAST = 50_000
"""Transitions at the end of the buffer whose ending share describes the final policies."""


def _chunked(fn, *arrays, size: int = 20_000) -> np.ndarray:
    n = arrays[0].shape[0]
    return np.concatenate([np.asarray(fn(*(a[i : i + size] for a in arrays))) for i in range(0, n, size)])


def window_sums(x: np.ndarray, length: int) -> np.ndarray:
    """``x``'s sums over consecutive windows of ``length`` steps (a query segment's), the last partial one dropped."""
    n = len(x) - len(x) % length
    return x[:n].reshape(-1, length).sum(1)


def window_spread(x: np.ndarray, length: int) -> float:
    """The standard deviation of ``x``'s sums over consecutive windows of ``length`` steps (a query segment's)."""
    return float(window_sums(x, length).std())


def seed_row(world, job: pc.Job, cfg, root: Path, seed: int) -> dict | None:
    """One seed's figures (module docstring), or None when its checkpoint is not here."""
    out = slice_dir(pc.train_dir(root, job), (seed,))
    if not (out / "checkpoint.npz").is_file():
        return None
    record = partial_path(root, job.key, seed)
    if not record.is_file():
        raise ValueError(f"seed {seed} of {job.key} has not finished (no partial record): reading it would train it")
    res = gym._train(world, job, cfg.seeds, out=out, fresh=False, progress=False, seed_ids=(seed,))
    carry = jax.tree.map(lambda x: x[0], res["carry"])
    rp = carry.loop.replay
    n = int(rp.size)
    obs, act, nxt = (np.asarray(x[:n]) for x in (rp.obs, rp.act, rp.next_obs))
    ended = np.asarray(rp.terminal[:n], bool)
    fn, params = methods.learned_reward(job.method, res["carry"])
    p = jax.tree.map(lambda x: x[0], params)
    r = _chunked(jax.jit(lambda o, a, o2: fn(p, o, a, o2)), obs, act, nxt)
    absorbing_fn = methods.get(job.method).learner(job.cfg).reward(res["carry"].model, None, None, job.cfg)[2]
    r_abs = np.asarray(absorbing_fn(p, jnp.asarray(nxt[ended]))) if absorbing_fn is not None and ended.any() else 0.0
    row = {
        "seed": seed,
        "final": float(json.loads(record.read_text())["final"][0]),
        "r_alive": float(r[~ended].mean()),
        "r_end": float(r[ended].mean()) if ended.any() else float("nan"),
        "r_abs": float(np.mean(r_abs)),
        "ended_share_last": float(ended[-LAST:].mean()),
    }
    r_h = np.asarray(rp.env_reward[:n])
    row["r_H_alive"] = float(r_h[~ended].mean())
    row["corr_r_H"] = float(np.corrcoef(r, r_h)[0, 1])
    row["corr_r_H_last"] = float(np.corrcoef(r[-LAST:], r_h[-LAST:])[0, 1])
    belief = next(iter(world.beliefs.values()))  # the person's only belief: the learned one
    floor = job.cfg.teacher.log_t_floor
    log_t = _chunked(jax.jit(lambda o, a, o2: world.env.log_prob(o, a, o2, belief)), obs, act, nxt)
    scored = np.maximum(log_t, floor)
    row["log_T_H_alive"] = float(scored[~ended].mean())
    row["sd_r_H"] = float(r_h.std())
    row["sd_log_T_H"] = float(scored.std())
    row["corr_log_T_H"] = float(np.corrcoef(r, scored)[0, 1])
    row["sd_seg_r_H"] = window_spread(r_h, job.cfg.segment)
    row["sd_seg_log_T_H"] = window_spread(scored, job.cfg.segment)
    if job.method == "prefbias":
        post = carry.model.posterior
        phi = post.belief.mean
        min_std = job.cfg.prefbias.dynamics.min_std
        log_f = _chunked(
            jax.jit(lambda o, a, o2: belief_log_prob(phi, post.norm, o, a, o2, min_std, post.log_unit)), obs, act, nxt
        )
        row["log_f_alive"] = float(log_f[~ended].mean())
        # whether f_φ moved towards the person's belief: its windows' sums against hers, beside f_ψ's (the prior's centre)
        dyn = carry.model.dynamics
        log_psi = _chunked(
            jax.jit(lambda o, a, o2: belief_log_prob(dyn.params, dyn.norm, o, a, o2, min_std, post.log_unit)),
            obs,
            act,
            nxt,
        )
        seg = job.cfg.segment
        row["sd_seg_log_f"] = window_spread(log_f, seg)
        row["corr_seg_log_f"] = window_corr(log_f, scored, seg)
        row["corr_seg_log_f_psi"] = window_corr(log_psi, scored, seg)
    return row


def window_corr(x: np.ndarray, y: np.ndarray, length: int) -> float:
    """The correlation of ``x``'s and ``y``'s sums over the same consecutive windows of ``length`` steps."""
    return float(np.corrcoef(window_sums(x, length), window_sums(y, length))[0, 1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--job", required=True, help="a learner job of the full preset, e.g. hopper/prefbias-q200")
    p.add_argument("--root", type=Path, default=Path("results/gym"))
    p.add_argument("--seeds", type=int, nargs="+", default=None)
    args = p.parse_args()
    cfg = gym.preset("full")
    name = args.job.split("/")[0]
    if name in gym.DOMAINS and name not in cfg.worlds:  # a domain outside the presets (hopper-fixed)
        cfg = replace(cfg, worlds=(name,))
    job = {j.key: j for j in gym.jobs(cfg)}.get(args.job)
    if job is None:
        sys.exit(f"gym_learned_reward: no job {args.job!r} in the full preset")
    if job.method not in ("prefbias", "pebble"):
        sys.exit(f"gym_learned_reward: {args.job} learns no reward from preferences")
    world, _ = gym.load_world(job.world, cfg)
    seeds = args.seeds if args.seeds is not None else list(range(cfg.seeds))
    cols = [
        "seed",
        "final",
        "ended_share_last",
        "corr_r_H",
        "corr_r_H_last",
        "r_alive",
        "r_end",
        "r_abs",
        "log_f_alive",
        "r_H_alive",
        "log_T_H_alive",
        "sd_r_H",
        "sd_log_T_H",
        "corr_log_T_H",
        "sd_seg_r_H",
        "sd_seg_log_T_H",
        "sd_seg_log_f",
        "corr_seg_log_f",
        "corr_seg_log_f_psi",
    ]
    print(" | ".join(cols))
    for s in seeds:
        try:
            row = seed_row(world, job, cfg, args.root, s)
        except ValueError as e:
            print(f"{s} | {e}")
            continue
        if row is None:
            print(f"{s} | no checkpoint in {slice_dir(pc.train_dir(args.root, job), (s,))}")
            continue
        print(" | ".join(f"{row[c]:.3f}" if isinstance(row.get(c), float) else str(row.get(c, "–")) for c in cols))


if __name__ == "__main__":
    main()
