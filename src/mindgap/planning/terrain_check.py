"""What a world's optimal and expected routes look like, and whether they are the intended ones.

``check_world`` plans under the true table (the optimal route, and a near-optimal
reference return for learners) and under a belief (the route the person expects, rolled
out in the world as the person imagines it), then tests the world file's ``[expect]``
entries (§3.2's required behaviours) on the rollouts.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..envs.terrain.dynamics import move_model
from ..envs.terrain.layout import WALL
from ..envs.terrain.world import TerrainWorld
from .terrain import RouteStats, plan, plan_action, rollouts, route_stats


class Expectation(NamedTuple):
    """One required behaviour: what it says, whether it held, what was measured."""

    text: str
    held: bool
    measured: str


class PlanningCheck(NamedTuple):
    """Result of :func:`check_world`."""

    world: str
    belief: str | None
    true: RouteStats
    expected: RouteStats | None
    expected_in_truth: RouteStats | None
    true_paths: list[np.ndarray]
    expected_paths: list[np.ndarray]
    expectations: list[Expectation]

    @property
    def reference_return(self) -> float:
        """Mean true return of the planned policy: a near-optimal bar for learners."""
        return self.true.ret

    @property
    def passed(self) -> bool:
        return all(e.held for e in self.expectations)


def _paths(positions, alive, count: int) -> list[np.ndarray]:
    pos, alive = np.asarray(positions), np.asarray(alive)
    out = []
    for i in range(min(count, len(pos))):
        n = int(alive[i].sum())
        out.append(pos[i, : n + 1])
    return out


def check_world(
    world: TerrainWorld,
    belief: str | None = None,
    n: int = 4,
    count: int = 200,
    seed: int = 0,
    draw: int = 12,
) -> PlanningCheck:
    """Plan under the truth and under ``belief`` (default: the world's first), roll out, test ``[expect]``.

    Args:
        n: sub-cells per cell side of the discretisation.
        count: rollouts per plan for the statistics.
        draw: rollouts kept for drawing.
    """
    k_true, k_belief, k_real = jax.random.split(rng.key(seed), 3)
    p_true = plan(world.params, n)
    pos, rew, alive = rollouts(k_true, world.params, plan_action, count, p_true)
    true = route_stats(world.params, pos, rew, alive)
    true_paths = _paths(pos, alive, draw)
    expected, expected_paths, in_truth, bname = None, [], None, None
    if world.beliefs:
        bname = belief or next(iter(world.beliefs))
        bparams = world.belief(bname)
        p_b = plan(bparams, n)
        pos, rew, alive = rollouts(k_belief, bparams, plan_action, count, p_b)
        expected = route_stats(bparams, pos, rew, alive)
        expected_paths = _paths(pos, alive, draw)
        # the policy the person expects, run in the real world: what obeying them would cost
        in_truth = route_stats(world.params, *rollouts(k_real, world.params, plan_action, count, p_b))
    return PlanningCheck(
        world.name,
        bname,
        true,
        expected,
        in_truth,
        true_paths,
        expected_paths,
        evaluate(world.expect, true, expected),
    )


def evaluate(expect: dict, true: RouteStats, expected: RouteStats | None) -> list[Expectation]:
    """Test a world's ``[expect]`` entries against the two routes' statistics."""
    out = []
    for key, route, stats in (("true_prefers", "optimal", true), ("belief_prefers", "expected", expected)):
        if key not in expect:
            continue
        want = expect[key]
        other = "sand" if want == "ice" else "ice"
        if stats is None:
            out.append(Expectation(f"{route} route mostly on {want}", False, "no belief to plan with"))
            continue
        share = {"ice": stats.ice, "sand": stats.sand}
        out.append(
            Expectation(
                f"{route} route spends more steps on {want} than on {other}",
                share[want] > share[other],
                f"{share[want]:.0%} on {want}, {share[other]:.0%} on {other}",
            )
        )
    if "wider_berth" in expect:
        margin = float(expect["wider_berth"])
        if expected is None:
            out.append(Expectation("expected route keeps farther from pits", False, "no belief to plan with"))
        else:
            gap = expected.pit_mean - true.pit_mean
            out.append(
                Expectation(
                    f"expected route keeps at least {margin:g} cell farther from pits on average",
                    gap >= margin,
                    f"{expected.pit_mean:.2f} vs {true.pit_mean:.2f} cells (+{gap:.2f})",
                )
            )
    return out


def noise_field(params, k: int = 8) -> np.ndarray:
    """[H·k, W·k] noise scale σ(s) of a step from each position (NaN in walls).

    The Gaussian part of the step model, including the pit term; stuck probabilities are
    per terrain and shown by the map itself.
    """
    grid = np.asarray(params.grid)
    h, w = grid.shape
    ys, xs = np.meshgrid((np.arange(h * k) + 0.5) / k, (np.arange(w * k) + 0.5) / k, indexing="ij")
    pts = jnp.asarray(np.stack([xs.ravel(), ys.ravel()], -1), jnp.float32)
    sigma = jax.jit(jax.vmap(lambda p: move_model(params, p, jnp.zeros(2))[1]))(pts)
    field = np.asarray(sigma).reshape(h * k, w * k)
    return np.where(np.repeat(np.repeat(grid == WALL, k, 0), k, 1), np.nan, field)
