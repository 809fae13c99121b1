"""What a world's optimal and expected routes look like, and whether they are the intended ones.

``check_world`` plans under the true table (the optimal route, and a near-optimal
reference return for learners) and under a belief (the route the person expects, rolled
out in the world as the person imagines it), then tests the world file's ``[expect]``
entries (§3.2's required behaviours) on the rollouts. It also drives both plans in the real
world and scores them as the preference teacher would (Σ_t [r_H + log T_H], Eq. 3.2): a person
who prefers the expected route in those terms misleads a learner that ignores her belief.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..data.segments import Segments
from ..envs.terrain.dynamics import move_model
from ..envs.terrain.layout import WALL
from ..envs.terrain.params import TerrainState
from ..envs.terrain.world import TERRAIN_ENV, TerrainWorld, observe
from ..planning.terrain import Plan, RouteStats, plan, plan_action, rollouts, route_stats
from ..teachers.preference import TeacherConfig, segment_scores


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
    person_scores: dict | None = None
    """The person's mean Σ_t [r_H + log T_H] of the ``optimal`` and ``expected`` plans as the robot
    really drives them (:func:`person_score`); None without a belief."""

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
    true_rollouts = (pos, alive)
    expected, expected_paths, in_truth, bname, scores = None, [], None, None, None
    if world.beliefs:
        bname = belief or next(iter(world.beliefs))
        bparams = world.belief(bname)
        p_b = plan(bparams, n)
        pos, rew, alive = rollouts(k_belief, bparams, plan_action, count, p_b)
        expected = route_stats(bparams, pos, rew, alive)
        expected_paths = _paths(pos, alive, draw)
        # the policy the person expects, run in the real world: what obeying them would cost
        pos, rew, alive = rollouts(k_real, world.params, plan_action, count, p_b)
        in_truth = route_stats(world.params, pos, rew, alive)
        scores = {
            "optimal": person_score(world.params, bparams, p_true, *true_rollouts),
            "expected": person_score(world.params, bparams, p_b, pos, alive),
        }
    return PlanningCheck(
        world.name,
        bname,
        true,
        expected,
        in_truth,
        true_paths,
        expected_paths,
        evaluate(world.expect, true, expected, scores, in_truth),
        scores,
    )


def person_score(world_params, belief_params, p: Plan, positions, alive) -> float:
    """The preference teacher's mean score Σ_t [r_H + log T_H] (Eq. 3.2, floored as
    :class:`~mindgap.teachers.preference.TeacherConfig` floors log T_H) of real-world rollouts of plan ``p``.

    ``positions [N, T+1, 2]`` and ``alive [N, T]`` as :func:`~.terrain.rollouts` returns them.
    """
    obs = observe(TerrainState(positions, jnp.zeros((), jnp.int32), False), world_params)
    act = jax.vmap(jax.vmap(lambda q: plan_action(p, q)))(positions[:, :-1])
    seg = Segments(obs[:, :-1], act, obs[:, 1:], jnp.asarray(alive, bool))
    return float(segment_scores(seg, TERRAIN_ENV, world_params, belief_params, TeacherConfig()).mean())


def evaluate(
    expect: dict,
    true: RouteStats,
    expected: RouteStats | None,
    person_scores: dict | None = None,
    in_truth: RouteStats | None = None,
) -> list[Expectation]:
    """Test a world's ``[expect]`` entries against the two routes' statistics (and the person's scores;
    ``in_truth``: the expected policy run in the real world)."""
    out = []
    if "obeying" in expect:  # what following the person's expected policy does in the real world
        arrives = expect["obeying"] == "arrives"
        text = f"the expected policy run in the real world {'reaches' if arrives else 'misses'} the goal in most rollouts"
        if in_truth is None:
            out.append(Expectation(text, False, "no belief to plan with"))
        else:
            held = in_truth.success >= 0.5 if arrives else in_truth.success < 0.5
            out.append(Expectation(text, held, f"goal {in_truth.success:.0%}, return {in_truth.ret:.1f}"))
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
    if expect.get("person_prefers") == "expected":
        text = "the person scores the expected route above the optimal one, both as the robot drives them"
        if person_scores is None:
            out.append(Expectation(text, False, "no belief to plan with"))
        else:
            opt, exp = person_scores["optimal"], person_scores["expected"]
            out.append(Expectation(text, exp > opt, f"Σ[r + log T_H] {exp:+.1f} vs {opt:+.1f}"))
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
