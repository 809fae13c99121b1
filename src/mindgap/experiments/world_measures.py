"""What the terrain experiments measure of a world and of a learner on it, on any world.

The experiments ``nav``, ``priors``, ``sampling``, ``eps`` and ``lambda`` take any world the
engine takes that has a belief and an exact density (``--env``: a named world, a world file
or a user's ``module:factory``). What they measure depends on what the world offers:

* **every world**: the return of a uniformly random policy (the 0 of the normalised score)
  and the reward error of a learned reward (:func:`reward_error`), both from the interface
  alone (``reset``/``step``/``observe``);
* **terrain worlds** (:class:`~mindgap.envs.terrain.TerrainWorld`, which have a map) add the
  planning check's routes, the route each seed takes (:func:`route_of`: goal rate, terrain
  shares, pit distance, the world's ``[expect]`` judgement), a reward error on a lattice of
  cells × compass pushes, and the maps of learned beliefs. On other worlds these are absent
  (None in records, empty cells in tables) rather than invented.

:func:`experiment_world` loads and checks a world for an experiment before anything is
written.
"""

from __future__ import annotations

import dataclasses
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..design.terrain_check import check_world
from ..envs.gym_world import GymWorld
from ..envs.interface import EnvError, check_env
from ..envs.resolve import resolve_env
from ..envs.terrain import TerrainWorld, observe
from ..envs.terrain.dynamics import sample_next
from ..envs.terrain.layout import GOAL, PIT, WALL
from ..envs.terrain.params import TerrainState
from ..envs.terrain.world import reward as true_reward
from ..planning.terrain import compass_actions, rollouts, route_stats

REWARD_DRAWS = 32
"""Draws of the true next state per (state, action) for the expected true reward."""


def experiment_world(spec: str, who: str):
    """The world ``spec`` names, refused with one line unless ``who`` (an experiment) can run on it.

    The experiments' simulated people score segments with the world's reward and exact
    density under a belief, so the world needs both, and at least one belief. A world made
    by a factory with ``key=value`` arguments is named with them (``point_mass(drift=0.1)``),
    so two settings of one factory do not share output files.
    """
    world = resolve_env(spec)
    if isinstance(world, GymWorld):
        raise EnvError(
            f"{who} needs a pure-JAX world with a belief and an exact density; {spec} is a gymnasium env "
            "(mindgap sac|pebble|drlhp --env run on it)"
        )
    check_env(world.env, density=True, who=f"{who}'s simulated person")
    if not world.beliefs:
        raise EnvError(f"{who} needs a world with a belief; {spec} declares none")
    kwargs = spec.partition(",")[2]
    if kwargs and not isinstance(world, TerrainWorld):
        world = dataclasses.replace(world, name=f"{world.name}({kwargs})")
    return world


def has_map(world) -> bool:
    """Whether ``world`` is a terrain world, whose map gives routes, planning and belief maps."""
    return isinstance(world, TerrainWorld)


def expect(world) -> dict:
    """The world's ``[expect]`` entries (terrain worlds; empty for others)."""
    return getattr(world, "expect", {}) or {}


# ---------------------------------------------------------------------------------------
# the random policy and the planning check


def _random_action(key, pos):
    """A uniformly random action seeded by the position's bits.

    Positions almost never repeat, so each step draws afresh; a robot stuck in sand stays
    put and tries the same push again, as a random policy with memoryless draws would not.
    """
    bits = jax.lax.bitcast_convert_type(pos, jnp.int32)
    return jax.random.uniform(jax.random.fold_in(key, bits[0] * 7919 + bits[1]), (2,), minval=-1.0, maxval=1.0)


@partial(jax.jit, static_argnames=("env", "count", "horizon", "draws"))
def random_transitions(key, env, params, count: int, horizon: int, draws: int = REWARD_DRAWS):
    """``count`` episodes of a uniformly random policy through the interface.

    Returns:
        dict of ``[count, T, ·]`` arrays: ``obs``, ``act``, ``next_obs``, ``reward`` (the
        world's, 0 after the episode ended), ``expected_reward`` (the mean reward of ``draws``
        fresh next states from the same state and action) and ``alive`` (the step happened).
    """
    act_dim = env.action_space.dim

    def one(k):
        k0, k1 = jax.random.split(k)

        def body(carry, kk):
            s, done = carry
            k_act, k_step, k_draw = jax.random.split(kk, 3)
            a = jax.random.uniform(k_act, (act_dim,), minval=-1.0, maxval=1.0)
            out = env.step(k_step, s, a, params)
            again = jax.vmap(lambda kd: env.step(kd, s, a, params).reward)(jax.random.split(k_draw, draws))
            nxt = jax.tree.map(lambda x, y: jnp.where(done, x, y), s, out.state)
            row = {
                "obs": env.observe(s, params),
                "act": a,
                "next_obs": env.observe(out.state, params),
                "reward": jnp.where(done, 0.0, out.reward),
                "expected_reward": again.mean(),
                "alive": ~done,
            }
            return (nxt, done | out.terminated | out.truncated), row

        start = (env.reset(k0, params), jnp.zeros((), bool))
        return jax.lax.scan(body, start, jax.random.split(k1, horizon))[1]

    return jax.vmap(one)(jax.random.split(key, count))


def reference_record(world, episodes: int, seed: int, plan_resolution: int, plan_rollouts: int) -> dict:
    """The random policy's return and, on a terrain world, the planning check's routes."""
    k_rand, k_pol = jax.random.split(rng.key(seed))
    if has_map(world):
        _, rew, _ = rollouts(k_rand, world.params, _random_action, episodes, k_pol)
    else:
        rew = random_transitions(k_rand, world.env, world.params, episodes, world.horizon)["reward"]
    ret = np.asarray(rew).sum(1)
    rec = {
        "done": f"random {ret.mean():.1f}",
        "random_return": float(ret.mean()),
        "random_return_std": float(ret.std()),
        **plan_record(world, plan_resolution, plan_rollouts, seed),
    }
    return rec


def plan_record(world, resolution: int, count: int, seed: int = 0) -> dict:
    """The planning check's reference return and the optimal and expected routes (None off the map)."""
    if not has_map(world):
        return {"plan_return": None, "optimal": None, "expected": None, "belief": None}
    chk = check_world(world, n=resolution, count=count, seed=seed)
    return {
        "plan_return": chk.reference_return,
        "optimal": chk.true._asdict(),
        "expected": None if chk.expected is None else chk.expected._asdict(),
        "belief": chk.belief,
    }


# ---------------------------------------------------------------------------------------
# routes


NO_ROUTE = {"goal": None, "ice": None, "sand": None, "pit_mean": None, "better": None}
"""The route of a seed on a world without a map: nothing to judge."""

STILL_STEPS = 10
"""A rollout is held still when its last this many steps stay within :data:`STILL_RADIUS` of where it ends."""
STILL_RADIUS = 0.25
"""Cells: a quarter of a cell, far below a step (a full push moves a cell; the worlds' noise is 0.05)."""


def held_still(world, path) -> bool:
    """Whether a rollout (positions ``[T+1, 2]``) ends short of the goal, out of the pits, with the agent
    stationary: its last :data:`STILL_STEPS` steps within :data:`STILL_RADIUS` cells of its end — an
    agent that stopped, not one that ran out of time on its way."""
    p = np.asarray(path, np.float64)
    end = p[-1]
    terrain = int(np.asarray(world.params.grid)[int(end[1]), int(end[0])])
    if terrain in (GOAL, PIT) or len(p) <= STILL_STEPS:
        return False
    return bool(np.max(np.linalg.norm(p[-STILL_STEPS - 1 :] - end, axis=-1)) < STILL_RADIUS)


def held_still_seeds(world, paths) -> int | None:
    """How many seeds are held still: most of their rollouts (a record's ``paths``, per seed a list of
    position arrays) :func:`held_still`. None on a world without a map."""
    if not has_map(world):
        return None
    return int(sum(np.mean([held_still(world, p) for p in seed]) > 0.5 for seed in paths))


def route_of(world, paths: list) -> dict:
    """The route one seed's greedy rollouts take: goal rate, terrain shares, pit distance, and
    ``better`` — whether it is the truly better route of the world's ``[expect]`` entries.

    * ``true_prefers = "ice"`` (nav1): most rollouts reach the goal with more steps on ice
      than on sand — the icy corridor;
    * ``wider_berth`` (nav2): most rollouts reach the goal and their mean distance to the pit
      is nearer the planned optimal route's than the route the person expects (filled in by
      :func:`better_route` from the reference job);
    * otherwise ``None``; on a world without a map, :data:`NO_ROUTE`.

    Each rollout goes through :func:`~mindgap.planning.terrain.route_stats` on its own, padded
    to the horizon (one array shape per world, whatever the number of rollouts), and the
    results are pooled as ``route_stats`` pools rollouts: terrain shares over all steps taken,
    goal rate and pit distance averaged over rollouts.
    """
    if not has_map(world):
        return dict(NO_ROUTE)
    horizon = int(world.params.horizon)
    per = []
    for p in paths:
        p = np.asarray(p, np.float32)[: horizon + 1]
        pos = np.repeat(p[-1:], horizon + 1, 0)
        pos[: len(p)] = p
        alive = np.arange(horizon) < len(p) - 1
        per.append(route_stats(world.params, pos[None], np.zeros((1, horizon), np.float32), alive[None]))
    steps = np.array([st.steps for st in per])
    weight = steps / max(steps.sum(), 1.0)
    pit = float(np.mean([st.pit_mean for st in per]))
    route = {
        "goal": float(np.mean([st.success for st in per])),
        "ice": float(weight @ [st.ice for st in per]),
        "sand": float(weight @ [st.sand for st in per]),
        "pit_mean": pit if pit < 1e5 else None,  # no pit in the world
    }
    want = expect(world).get("true_prefers")
    if want in ("ice", "sand"):
        other = "sand" if want == "ice" else "ice"
        route["better"] = bool(route["goal"] >= 0.5 and route[want] > route[other])
    else:
        route["better"] = None
    return route


def better_route(route: dict, reference: dict | None) -> bool | None:
    """``route["better"]``, or for worlds judged by pit distance, the comparison with the planned routes."""
    if route["better"] is not None or reference is None or route["pit_mean"] is None:
        return route["better"]
    expected = reference.get("expected")
    if expected is None:
        return None
    to_opt = abs(route["pit_mean"] - reference["optimal"]["pit_mean"])
    to_exp = abs(route["pit_mean"] - expected["pit_mean"])
    return bool(route["goal"] >= 0.5 and to_opt < to_exp)


def seed_route_share(rec: dict, reference: dict | None) -> float:
    """Fraction of a learner's seeds that take the truly better route (NaN where it is not defined)."""
    flags = [better_route(r, reference) for r in rec["routes"]]
    flags = [f for f in flags if f is not None]
    return float(np.mean(flags)) if flags else float("nan")


def route_means(routes: list[dict]) -> dict:
    """Goal rate, ice and sand shares and pit distance over seeds (NaN where no seed has one)."""

    def mean(name):
        v = [r[name] for r in routes if r.get(name) is not None]
        return float(np.mean(v)) if v else float("nan")

    return {
        "goal_rate": mean("goal"),
        "ice_share": mean("ice"),
        "sand_share": mean("sand"),
        "pit_mean": mean("pit_mean"),
    }


ROUTES = {"true_prefers": "the {} corridor", "wider_berth": "the shortcut past the pit"}


def route_name(world) -> str:
    """What ``better_route`` means in this world (e.g. 'the ice corridor' on nav1)."""
    want = expect(world)
    if "true_prefers" in want:
        return ROUTES["true_prefers"].format(want["true_prefers"])
    return ROUTES["wider_berth"] if "wider_berth" in want else "-"


# ---------------------------------------------------------------------------------------
# the learned reward's error


def _passable_grid(params, k: int = 3) -> np.ndarray:
    """[N, 2] positions, k×k per cell where episodes run: every cell but walls; with episodes that end
    at the goal or a pit (not a fixed horizon), not those either."""
    grid = np.asarray(params.grid)
    ends = float(params.fixed_horizon) < 0.5
    rows, cols = np.nonzero((grid != WALL) & ~(ends & ((grid == GOAL) | (grid == PIT))))
    off = (np.arange(k) + 0.5) / k
    ox, oy = np.meshgrid(off, off)
    pts = np.stack([cols[:, None] + ox.ravel(), rows[:, None] + oy.ravel()], -1)
    return pts.reshape(-1, 2).astype(np.float32)


@jax.jit
def _expected_true_reward(params, pos, act, key):
    """E_{s' ~ T}[r(s, a, s')] per (position, action), by :data:`REWARD_DRAWS` draws of the true next position."""

    def one(p, a, k):
        s = TerrainState(p, jnp.zeros((), jnp.int32), jnp.zeros((), bool))

        def draw(kk):
            return true_reward(s, a, s._replace(pos=sample_next(kk, params, p, a)), params)

        return jax.vmap(draw)(jax.random.split(k, REWARD_DRAWS)).mean()

    keys = jax.random.split(key, pos.shape[0])
    return jax.vmap(one)(pos, act, keys)


def reward_grid(world, k: int = 3, seed: int = 0, episodes: int = 50):
    """Where the reward error is measured: observations, actions, next observations and the true expected reward.

    On a terrain world: k×k points in every cell that is neither wall, goal nor pit, times
    the 8 full pushes of :func:`~mindgap.planning.terrain.compass_actions` (every pair; the
    next observation is the observation itself, the learned rewards being functions of the
    state and action). On any other world: every step of ``episodes`` episodes of a
    uniformly random policy, with the world's reward averaged over fresh next states
    (:func:`random_transitions`).

    Returns:
        ``(obs [N, d], act [N, a], next_obs [N, d], r [N])``.
    """
    if not has_map(world):
        tr = random_transitions(rng.key(seed), world.env, world.params, episodes, world.horizon)
        alive = np.asarray(tr["alive"]).reshape(-1)
        flat = {n: np.asarray(v).reshape(alive.size, -1)[alive] for n, v in tr.items()}
        return flat["obs"], flat["act"], flat["next_obs"], flat["expected_reward"][:, 0].astype(np.float64)
    pts = _passable_grid(world.params, k)
    acts = compass_actions(8)
    pos = np.repeat(pts, len(acts), 0)
    act = np.tile(acts, (len(pts), 1))
    r = _expected_true_reward(world.params, jnp.asarray(pos), jnp.asarray(act), rng.key(seed))
    state = TerrainState(jnp.asarray(pos), jnp.zeros(len(pos), jnp.int32), jnp.zeros(len(pos), bool))
    obs = observe(state, world.params)
    return obs, jnp.asarray(act), obs, np.asarray(r, np.float64)


def _zscore(x: np.ndarray) -> np.ndarray:
    sd = x.std(-1, keepdims=True)
    return (x - x.mean(-1, keepdims=True)) / np.where(sd > 0, sd, 1.0)


def reward_error(world, reward_fn, params) -> np.ndarray:
    """Per seed, the L2 (RMS) error of the normalised learned reward against the true reward.

    On the points of :func:`reward_grid`, both the learned ``r̂(s, a, s')`` (``reward_fn`` at
    the seed's parameters; the posterior mean for PrefBias, the ensemble mean for PEBBLE)
    and the true ``r̄(s, a) = E_{s'~T}[r(s, a, s')]`` (the world's reward under its true
    dynamics, by Monte Carlo) are z-scored over the points — ``z(x) = (x − mean x) / std x``
    — and the error is ``sqrt(mean (z(r̂) − z(r̄))²)``. Preferences fix a reward only up to an
    offset and a scale, which the z-score removes; the error equals ``sqrt(2 (1 − ρ))`` with ρ
    the Pearson correlation over the points: 0 for the true reward up to a positive affine
    map, √2 ≈ 1.41 for an unrelated one, 2 for the reversed one.

    Args:
        params: the learned reward's parameters with a leading seed axis.

    Returns:
        [seeds] float.
    """
    return reward_error_on(*reward_grid(world), reward_fn, params)


def reward_error_on(obs, act, nxt, truth, reward_fn, params) -> np.ndarray:
    """:func:`reward_error` on given points: transitions ``(obs, act, nxt)`` and the true reward ``truth`` [N]."""
    learned = np.asarray(jax.vmap(lambda p: reward_fn(p, obs, act, nxt))(params), np.float64)
    diff = _zscore(learned) - _zscore(np.asarray(truth, np.float64))[None]
    return np.sqrt((diff**2).mean(-1))
