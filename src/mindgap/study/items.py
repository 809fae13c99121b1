"""The items a study shows, built once from its study file and stored with the answers.

An item is either a *demonstration* to rate (tabular domains: ``states [n + 1]``,
``actions [n]``) or a *pair* of segments to compare (terrain worlds: each segment
``obs``, ``act``, ``next_obs`` ``[L, 2]`` and ``mask [L]``, the layout of
:class:`~mindgap.data.segments.Segments`). Items are plain JSON so the store keeps
exactly what was shown: an export never depends on regenerating them.

Sources:

* ``coffee-demos`` — the nine demonstrations of the coffee study (§2.3.2, Fig. 11);
* ``random`` (grid7) — ``count`` random-policy demonstrations of ``length`` steps;
* ``random-pairs`` (terrain) — ``pairs`` pairs of segments of ``segment`` steps, each a
  persistent random walk from a random free cell under the true dynamics; with
  ``sanity_pairs: N`` N extra pairs whose answer is obvious under the world's reward
  (the best and the worst of a pool) become sanity checks;
* ``belief-pairs`` (terrain, expectation) — the same start and actions played once under
  the true dynamics and once under a belief (``domain.belief``); which side is the truth
  is drawn per pair and kept in ``truth``;
* ``file`` — pairs from a preferences file (labels ignored), see :mod:`.prefs_file`;
* ``live`` — a training run posts its queries (:mod:`.live`); a driving study may show fixed
  items first (``items.fixed``: the bias-validation question and the sanity item of §4.4.2);
* driving (:mod:`.driving`) — ``live``, or ``file``: rollouts to rate from a rollouts file
  (:mod:`mindgap.data.rollouts_file`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .config import Study, StudyFileError


@dataclasses.dataclass(frozen=True)
class Item:
    """One page of the study: ``kind`` ``demo`` or ``pair``; ``data`` JSON-ready; optional sanity rule."""

    id: str
    kind: str
    data: dict
    sanity: dict | None = None

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @staticmethod
    def from_dict(d: dict) -> Item:
        return Item(d["id"], d["kind"], d["data"], d.get("sanity"))


def build_items(study: Study) -> list[Item]:
    """The study's fixed items (none for a live study), with its sanity rules attached.

    Raises:
        StudyFileError: a sanity rule names an unknown item, or the source's options are wrong.
    """
    src = study.items["source"]
    if src == "live":
        if study.domain["name"] == "gym":  # refuse an env that cannot be made or drawn before anyone is invited
            from ..plotting.animation import check_observation_frames

            world = load_study_world(study)
            try:
                check_observation_frames(world)
            except ValueError as e:
                raise StudyFileError(f"domain.env: {e}") from None
        if study.domain["name"] != "driving":
            return []
    if study.domain["name"] == "driving":  # §4.4.2: fixed items before live queries, or rollouts to rate
        from .driving import fixed_items, rollout_items

        items = fixed_items(study) if src == "live" else rollout_items(study)
    elif src == "coffee-demos":
        items = _coffee(study)
    elif src == "random":
        items = _grid(study)
    elif src in ("random-pairs", "belief-pairs"):
        items = _terrain_pairs(study)
    else:
        items = _file_pairs(study)
    by_id = {it.id: it for it in items}
    for s in study.sanity:
        if s.item not in by_id:
            raise StudyFileError(f"sanity item {s.item!r} is not one of the study's items ({', '.join(by_id)})")
        by_id[s.item] = dataclasses.replace(by_id[s.item], sanity={"rule": s.rule, "value": s.value})
    return list(by_id.values())


def _opt(study: Study, key: str, default, kind=int):
    v = study.items.get(key, default)
    if kind is int and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
        raise StudyFileError(f"items.{key} must be a positive integer, got {v!r}")
    return v


def _coffee(study: Study) -> list[Item]:
    from ..envs.coffee_demos import study_traces

    traces = study_traces(int(study.items.get("sanity_seed", 0)))
    return [Item(t.name, "demo", {"states": list(t.states), "actions": list(t.actions)}) for t in traces]


def _grid(study: Study) -> list[Item]:
    import jax

    from ..feedback.demos import random_demonstrations
    from ..planning.grid_task import make_grid

    size = int(study.domain.get("size", 7))
    count, length = _opt(study, "count", 12), _opt(study, "length", 10)
    task = make_grid(size, "true", seed=int(study.items.get("seed", 0)))
    demos = random_demonstrations(jax.random.key(int(study.items.get("seed", 0))), task.mdp, count, length)
    states, actions = np.asarray(demos.states), np.asarray(demos.actions)
    from ..envs.grid import move_targets  # the last shown state: where the final action is meant to go

    items = []
    for i in range(count):
        s, a = states[i].tolist(), actions[i].tolist()
        end = int(move_targets(size)[s[-1], a[-1]])
        items.append(Item(f"demo-{i:02d}", "demo", {"states": s + [end], "actions": a, "size": size}))
    return items


def load_study_world(study: Study):
    """The world a study shows: a terrain world (a named world or a file relative to the study
    file), or a gymnasium env (``domain.env``, ``gym:ID[,key=value...]``)."""
    if study.domain["name"] == "driving":
        from .driving import driving_world

        return driving_world(study.domain)
    if study.domain["name"] == "gym":
        from ..envs.interface import EnvError
        from ..envs.resolve import resolve_env

        try:
            return resolve_env(study.domain["env"])
        except EnvError as e:
            raise StudyFileError(f"domain.env: {e}") from None
    from ..envs.terrain import NAMED_WORLDS, load_world

    name = study.domain["world"]
    if name not in NAMED_WORLDS and not Path(name).is_absolute():
        name = str(Path(study.base_dir) / name)
    try:
        return load_world(name)
    except ValueError as e:
        raise StudyFileError(f"domain.world: {e}") from None


def random_segments(key, params, count: int, length: int, belief_params=None, starts=None, actions=None):
    """``count`` segments of persistent random walks from random free cells.

    Each walk keeps a heading drawn per segment (actions ``0.8 (cos θ, sin θ) + N(0, 0.3²)``,
    clipped to [−1, 1]) so that segments go somewhere a person can judge. With
    ``belief_params`` the positions follow those dynamics instead of the true ones;
    ``starts [K, 2]`` and ``actions [K, L, 2]`` replay given walks.

    Returns:
        dict of numpy arrays ``obs, act, next_obs [K, L, 2]``, ``mask [K, L]``.
    """
    import jax
    import jax.numpy as jnp

    from ..envs.terrain.layout import GOAL, PIT, WALL

    k_start, k_head, k_noise, k_step = jax.random.split(key, 4)
    if starts is None:
        grid = np.asarray(params.grid)
        free = np.argwhere((grid != WALL) & (grid != PIT) & (grid != GOAL))  # (row, col)
        cells = free[np.asarray(jax.random.randint(k_start, (count,), 0, len(free)))]
        jitter = np.asarray(jax.random.uniform(k_head, (count, 2), minval=0.2, maxval=0.8))
        starts = cells[:, ::-1] + jitter
    if actions is None:
        theta = jax.random.uniform(jax.random.fold_in(k_head, 1), (count, 1), maxval=2 * np.pi)
        heading = 0.8 * jnp.concatenate([jnp.cos(theta), jnp.sin(theta)], -1)[:, None, :]
        actions = jnp.clip(heading + 0.3 * jax.random.normal(k_noise, (count, length, 2)), -1.0, 1.0)
    moves = params if belief_params is None else belief_params
    keys = jax.random.split(k_step, count)
    obs, nxt, live = _walks(keys, jnp.asarray(starts, jnp.float32), jnp.asarray(actions, jnp.float32), params, moves)
    return {
        "obs": np.asarray(obs),
        "act": np.asarray(actions, np.float32),
        "next_obs": np.asarray(nxt),
        "mask": np.asarray(live),
    }


def _walks_impl(keys, starts, actions, params, moves):
    """Play ``actions [K, L, 2]`` from ``starts [K, 2]`` with the dynamics of ``moves``; observe with ``params``."""
    import jax
    import jax.numpy as jnp

    from ..envs.terrain import TerrainState, observe, step

    def walk(k, s0, acts):
        state = TerrainState(s0, jnp.zeros((), jnp.int32), jnp.zeros((), bool))

        def one(st, xs):
            kk, a = xs
            out = step(kk, st, a, moves)
            return out.state, (observe(st, params), observe(out.state, params), ~st.done)

        return jax.lax.scan(one, state, (jax.random.split(k, acts.shape[0]), acts))[1]

    return jax.vmap(walk)(keys, starts, actions)


def _walks(*args):
    import jax

    global _walks_jit
    if _walks_jit is None:
        _walks_jit = jax.jit(_walks_impl)
    return _walks_jit(*args)


_walks_jit = None


def segment_dict(seg: dict, i: int) -> dict:
    """Segment ``i`` of a batch as JSON-ready lists (rounded to 5 decimals)."""
    return {
        "obs": np.round(seg["obs"][i], 5).tolist(),
        "act": np.round(seg["act"][i], 5).tolist(),
        "next_obs": np.round(seg["next_obs"][i], 5).tolist(),
        "mask": [bool(x) for x in seg["mask"][i]],
    }


def true_returns(params, seg: dict) -> np.ndarray:
    """Each segment's return under the world's own reward (the ordinary B-Pref teacher's score)."""
    import jax
    import jax.numpy as jnp

    from ..data.segments import Segments
    from ..envs.terrain import TERRAIN_ENV
    from ..teachers.preference import TeacherConfig, segment_scores

    s = Segments(*(jnp.asarray(seg[k]) for k in ("obs", "act", "next_obs", "mask")))
    scores = jax.jit(segment_scores, static_argnames=("env", "cfg"))
    return np.asarray(scores(s, TERRAIN_ENV, params, None, cfg=TeacherConfig(use_belief=False)))


def _terrain_pairs(study: Study) -> list[Item]:
    import jax

    world = load_study_world(study)
    n, length = _opt(study, "pairs", 10), _opt(study, "segment", 10)
    key = jax.random.key(int(study.items.get("seed", 0)))
    if study.items["source"] == "belief-pairs":
        try:
            belief = world.belief(study.domain.get("belief"))
        except ValueError as e:
            raise StudyFileError(f"domain.belief: {e}") from None
        k_true, k_bel, k_side = jax.random.split(key, 3)
        truth = random_segments(k_true, world.params, n, length)
        starts = np.asarray([world_pos(world.params, o[0]) for o in truth["obs"]])
        believed = random_segments(k_bel, world.params, n, length, belief, starts=starts, actions=truth["act"])
        sides = np.asarray(jax.random.bernoulli(k_side, 0.5, (n,)))
        items = []
        for i in range(n):
            a, b = (truth, believed) if sides[i] else (believed, truth)
            data = {"a": segment_dict(a, i), "b": segment_dict(b, i), "truth": "a" if sides[i] else "b"}
            items.append(Item(f"pair-{i:02d}", "pair", data))
        return items
    n_sanity = int(study.items.get("sanity_pairs", 0))
    segs = random_segments(key, world.params, 2 * n + 20 * n_sanity, length)  # one compiled program for all
    items = [
        Item(f"pair-{i:02d}", "pair", {"a": segment_dict(segs, i), "b": segment_dict(segs, n + i)}) for i in range(n)
    ]
    if n_sanity:
        pool = {k: v[2 * n :] for k, v in segs.items()}
        order = np.argsort(true_returns(world.params, pool))
        for j in range(n_sanity):
            best, worst = int(order[-1 - j]), int(order[j])
            flip = j % 2 == 1  # the obvious answer is not always on the same side
            a, b = (worst, best) if flip else (best, worst)
            items.append(
                Item(
                    f"sanity-{j}",
                    "pair",
                    {"a": segment_dict(pool, a), "b": segment_dict(pool, b)},
                    {"rule": "answer", "value": "b" if flip else "a"},
                )
            )
    return items


def world_pos(params, obs) -> np.ndarray:
    """Position (x, y) in cells of an observation in [−1, 1]² (inverse of ``observe``)."""
    h, w = np.asarray(params.grid).shape
    return (np.asarray(obs) + 1.0) * 0.5 * np.array([w, h])


def _file_pairs(study: Study) -> list[Item]:
    from .prefs_file import read_preferences

    path = Path(study.items["path"])
    if not path.is_absolute():
        path = Path(study.base_dir) / path
    prefs = read_preferences(path, require_labels=False)
    return [
        Item(r.get("item") or f"pair-{i:02d}", "pair", {"a": r["a"], "b": r["b"]}) for i, r in enumerate(prefs.records)
    ]
