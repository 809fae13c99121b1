"""What a preference learner's reward asks for: ``mindgap design reward-plan --run DIR --job KEY``.

A learner's greedy policy misses the better route for one of two reasons: its learned reward
r̂ ranks the routes wrongly, or its policy did not find the optimum of a reward that ranks them
rightly. On a terrain world the sub-cell MDP tells them apart
(:mod:`~mindgap.planning.reward_plan`). For each seed of a finished job, from the job's
checkpoint in ``DIR/train``:

1. the table r̂(s, a) of every sub-cell centre and compass action (r̂ read as a function of
   the state and action, as the reward error reads it, :func:`~mindgap.experiments.world_measures.reward_grid`),
   and, for a learner with absorbing states, r_abs / (1 − γ) in the terminal sub-cells;
2. **r̂'s own optimum**: value iteration on that table under the true dynamics with the
   learner's discount γ, rolled out in the continuous world — its true return, goal and pit
   rates and route;
3. **what r̂ says of the world's two reference routes**: the discounted value under r̂, from the
   start distribution, of the optimal plan (value iteration on the true reward) and of the
   person's expected plan (value iteration under the belief) — whether r̂ ranks them as the
   truth does;
4. r̂ and the true expected reward by terrain (goal, pit, ice, sand, floor): each z-scored over
   the sub-cells outside the pits and averaged over the compass actions — where r̂ puts each
   terrain against the truth, up to the offset and scale that preferences leave free;
5. beside them, the learned policy's own final return and route from the job's record.

If r̂'s own optimum takes the better route, a miss is the policy's; if r̂ ranks the expected
route above the optimal one, the miss is the reward's (docs/experiments/identifiability.md,
"nav2: what the learned reward asks for").
"""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..algorithms import methods
from ..envs.terrain.dynamics import terrain_at
from ..envs.terrain.layout import PIT, TERRAINS
from ..envs.terrain.params import TerrainState
from ..envs.terrain.world import observe
from ..planning import terrain as pt
from ..planning.finite_horizon import start_distribution
from ..planning.reward_plan import plan_rewards, policy_values
from . import prefbias_common as pc
from . import registry
from ._runfolder import record_path
from .world_measures import experiment_world, has_map, route_of

ROLLOUTS = 20
"""Rollouts of r̂'s optimal plan per seed in the continuous world."""


def _run_job(root: Path, key: str):
    """The experiment's job ``key`` of the run folder ``root``, with the run's seeds and its record."""
    progress = root / "progress.json"
    if not progress.is_file():
        raise ValueError(f"{root} is not a run folder of mindgap reproduce (no progress.json)")
    name = json.loads(progress.read_text())["experiment"]
    stored = json.loads((root / "config.json").read_text())
    preset = registry.preset_of(name, stored)
    if preset == "custom":
        raise ValueError(f"{root}: a custom configuration of {name}; reward-plan reads full and fast runs only")
    taken = registry.options(name)
    if "worlds" not in taken:
        raise ValueError(f"{name} is not a terrain experiment: reward-plan reads nav, priors and sampling runs")
    # the options the command line set (seeds, worlds, and nav's or gym's added learners), as the run has them
    given = {
        o: tuple(v) if isinstance(v, list) else v
        for o in ("seeds", "worlds", "methods")
        if o in taken and (v := stored.get(o))
    }
    cfg = registry.configure(name, preset, **given)
    jobs = {j.key: j for j in registry.module(name).jobs(cfg)}
    if key not in jobs:
        raise ValueError(f"{name} has no job {key!r}: its jobs are named like {', '.join(list(jobs)[:6])}, …")
    job = jobs[key]
    record_file = record_path(root, key)
    if not record_file.is_file():
        raise ValueError(f"{key} has not finished in {root} (no record in jobs/)")
    return name, cfg, job, json.loads(record_file.read_text())


def reward_plan(root: Path, key: str, rollouts: int = ROLLOUTS) -> dict:
    """Per seed of the finished job ``key`` of the run folder ``root``: r̂'s own optimum, r̂'s
    values of the optimal and the expected plan, and the learned policy's result (module doc).

    Raises:
        ValueError: not a terrain experiment's preference learner, not finished, or its
            checkpoint is gone (run folders under ``results/`` keep records only).
    """
    root = Path(root)
    name, cfg, job, record = _run_job(root, key)
    method = methods.get(job.method)
    if not method.learns_reward_from_preferences:
        raise ValueError(
            f"{key}: {job.method} learns no reward from preferences; reward-plan reads PrefBias and PEBBLE jobs"
        )
    world = experiment_world(job.world, "reward-plan")
    if not has_map(world):
        raise ValueError(f"{job.world} has no map to plan on: reward-plan needs a terrain world")
    out = pc.train_dir(root, job)
    if not (out / "checkpoint.npz").is_file():
        raise ValueError(
            f"no checkpoint of {key} in {out} (folders under results/ keep the records only): "
            f"rerun the job into a folder of your own, mindgap reproduce {name} --out DIR --job {key}"
        )
    res = methods.train(
        job.method, world, job.cfg, seeds=cfg.seeds, out=out, progress=False, teacher=pc.teacher_of(job)
    )
    fn, params = methods.learned_reward(job.method, res["carry"])
    # the absorbing states' reward function (None without): PrefBias's and PEBBLE's Learners read neither world nor env for it
    absorbing_fn = method.learner(job.cfg).reward(res["carry"].model, None, None, job.cfg)[2]
    gamma = float(job.cfg.sac.gamma)

    d = pt.discretise(world.params, 4)
    n_states, n_actions = d.rewards.shape
    state = TerrainState(d.positions, jnp.zeros(n_states, jnp.int32), jnp.zeros(n_states, bool))
    obs = observe(state, world.params)
    obs_k = jnp.repeat(obs, n_actions, 0)
    act_k = jnp.tile(d.actions, (n_states, 1))
    start = np.asarray(start_distribution(d, world.params))
    optimal, expected = pt.plan(world.params, 4, gamma), pt.plan(world.belief(), 4, gamma)
    terrain = np.asarray(jax.vmap(lambda q: terrain_at(world.params, q))(d.positions))
    truth = np.asarray(d.rewards).mean(-1)

    seeds = []
    for s in range(cfg.seeds):
        p = jax.tree.map(lambda x, s=s: x[s], params)
        table = fn(p, obs_k, act_k, obs_k).reshape(n_states, n_actions)
        terminal = absorbing_fn(p, obs) / (1.0 - gamma) if absorbing_fn is not None else None
        own = plan_rewards(d, table, terminal, gamma)
        value = {
            "own": float(start @ np.asarray(own.q.max(-1))),
            "optimal": float(start @ np.asarray(policy_values(d, table, optimal.policy, terminal, gamma))),
            "expected": float(start @ np.asarray(policy_values(d, table, expected.policy, terminal, gamma))),
        }
        pos, rew, alive = pt.rollouts(rng.key(s), world.params, pt.plan_action, rollouts, own)
        stats = pt.route_stats(world.params, pos, rew, alive)
        paths = [np.asarray(pos[i])[: int(np.asarray(alive[i]).sum()) + 1] for i in range(rollouts)]
        route = route_of(world, paths)
        seeds.append(
            {
                "seed": s,
                "by_terrain": by_terrain(np.asarray(table).mean(-1), truth, terrain),
                "plan": {
                    "return": stats.ret,
                    "goal": stats.success,
                    "pit": stats.fell,
                    "ice": stats.ice,
                    "sand": stats.sand,
                    "pit_mean": route["pit_mean"],
                },
                "value": value,
                "ranks_optimal_first": value["optimal"] > value["expected"],
                "policy": {
                    "final": record["final"][s],
                    "goal": record["routes"][s]["goal"],
                    "better": record["routes"][s]["better"],
                },
            }
        )
    plan_truth = pt.route_stats(world.params, *pt.rollouts(rng.key(0), world.params, pt.plan_action, rollouts, optimal))
    plan_belief = pt.route_stats(
        world.params, *pt.rollouts(rng.key(0), world.params, pt.plan_action, rollouts, expected)
    )
    return {
        "run": str(root),
        "job": key,
        "world": job.world,
        "method": job.method,
        "gamma": gamma,
        "optimal_plan": plan_truth._asdict(),
        "expected_plan": plan_belief._asdict(),
        "seeds": seeds,
        "summary": {
            "own_optimum_reaches_goal": sum(x["plan"]["goal"] >= 0.5 for x in seeds),
            "ranks_optimal_first": sum(x["ranks_optimal_first"] for x in seeds),
            "policy_on_better_route": sum(bool(x["policy"]["better"]) for x in seeds),
            "seeds": len(seeds),
        },
    }


def by_terrain(learned: np.ndarray, truth: np.ndarray, terrain: np.ndarray) -> dict:
    """``{terrain: [learned z, true z]}``: both [N] per-sub-cell rewards z-scored over the sub-cells
    outside the pits, averaged on each terrain present."""
    live = terrain != PIT

    def z(x):
        sd = x[live].std()
        return (x - x[live].mean()) / (sd if sd > 0 else 1.0)

    zl, zt = z(learned), z(truth)
    return {
        TERRAINS[code]: [float(zl[terrain == code].mean()), float(zt[terrain == code].mean())]
        for code in np.unique(terrain)
    }


def report(rec: dict) -> str:
    """The text ``mindgap design reward-plan`` prints."""
    o, e = rec["optimal_plan"], rec["expected_plan"]
    lines = [
        f"{rec['job']} in {rec['run']}: what the learned reward r̂ asks for ({rec['world']}, γ = {rec['gamma']})",
        f"  the optimal plan (true reward): return {o['ret']:.1f}, goal {o['success']:.0%}",
        f"  the person's expected plan (belief), in the true world: return {e['ret']:.1f}, goal {e['success']:.0%}",
        "  seed | r̂'s own optimum, run in the true world      | r̂'s value from the start: own / optimal plan / expected plan | learned policy",
    ]
    for x in rec["seeds"]:
        p, v, pol = x["plan"], x["value"], x["policy"]
        where = f"ice {p['ice']:.0%}, sand {p['sand']:.0%}" + (
            f", pit distance {p['pit_mean']:.2f}" if p["pit_mean"] is not None else ""
        )
        rank = "optimal first" if x["ranks_optimal_first"] else "expected first"
        lines.append(
            f"  {x['seed']:>4} | return {p['return']:7.1f}, goal {p['goal']:4.0%}, pit {p['pit']:4.0%}, {where}"
            f" | {v['own']:7.1f} / {v['optimal']:7.1f} / {v['expected']:7.1f} ({rank})"
            f" | {pol['final']:7.1f}, goal {pol['goal']:.0%}, {'better route' if pol['better'] else 'not the better route'}"
        )
    lines.append("  seed | r̂ by terrain, z-scored over the sub-cells outside pits (the truth's in brackets)")
    for x in rec["seeds"]:
        lines.append(
            f"  {x['seed']:>4} | " + ", ".join(f"{t} {a:+.2f} ({b:+.2f})" for t, (a, b) in x["by_terrain"].items())
        )
    s = rec["summary"]
    lines.append(
        f"  r̂'s own optimum reaches the goal in {s['own_optimum_reaches_goal']} of {s['seeds']} seeds; r̂ ranks the optimal "
        f"plan above the expected one in {s['ranks_optimal_first']}; the learned policy takes the better route in "
        f"{s['policy_on_better_route']}"
    )
    return "\n".join(lines)
