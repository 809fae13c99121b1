"""Scripted driving policies scored by r_A and by the participants' reward r_H (docs/experiments/driving.md).

Checks the measurement behind the participants' fourth factor: with r_A's lane following
(offset from the nearest lane's centre) a person who believes the road is dry would expect a
lane change, whereas with Fig. 32's "staying on the same lane" (1 in the start lane, 0 one lane
away; :func:`mindgap.teachers.drivers.stay_in_lane`) they would expect braking in lane.

Five policies, each run for ``--episodes`` episodes on a dry road and at ``--sleet`` (with
``--traffic N`` other cars, as ``mindgap reproduce driving --traffic N``):

* ``brake in lane``: SLOWER once the front car brakes (IDLE before);
* ``change lane when it brakes``: LANE_LEFT once the front car brakes (IDLE before);
* ``change lane at once``: LANE_LEFT at the first step, IDLE after;
* ``brake, then change lane``: SLOWER at the first decision after the front car brakes, LANE_LEFT
  after (IDLE before): what EPS does in the dissertation (Fig. 36);
* ``overtake and return``: LANE_LEFT once the front car brakes, IDLE in the next lane until the
  front car is 15 m behind, then LANE_RIGHT back to the start lane.

Both rewards use the study's average importances (Fig. 32). Prints the mean return (± its
standard error) of each policy under each reward. With ``--run DIR`` (a ``mindgap reproduce
driving`` run folder) it prints instead how expected each policy's episodes look to that run's
valid participants, per step, both as the identifiable protocol scores them — Σ_t [log T_H +
log π_H] — and by log π_H alone, as ``--answers-by decisions`` does
(:func:`mindgap.teachers.drivers.per_step_scores`), averaged over the attentive participants and
the episodes, and how many of them find braking in lane the most expected of the five. With ``--run DIR --expected`` it prints
what each attentive participant expects the car to do: their π_H's own episodes (actions drawn
from π_H) in the world as they believe it — how often the expected car changes lane before the
front car brakes, its first decision once it brakes, and how expected those episodes look per
step to the participant themselves, to set beside the scripted policies' scores:

    .venv/bin/python scripts/driving_scripted.py [--episodes 200] [--sleet 1.0] [--traffic 0] [--seed 0] [--run DIR [--expected]]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.data.segments import Segments
from mindgap.envs.driving import STUDY_IMPORTANCE, importance_weights, make_world
from mindgap.envs.driving.params import ACTIONS
from mindgap.envs.driving.world import DIST_SCALE, EGO_OBS
from mindgap.experiments import driving as dr
from mindgap.experiments import registry
from mindgap.models.categorical import sample_categorical
from mindgap.teachers.drivers import RewardH, participant_reward, per_step_scores
from mindgap.teachers.expectation import ExpectationTeacher

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


def act(policy: int, obs: jax.Array, t: jax.Array, seen: jax.Array, start_lane: jax.Array) -> jax.Array:
    """The scripted action of ``policy`` (an index into :data:`POLICIES`) at step ``t``, after ``seen``
    decisions with the front car braking, on a road whose cars start in ``start_lane``."""
    front_brakes = obs[7] > 0.5  # the observation's "front car braking" flag
    home = jnp.round(obs[3]) == start_lane  # the target lane is the start lane
    front_dx = obs[EGO_OBS] * DIST_SCALE  # the front car's distance ahead (centre to centre)
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


def returns(world, params, policy: int, episodes: int, key, keep: bool = False):
    """Returns [episodes] of ``policy`` under r_A and under the average participant's r_H (``keep``: and the
    episodes as :class:`~mindgap.data.segments.Segments`)."""
    env, horizon = world.env, world.horizon
    r_h = RewardH(jnp.asarray(importance_weights(STUDY_IMPORTANCE), jnp.float32), params)

    def episode(k):
        k0, k1 = jax.random.split(k)
        state = env.reset(k0, params)

        def body(carry, kt):
            state, done, t, seen, ra, rh = carry
            obs = env.observe(state, params)
            a = act(policy, obs, t, seen, params.start_lane)
            seen = seen + (obs[7] > 0.5)
            out = env.step(kt, state, a, params)
            nxt = env.observe(out.state, params)
            live = ~done
            ra = ra + live * env.reward(obs, a, nxt, params)
            rh = rh + live * participant_reward(r_h, obs[None], a[None], nxt[None])[0]
            done = done | out.terminated | out.truncated
            return (out.state, done, t + 1, seen, ra, rh), (obs, a, nxt, live)

        zero = jnp.zeros((), jnp.float32)
        (*_, ra, rh), steps = jax.lax.scan(
            body, (state, jnp.zeros((), bool), 0, 0, zero, zero), jax.random.split(k1, horizon)
        )
        return ra, rh, steps

    ra, rh, (obs, a, nxt, live) = jax.jit(jax.vmap(episode))(jax.random.split(key, episodes))
    if keep:
        return np.asarray(ra), np.asarray(rh), Segments(obs, a[..., None].astype(jnp.float32), nxt, live)
    return np.asarray(ra), np.asarray(rh)


def participants(run: Path, world):
    """The run's attentive valid participants as (driver, π_H actor) pairs, and how they answer."""
    stored = json.loads((run / "config.json").read_text())
    preset = registry.preset_of("driving", stored)  # whose π_H networks the run trained
    if preset == "custom":
        raise SystemExit(f"{run}: not a run of a driving preset (its config was changed in code)")
    cfg = dr.preset(preset)
    teacher = dataclasses.replace(cfg.teacher, use_belief=stored["teacher"]["use_belief"])  # --answers-by
    people = json.loads((run / "jobs" / "driving__people.json").read_text())
    valid, actors = dr.load_people(SimpleNamespace(root=run), world, people, cfg)
    pairs = [(d, jax.tree.map(lambda a, j=j: a[j], actors)) for j, d in enumerate(valid) if d.attentive]
    return pairs, teacher


def expected_episodes(run: Path, world, episodes: int, key) -> None:
    """What each attentive participant of ``run`` expects: their π_H's own episodes in their believed world."""
    env = world.env

    def episode(actor, params, k):
        k0, k1 = jax.random.split(k)

        def body(carry, kt):
            state, done = carry
            obs = env.observe(state, params)
            ka, ks = jax.random.split(kt)
            a = sample_categorical(actor, obs, ka)[0][0]
            out = env.step(ks, state, a, params)
            return (out.state, done | out.terminated | out.truncated), (obs, a, env.observe(out.state, params), ~done)

        _, steps = jax.lax.scan(body, (env.reset(k0, params), jnp.zeros((), bool)), jax.random.split(k1, world.horizon))
        return steps

    many = jax.jit(jax.vmap(episode, in_axes=(None, None, 0)))
    print(
        f"{episodes} episodes of each attentive participant's π_H (actions drawn from it) in the world they believe in"
    )
    print(f"{'participant':<12} {'belief':<7} {'changes lane before it brakes':>30} | first decision once it brakes: "
          f"{'SLOWER':>7} {'lane change':>12} {'IDLE/FASTER':>12} | own episodes' expectedness per step")  # fmt: skip
    rows = []
    pairs, teacher = participants(run, world)
    for d, actor in pairs:
        belief = dr.belief_params(world, d)
        steps = many(actor, belief, jax.random.split(key, episodes))
        seg = Segments(steps[0], steps[1][..., None].astype(jnp.float32), steps[2], steps[3].astype(jnp.float32))
        own = float(np.mean(per_step_scores(seg, ExpectationTeacher(belief, actor, env), teacher)))
        obs, act, _, live = map(np.asarray, steps)
        act = act.astype(int)
        braking = (obs[..., 7] > 0.5) & live
        onset = np.where(braking.any(1), np.argmax(braking, 1), world.horizon)
        lane = np.abs(np.diff(obs[..., 3], axis=1)) > 0.5  # the target lane changed at this decision
        before = np.array([lane[i, : onset[i]].any() for i in range(episodes)])  # decisions 0 … onset − 1
        first = np.array([act[i, onset[i]] if onset[i] < world.horizon else -1 for i in range(episodes)])
        shares = [
            np.mean(first == SLOWER),
            np.mean(np.isin(first, (LEFT, RIGHT))),
            np.mean(np.isin(first, (IDLE, FASTER))),
        ]
        rows.append([before.mean(), *shares, own])
        name = "dry" if d.believed_sleet == 0 else f"{d.believed_sleet:g}"
        print(
            f"{d.pid:<12} {name:<7} {before.mean():>30.2f} | {'':>31}{shares[0]:>7.2f} {shares[1]:>12.2f} "
            f"{shares[2]:>12.2f} | {own:>8.2f}"
        )
    m = np.mean(rows, 0)
    print(f"{'mean':<12} {'':<7} {m[0]:>30.2f} | {'':>31}{m[1]:>7.2f} {m[2]:>12.2f} {m[3]:>12.2f} | {m[4]:>8.2f}")


def expectedness(run: Path, world, episodes: int, key) -> None:
    """How expected each scripted policy's episodes look per step to the valid, attentive participants of
    ``run``, under both ways of answering: Σ [log T_H + log π_H] (the identifiable protocol) and log π_H
    alone (``--answers-by decisions``). Also counts, per road and way, the participants to whom braking in
    lane is the most expected of the five policies."""
    pairs, teacher = participants(run, world)
    persons = [ExpectationTeacher(dr.belief_params(world, d), actor, world.env) for d, actor in pairs]
    ways = {
        "log T_H + log π_H": dataclasses.replace(teacher, use_belief=True),
        "log π_H": dataclasses.replace(teacher, use_belief=False),
    }
    print(f"per-step expectedness of {episodes} episodes, mean over the {len(persons)} attentive participants of "
          f"{run} (it answers by {'Σ [log T_H + log π_H]' if teacher.use_belief else 'log π_H'})")  # fmt: skip
    print(f"{'road':<8} {'policy':<28} " + " ".join(f"{w:>18}" for w in ways))
    for road, params in (("dry", world.beliefs["dry"]), ("sleet", world.params)):
        table = {w: [] for w in ways}  # [policy][participant]
        for i, name in enumerate(POLICIES):
            *_, seg = returns(world, params, i, episodes, key, keep=True)
            for w, cfg in ways.items():
                table[w].append([float(np.mean(per_step_scores(seg, person, cfg))) for person in persons])
            print(f"{road:<8} {name:<28} " + " ".join(f"{np.mean(table[w][i]):>18.2f}" for w in ways))
        best = {
            w: int(np.sum(np.argmax(np.asarray(t), 0) == POLICIES.index("brake in lane"))) for w, t in table.items()
        }
        print(
            f"{road:<8} {'braking in lane most expected':<28} "
            + " ".join(f"{best[w]:>15} of {len(persons)}" for w in ways)
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--sleet", type=float, default=1.0)
    ap.add_argument("--traffic", type=int, default=0, help="other cars on the road (make_world's traffic)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--run", type=Path, help="a driving run folder: score by its participants' expectations")
    ap.add_argument("--expected", action="store_true", help="with --run: the participants' own expected episodes")
    args = ap.parse_args()
    traffic = args.traffic
    if args.run is not None:  # the run's road
        traffic = json.loads((args.run / "config.json").read_text()).get("traffic", 0)
    world = make_world(sleet=args.sleet, traffic=traffic)
    key = jax.random.key(args.seed)
    if args.expected and args.run is None:
        raise SystemExit("--expected needs --run DIR")
    if args.run is not None:
        return (expected_episodes if args.expected else expectedness)(args.run, world, args.episodes, key)
    print(f"mean return over {args.episodes} episodes (± standard error); study's average importances")
    print(f"{'road':<8} {'policy':<28} {'r_A (lane following)':>22} {'r_H (same lane)':>18}")
    for road, params in (("dry", world.beliefs["dry"]), (f"sleet {args.sleet:g}", world.params)):
        for i, name in enumerate(POLICIES):
            ra, rh = returns(world, params, i, args.episodes, key)
            se = lambda x: x.std(ddof=1) / np.sqrt(len(x))  # noqa: E731
            print(f"{road:<8} {name:<28} {ra.mean():>14.1f} ± {se(ra):<5.1f} {rh.mean():>10.1f} ± {se(rh):<5.1f}")


if __name__ == "__main__":
    main()
