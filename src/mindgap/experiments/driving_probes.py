"""The driving study's participant gates: what the simulated participants want and expect, before any learner.

A learner can only follow answers that say something. These probes measure, on a run folder's
participants (its ``driving/people`` job) and five scripted policies, what the dissertation
says of its participants (§4.4.2.1: they "preferred to brake than steer in general"; 12 of 14
expected braking to work as on a dry road; 1 of 15 failed the sanity check):

* :func:`scripted_segments`: five scripted responses to the front car's braking —
  ``brake in lane`` (SLOWER once the front car brakes), ``change lane when it brakes``
  (LANE_LEFT then), ``change lane at once`` (LANE_LEFT at the first decision), ``brake, then
  change lane`` (SLOWER at the first decision after the onset, LANE_LEFT after: Fig. 36's EPS) and
  ``overtake and return`` (LANE_LEFT at the onset, back to the start lane once the front car is
  15 m behind);
* :func:`reward_table`: each participant's own reward r_H of each policy, on the dry road and on
  sleet (which policy each participant *wants*);
* :func:`onset_response`: each participant's π_H driving in the world they believe in (actions
  drawn from it): its first decision once the front car brakes;
* :func:`expectedness_table`: how expected each policy's clip (the queries' length, from the
  episode's start) looks per decision to each participant, as the run has them judge
  (:attr:`~mindgap.experiments.driving.DrivingConfig.answers_by`), and the rating it gets;
* :func:`gates`: the verdicts of docs/experiments/driving.md ("Participants, before any learner"),
  which ``mindgap design driving --run DIR`` prints.

Written by hand: scripted policies and the study's own counts.
"""

from __future__ import annotations

import dataclasses
import json
from functools import partial
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from ..algorithms.sac import SACConfig
from ..data.segments import Segments
from ..envs.driving.params import ACTIONS
from ..envs.driving.world import DIST_SCALE, EGO_OBS
from ..models.categorical import sample_categorical
from ..teachers import drivers as dv
from . import driving as dr

PASSED = 15.0
"""The overtaking script returns to its lane once the front car is this far behind [m]."""
IDLE, LEFT, SLOWER = ACTIONS.index("IDLE"), ACTIONS.index("LANE_LEFT"), ACTIONS.index("SLOWER")
RIGHT, FASTER = ACTIONS.index("LANE_RIGHT"), ACTIONS.index("FASTER")
POLICIES = (
    "brake in lane",
    "change lane when it brakes",
    "change lane at once",
    "brake, then change lane",
    "overtake and return",
)
BRAKE = POLICIES.index("brake in lane")


def scripted_action(policy: int, obs: jax.Array, t: jax.Array, seen: jax.Array, start_lane: jax.Array) -> jax.Array:
    """The action of :data:`POLICIES` [``policy``] at decision ``t``, after ``seen`` decisions with the front
    car braking, on a road whose cars start in ``start_lane``."""
    front_brakes = obs[7] > 0.5
    home = jnp.round(obs[3]) == start_lane
    front_dx = obs[EGO_OBS] * DIST_SCALE
    overtake = jnp.where(
        home, jnp.where(front_brakes & (front_dx > 0), LEFT, IDLE), jnp.where(front_dx > -PASSED, IDLE, RIGHT)
    )
    return jnp.select(
        [policy == 0, policy == 1, policy == 2, policy == 3],
        [
            jnp.where(front_brakes, SLOWER, IDLE),
            jnp.where(front_brakes, LEFT, IDLE),
            jnp.where(t == 0, LEFT, IDLE),
            jnp.where(front_brakes, jnp.where(seen == 0, SLOWER, LEFT), IDLE),
        ],
        overtake,
    )


def scripted_segments(world, params, policy: int, episodes: int, key) -> tuple[Segments, np.ndarray]:
    """``episodes`` whole episodes of scripted ``policy`` in the world ``params``: (Segments [E, T, ·], r_A returns [E])."""
    obs, a, nxt, live, r = _scripted(
        jax.random.split(key, episodes), jnp.int32(policy), params, world.env, world.horizon
    )
    return Segments(obs, a[..., None].astype(jnp.float32), nxt, live.astype(jnp.float32)), np.asarray(r.sum(-1))


@partial(jax.jit, static_argnames=("env", "horizon"))
def _scripted(keys, policy, params, env, horizon: int):
    def episode(k):
        k0, k1 = jax.random.split(k)

        def body(carry, kt):
            state, done, t, seen = carry
            obs = env.observe(state, params)
            a = scripted_action(policy, obs, t, seen, params.start_lane)
            out = env.step(kt, state, a, params)
            nxt = env.observe(out.state, params)
            r = jnp.where(done, 0.0, env.reward(obs, a, nxt, params))
            return (out.state, done | out.terminated | out.truncated, t + 1, seen + (obs[7] > 0.5)), (
                obs,
                a,
                nxt,
                ~done,
                r,
            )

        init = (env.reset(k0, params), jnp.zeros((), bool), 0, 0)
        return jax.lax.scan(body, init, jax.random.split(k1, horizon))[1]

    return jax.vmap(episode)(keys)


def _clip(seg: Segments, length: int) -> Segments:
    """The first ``length`` decisions of each episode: what a query shows (from the episode's start)."""
    return jax.tree.map(lambda x: x[:, :length], seg)


@dataclasses.dataclass
class Participants:
    """A run's valid participants: config, world, drivers and their π_H (a leading participant axis)."""

    cfg: dr.DrivingConfig
    world: object
    drivers: list
    actors: object
    people: dict

    def actor(self, i: int):
        return jax.tree.map(lambda a: a[i], self.actors)


def load_participants(run: Path, answers_by: str | None = None) -> Participants:
    """The valid participants of run folder ``run`` (its ``driving/people`` job), judging clips as the run
    does (or as ``answers_by`` says). One clear line when the folder has no participants."""
    run = Path(run)
    people_path = run / "jobs" / "driving__people.json"
    if not people_path.is_file() or not (run / "config.json").is_file():
        raise ValueError(
            f"{run} has no finished participants job (run `mindgap reproduce driving --job driving/people`)"
        )
    stored = json.loads((run / "config.json").read_text())
    fast = dr.preset("fast")
    base = fast if stored["eps"]["total_steps"] == fast.eps.total_steps else dr.preset("full")  # the run's schedule
    person = dataclasses.replace(base.person, sac=SACConfig(hidden=tuple(stored["person"]["sac"]["hidden"])))
    way = answers_by or stored.get("answers_by") or ("expectation" if stored["teacher"]["use_belief"] else "decisions")
    cfg = dataclasses.replace(
        base, sleet=stored["sleet"], traffic=stored.get("traffic", 0), person=person, answers_by=way,
        eps=dataclasses.replace(base.eps, segment=int(stored["eps"]["segment"])),
    )  # fmt: skip
    people = json.loads(people_path.read_text())
    world = dr.world_of(cfg, people["engineered_weights"])
    drivers, actors = dr.load_people(SimpleNamespace(root=run), world, people, cfg)
    return Participants(cfg, world, drivers, actors, people)


def reward_table(p: Participants, episodes: int, key) -> dict[str, np.ndarray]:
    """Per road (``dry``, ``sleet``): each participant's mean r_H of each scripted policy's episodes, [P, 5]."""
    out = {}
    weights = jnp.asarray(np.stack([d.weights for d in p.drivers]))
    everyone = jax.jit(
        jax.vmap(lambda seg, w, params: dv.reward_sums(seg, dv.RewardH(w, params)).mean(), (None, 0, None))
    )
    for road, params in (("dry", p.world.beliefs["dry"]), ("sleet", p.world.params)):
        table = np.zeros((len(p.drivers), len(POLICIES)))
        for j in range(len(POLICIES)):
            seg, _ = scripted_segments(p.world, params, j, episodes, key)
            table[:, j] = np.asarray(everyone(seg, weights, params))
        out[road] = table
    return out


def onset_response(p: Participants, episodes: int, key) -> np.ndarray:
    """Each participant's π_H in the world they believe in (actions drawn from it): the shares of episodes
    whose first decision once the front car brakes is SLOWER, a lane change, and IDLE/FASTER, [P, 3]."""
    env, horizon = p.world.env, p.world.horizon

    def episode(actor, params, k):
        k0, k1 = jax.random.split(k)

        def body(carry, kt):
            state, done = carry
            obs = env.observe(state, params)
            ka, ks = jax.random.split(kt)
            a = sample_categorical(actor, obs, ka)[0][0]
            out = env.step(ks, state, a, params)
            return (out.state, done | out.terminated | out.truncated), (obs, a, ~done)

        _, steps = jax.lax.scan(body, (env.reset(k0, params), jnp.zeros((), bool)), jax.random.split(k1, horizon))
        return steps

    many = jax.jit(jax.vmap(episode, in_axes=(None, None, 0)))
    rows = []
    for i, d in enumerate(p.drivers):
        obs, act, live = map(
            np.asarray, many(p.actor(i), dr.belief_params(p.world, d), jax.random.split(key, episodes))
        )
        braking = (obs[..., 7] > 0.5) & live
        seen = braking.any(1)
        first = act[np.arange(episodes), np.argmax(braking, 1)].astype(int)[seen]
        n = max(int(seen.sum()), 1)
        rows.append([np.sum(first == SLOWER) / n, np.sum(np.isin(first, (LEFT, RIGHT))) / n,
                     np.sum(np.isin(first, (IDLE, FASTER))) / n])  # fmt: skip
    return np.asarray(rows)


def expectedness_table(p: Participants, episodes: int, key) -> dict[str, np.ndarray]:
    """Per road: how expected each policy's clips look per decision to each participant, [P, 5], and the
    sanity collision's clip beside them on sleet (``sanity``, [P]), as the run's participants judge."""
    out = {}
    length = p.cfg.eps.segment
    beliefs = jax.tree.map(lambda *xs: jnp.stack(xs), *[dr.belief_params(p.world, d) for d in p.drivers])
    everyone = jax.jit(jax.vmap(lambda seg, a, b: dr.clip_per_step(p.cfg, seg, a, b, p.world.env), (None, 0, 0)))
    for road, params in (("dry", p.world.beliefs["dry"]), ("sleet", p.world.params)):
        table = np.zeros((len(p.drivers), len(POLICIES)))
        for j in range(len(POLICIES)):
            seg = _clip(scripted_segments(p.world, params, j, episodes, key)[0], length)
            table[:, j] = np.asarray(everyone(seg, p.actors, beliefs)).mean(1)
        out[road] = table
    (c_obs, c_act, c_alive), _ = dr.sanity_segments(p.world, p.world.horizon)
    crash = dr._segment(c_obs, c_act, c_alive, p.world.horizon)
    out["sanity"] = np.asarray(everyone(crash, p.actors, beliefs))[:, 0]
    return out


def rating(per_step: np.ndarray) -> np.ndarray:
    """The noise-free 1–10 rating of a clip from its per-decision score (§2.2.1's geometric-mean form)."""
    return dv.RATING[0] + (dv.RATING[1] - dv.RATING[0]) * np.exp(per_step)


def gates(p: Participants, episodes: int = 200, seed: int = 0) -> dict:
    """The participant gates (module docstring): every table and each verdict with its target."""
    key = jax.random.key(seed)
    att = np.array([d.attentive for d in p.drivers])
    rewards = reward_table(p, episodes, key)
    onset = onset_response(p, max(episodes // 4, 20), key)
    expect = expectedness_table(p, episodes, key)
    n = len(p.drivers)
    slows = int(np.sum(onset[:, 0] > 0.5))
    brake_expected = int(np.sum(np.argmax(expect["sleet"], 1) == BRAKE))
    crash_lowest = int(np.sum(expect["sanity"] < expect["sleet"].min(1)))
    verdicts = {
        "slows_at_onset": {"value": slows, "of": n, "target": ">= 9 of 14", "holds": slows >= 9 * n / 14},
        "braking_most_expected_on_sleet": {
            "value": brake_expected, "of": n, "target": ">= 9 of 14", "holds": brake_expected >= 9 * n / 14,
        },
        "bias": {"value": int(p.people["bias_effective"]), "of": n, "target": "about 12 of 14",
                 "holds": abs(p.people["bias_effective"] / n - 12 / 14) <= 2 / 14},
        "sanity_dropped": {"value": p.people["recruits"] - p.people["valid"], "of": p.people["recruits"],
                           "target": "about 1 of 15", "holds": p.people["recruits"] - p.people["valid"] <= 2},
        "crash_rated_lowest": {"value": crash_lowest, "of": n, "target": "every participant", "holds": crash_lowest == n},
    }  # fmt: skip
    return {
        "answers_by": p.cfg.answers_by,
        "episodes": episodes,
        "participants": [
            {"pid": d.pid, "believed_sleet": d.believed_sleet, "attentive": bool(a)} for d, a in zip(p.drivers, att)
        ],
        "policies": list(POLICIES),
        "reward": {k: v.round(3).tolist() for k, v in rewards.items()},
        "best_reward": {k: [POLICIES[j] for j in np.argmax(v, 1)] for k, v in rewards.items()},
        "onset": onset.round(3).tolist(),
        "expectedness": {k: np.round(v, 3).tolist() for k, v in expect.items()},
        "gates": verdicts,
    }


def report(g: dict) -> str:
    """The gates as text: one table per measure, then the verdicts."""
    lines = [f"participants judge clips by: {g['answers_by']}; {g['episodes']} episodes per scripted policy"]
    names = [p["pid"] for p in g["participants"]]
    short = ["brake", "change@onset", "change@once", "brake+change", "overtake"]
    for title, table in (
        ("r_H on the dry road", g["reward"]["dry"]),
        ("r_H on sleet", g["reward"]["sleet"]),
        ("expectedness per decision, dry road", g["expectedness"]["dry"]),
        ("expectedness per decision, sleet", g["expectedness"]["sleet"]),
    ):
        lines += ["", title, f"{'participant':<12} {'belief':<6} " + " ".join(f"{s:>13}" for s in short)]
        for name, who, row in zip(names, g["participants"], table):
            best = int(np.argmax(row))
            cells = [f"{v:>12.2f}{'*' if j == best else ' '}" for j, v in enumerate(row)]
            lines.append(f"{name:<12} {'dry' if who['believed_sleet'] == 0 else 'sleet':<6} " + " ".join(cells))
    lines += ["", "first decision once the front car brakes, π_H in the world they believe in",
              f"{'participant':<12} {'SLOWER':>8} {'lane change':>12} {'IDLE/FASTER':>12} {'sanity crash (per decision)':>28}"]  # fmt: skip
    for name, row, s in zip(names, g["onset"], g["expectedness"]["sanity"]):
        lines.append(f"{name:<12} {row[0]:>8.2f} {row[1]:>12.2f} {row[2]:>12.2f} {s:>28.2f}")
    lines += ["", "gates"]
    for k, v in g["gates"].items():
        lines.append(
            f"  {k:<32} {v['value']:>3} of {v['of']:<3} target {v['target']:<18} {'holds' if v['holds'] else 'FAILS'}"
        )
    return "\n".join(lines)
