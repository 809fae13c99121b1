"""The optimisation loop shared by the rating-based learners.

Every learner supplies a pure ``step(state, key, data) -> (state, objective)`` for one
restart; ``data`` (the world, the ratings) is an argument, not a closure, so one
compiled chunk serves every fit of the same shapes. This module vmaps the step over
restarts, runs ``check_every`` steps per jitted chunk (``lax.scan``), and between
chunks, on the host: updates the progress bar,
records a snapshot for the learning curves, stops a restart whose objective went
non-finite, and tests convergence (Algorithm 1, line 3: the objective's chunk mean
changed by less than ``tol`` per observation, or the iteration cap).

With ``keep < R`` it screens: after ``screen_iter`` iterations only the ``keep``
restarts with the highest objective go on. Which basin a restart falls into shows
long before it converges, so many cheap starts buy the reliability of many full fits.
Until then the R restarts run in groups of ``keep`` through the program that then serves
the survivors: one compiled chunk per fit rather than one for R and one for ``keep``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm


@dataclass(frozen=True)
class RestartSchedule:
    """How many restarts run, how they are screened and when they stop (base of the learners' configs)."""

    max_iter: int = 1500
    """Iteration cap (MaxIter)."""
    check_every: int = 50
    """Iterations between convergence tests (and learning-curve points)."""
    tol: float = 1e-4
    """Converged when the objective's chunk mean moves less than this per rating."""
    restarts: int = 32
    """Random restarts run side by side; the highest objective wins."""
    keep: int = 4
    """Restarts that go on after screening (the rest stop at ``screen_iter``)."""
    screen_iter: int = 300
    """Iterations before screening restarts by their objective."""

    def __post_init__(self):
        for name in ("max_iter", "check_every", "restarts", "keep"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")


@dataclass
class RestartRun:
    """What a multi-restart optimisation produced.

    Attributes:
        states: final states of the surviving restarts (leading axis ``[R']``).
        objective: ``[R']`` their final chunk-mean objective (−inf for a failed restart).
        ids: ``[R']`` which of the initial restarts survived screening.
        iterations: iterations run.
        converged: ``[R']`` bool.
        history: per chunk, ``(iteration, ids, snapshot, objective)`` for the restarts alive then.
        dropped: ``{restart id: (snapshot, objective)}`` for restarts dropped by screening.
    """

    states: Any
    objective: np.ndarray
    ids: np.ndarray
    iterations: int
    converged: np.ndarray
    history: list = field(default_factory=list)
    dropped: dict = field(default_factory=dict)
    elapsed: list = field(default_factory=list)
    """Seconds since the start at each history entry (compilation included)."""

    def trace(self, restart_id: int):
        """``(iterations, snapshots)`` of one initial restart along the run."""
        its, snaps = [], []
        for it, ids, snap, _ in self.history:
            pos = np.flatnonzero(ids == restart_id)
            if len(pos):
                its.append(it)
                snaps.append(jax.tree_util.tree_map(lambda x: x[pos[0]], snap))
        return np.array(its), snaps

    @property
    def best(self) -> int:
        """Index of the restart with the highest objective."""
        if not np.isfinite(self.objective).any():
            raise FloatingPointError("every restart diverged (objective not finite); lower the learning rate")
        return int(np.argmax(np.where(np.isfinite(self.objective), self.objective, -np.inf)))


@lru_cache(maxsize=64)
def _compiled_chunk(step: Callable):
    def chunk(state, keys, data):
        state, obj = jax.lax.scan(lambda s, k: step(s, k, data), state, keys)
        return state, obj.mean()

    return jax.jit(jax.vmap(chunk, in_axes=(0, 0, None)))


def run_restarts(
    step: Callable,
    init_states,
    key,
    data,
    *,
    max_iter: int,
    check_every: int,
    tol: float,
    n_obs: int,
    snapshot: Callable = lambda s: s,
    desc: str = "fit",
    progress: bool = True,
    keep: int | None = None,
    screen_iter: int = 0,
) -> RestartRun:
    """Run ``step`` for every restart until all converge or ``max_iter`` is reached.

    Args:
        step: ``(state, key, data) -> (state, objective)`` for a single restart; pure
            and hashable (build it once per configuration).
        init_states: pytree with a leading ``[R]`` restart axis.
        key: PRNG key.
        data: pytree of arrays shared by all restarts.
        max_iter: iteration cap (rounded up to a multiple of ``check_every``).
        check_every: iterations per jitted chunk (and per convergence test).
        tol: convergence threshold on the change of the chunk-mean objective divided by ``n_obs``.
        n_obs: number of observations (ratings, demonstrations) the objective sums over.
        snapshot: picks what to keep of a state for the history.
        desc: progress-bar label.
        progress: show a progress bar.
        keep: restarts kept after screening (``None``: all).
        screen_iter: iterations before screening (rounded up to a multiple of ``check_every``).
    """
    chunk = _compiled_chunk(step)
    states = init_states
    n_restarts = jax.tree_util.tree_leaves(init_states)[0].shape[0]
    prev = np.full(n_restarts, np.nan)
    objective = np.full(n_restarts, -np.inf)
    converged = np.zeros(n_restarts, bool)
    failed = np.zeros(n_restarts, bool)
    ids = np.arange(n_restarts)
    history = [(0, ids, jax.device_get(snapshot(states)), np.full(n_restarts, np.nan))]
    dropped = {}
    screening = keep is not None and keep < n_restarts
    it = 0
    start = time.perf_counter()
    elapsed = [0.0]
    with tqdm(total=max_iter, desc=desc, disable=not progress, leave=False) as bar:
        while it < max_iter and not (converged | failed).all():
            if screening and it >= screen_iter:
                order = np.argsort(-np.where(np.isfinite(objective), objective, -np.inf), kind="stable")
                survive = np.sort(order[:keep])
                snap = jax.device_get(snapshot(states))
                for pos in order[keep:]:
                    dropped[int(ids[pos])] = (jax.tree_util.tree_map(lambda x: x[pos], snap), objective[pos])
                states = jax.tree_util.tree_map(lambda x: x[survive], states)
                ids, prev, objective = ids[survive], prev[survive], objective[survive]
                converged, failed = converged[survive], failed[survive]
                n_restarts = len(survive)
                screening = False
            n = check_every  # one chunk length, one compiled program
            key, sub = jax.random.split(key)
            keys = jax.random.split(sub, (n_restarts, n))
            new_states, obj = _in_groups(chunk, states, keys, data, keep if screening else n_restarts)
            obj = np.asarray(obj, np.float64)
            bad = ~np.isfinite(obj) | ~_all_finite(new_states)
            failed |= bad
            # a failed restart keeps its last finite state and is frozen there
            states = jax.tree_util.tree_map(
                lambda new, old: jnp.where(_expand(jnp.asarray(failed), new), old, new), new_states, states
            )
            objective = np.where(failed, -np.inf, obj)
            delta = np.abs(obj - prev) / max(n_obs, 1)
            converged |= (delta < tol) & ~failed
            prev = obj
            it += n
            history.append((it, ids, jax.device_get(snapshot(states)), objective.copy()))
            elapsed.append(time.perf_counter() - start)
            bar.update(n)
            bar.set_postfix(best=f"{np.max(objective):.4g}", done=f"{int((converged | failed).sum())}/{n_restarts}")
    return RestartRun(states, objective, ids, it, converged, history, dropped, elapsed)


def _in_groups(chunk, states, keys, data, size: int):
    """``chunk`` over the restart axis in groups of ``size`` (the last one filled up with copies of the
    first restart, whose results are dropped): the same results as one call, through the program of
    ``size`` restarts."""
    r = keys.shape[0]
    if size >= r:
        return chunk(states, keys, data)
    pad = -r % size
    if pad:
        fill = np.concatenate([np.arange(r), np.zeros(pad, int)])
        states, keys = jax.tree_util.tree_map(lambda x: x[fill], states), keys[fill]
    outs = [
        chunk(jax.tree_util.tree_map(lambda x, i=i: x[i : i + size], states), keys[i : i + size], data)
        for i in range(0, r + pad, size)
    ]
    new = jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs)[:r], *[o[0] for o in outs])
    return new, jnp.concatenate([o[1] for o in outs])[:r]


def _expand(mask, like):
    return mask.reshape(mask.shape + (1,) * (like.ndim - 1))


def _all_finite(states) -> np.ndarray:
    leaves = [x for x in jax.tree_util.tree_leaves(states) if jnp.issubdtype(x.dtype, jnp.floating)]
    ok = np.ones(leaves[0].shape[0], bool) if leaves else np.ones(1, bool)
    for x in leaves:
        ok &= np.asarray(jnp.isfinite(x.reshape(x.shape[0], -1)).all(-1))
    return ok
