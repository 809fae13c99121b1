"""Measuring a driving policy (§4.4.2, Figs. 34–36): its greedy episodes, their behaviours, a learner's record.

:func:`behaviour` reads, per episode, what Table 5's discussion and Figs. 34–36 describe: a
collision, the first lane change relative to the front car's braking, whether the car braked
before it, and the smallest bumper gap to the front car while in line with it. Used by the
experiment (:mod:`~.driving`) and its learner controls (:mod:`~.driving_controls`).
"""

from __future__ import annotations

import jax
import numpy as np

from .. import rng
from ..algorithms.sac_loop import greedy_policy, rollouts
from ..envs.driving.params import LANE_WIDTH, LENGTH, SLOWER, WIDTH
from ..envs.driving.world import DIST_SCALE, EGO_OBS


def greedy_episodes(world, actor, key, count: int):
    """``count`` greedy episodes of one actor in ``world``: (obs [E, T+1, d], act [E, T, 1], alive [E, T], rewards [E, T])."""
    policy = greedy_policy(world.env)
    obs, rew, alive = rollouts(key, world.env, world.params, policy, actor, count, world.horizon)
    act = jax.vmap(jax.vmap(lambda o: policy(actor, o)))(obs[:, :-1])
    return obs, act, alive, rew


def behaviour(obs: np.ndarray, act: np.ndarray, alive: np.ndarray, world) -> dict[str, np.ndarray]:
    """Per episode: collided; the first lane change in decisions after the front car starts braking (NaN:
    none; negative: before it); whether it changed lane; whether it braked (SLOWER) before its first lane
    change after the onset; the smallest bumper gap [m] to the front car while it is ahead and the
    two cars overlap sideways (centres less than a car's width apart: in line, so the gap is one a
    collision would close; a car passing beside it mid-lane-change has no bumper gap to it)."""
    start = obs[:, 0, 3]
    steps = alive.sum(-1).astype(int)
    out = {k: [] for k in ("collided", "first_change", "changed", "braked_first", "min_gap")}
    for e in range(obs.shape[0]):
        n = steps[e]
        o, a = obs[e, : n + 1], act[e, :n, 0]
        onset = np.flatnonzero(o[:, 7] > 0.5)
        onset = int(onset[0]) if onset.size else n
        lane = np.flatnonzero(np.round(o[1:, 3]) != np.round(start[e]))
        change = int(lane[0]) if lane.size else None  # the action at step `change` moved the target lane
        out["collided"].append(float(o[-1, 6] > 0.5))
        out["changed"].append(float(change is not None))
        out["first_change"].append(np.nan if change is None else float(change + 1 - onset))
        before = a[onset - 1 : change] if change is not None else a[max(onset - 1, 0) :]
        out["braked_first"].append(float(np.any(np.round(before) == SLOWER)))
        in_line = np.abs(o[:, 0] - o[:, EGO_OBS + 1]) * LANE_WIDTH < WIDTH  # lateral positions are in lane widths
        same = in_line & (o[:, EGO_OBS] > 0)  # in line with it, and it is ahead
        gap = o[:, EGO_OBS] * DIST_SCALE - LENGTH
        out["min_gap"].append(float(gap[same].min()) if same.any() else np.nan)
    return {k: np.asarray(v, np.float64) for k, v in out.items()}


def learner_record(world, actors, res: dict, episodes: int) -> dict:
    """A learner's record: curve, and per seed the return and behaviour of ``episodes`` greedy episodes."""
    seeds = jax.tree.leaves(actors)[0].shape[0]
    per = {k: [] for k in ("return", "collided", "first_change", "changed", "braked_first", "min_gap")}
    for s in range(seeds):
        actor = jax.tree.map(lambda a, s=s: a[s], actors)
        obs, act, alive, rew = greedy_episodes(world, actor, rng.key(20_000 + s), episodes)
        b = behaviour(np.asarray(obs), np.asarray(act), np.asarray(alive), world)
        per["return"].append(float(np.asarray(rew).sum(-1).mean()))
        for k, v in b.items():
            per[k].append(float(np.nanmean(v)) if np.isfinite(v).any() else None)
    final = np.asarray(res["final_returns"], np.float64)
    if not np.all(np.isfinite(final)):
        raise FloatingPointError("non-finite returns: the run diverged")
    return {
        "seeds": seeds,
        "curve": [[int(s), int(t), float(r), int(q)] for s, t, r, q in res["curve"]],
        "final": [float(x) for x in final.mean(1)],
        **per,
    }
