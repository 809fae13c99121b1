"""The maximum-likelihood check: a planted belief is recovered; a deterministic truth leaves it unidentified."""

import dataclasses
import tomllib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.design.belief_fit import (
    FLAT_NATS,
    Z_MARGIN,
    BeliefFit,
    Estimate,
    Profile,
    Queries,
    fit_world,
    imprecise_moves,
    log_likelihood,
    verdict,
)
from mindgap.design.design_check import DesignConfig
from mindgap.envs.terrain import world_from_dict
from mindgap.envs.terrain.dynamics import log_prob_pos
from mindgap.envs.terrain.layout import TERRAINS
from mindgap.envs.terrain.world import potential
from mindgap.planning.identifiability import parameter_slots
from mindgap.teachers.preference import TeacherConfig

# An icy shortcut to the goal and a sandy detour, a fixed horizon and a state-form reward. The walls
# slide: under the default bump rule a push into a wall leaves the robot where it was, a second
# outcome on the ice even where the truth never sticks (docs/experiments/identifiability.md).
WORLD = """
name = "corridors"
horizon = 40
episode_ends = false
layout = '''
##########
#G~~~~~~S#
#.######.#
#::::::::#
##########
'''
[rewards]
form = "state"
step = -1.0
goal = 1.0
[dynamics]
walls = "slide"
ice = {{ stuck = {stuck} }}
sand = {{ speed = 0.5 }}
[beliefs.human]
ice = {{ stuck = 0.7 }}
"""
CFG = DesignConfig(n=2, draws=8, budget=800)


def _world(stuck: float):
    return world_from_dict(tomllib.loads(WORLD.format(stuck=stuck)))


def test_a_planted_belief_is_recovered_and_told_from_the_truth():
    fit = fit_world(_world(0.1), cfg=CFG)
    (stuck,) = [e for e in fit.parameters if e.name == "ice.stuck"]
    assert (stuck.truth, stuck.belief) == pytest.approx((0.1, 0.7)) and stuck.stderr < 0.2
    assert stuck.z_belief <= Z_MARGIN <= stuck.z_truth  # within 3 SE of the belief, at least 3 SE from the truth
    assert verdict(fit, "ice.stuck") == "recovered"
    # the likelihood ratio agrees: the grid points beside the truth's 0.1 lie more than Z²/2 nats below the
    # maximum, the best one beside the belief's 0.7 less
    prof = fit.profile
    assert prof.name == "ice.stuck" and prof.span > FLAT_NATS
    assert prof.loglik[prof.grid < 0.2].max() < -(Z_MARGIN**2) / 2 < prof.loglik[np.abs(prof.grid - 0.7) < 0.06].max()
    # the unbiased parameters of the ice, and its reward (−1 a step, the floor's held at −1), within 3 SE
    ice = [e for e in fit.parameters + fit.rewards if e.name in ("ice.speed", "ice.noise", "ice")]
    assert len(ice) == 3 and all(e.z_belief <= Z_MARGIN for e in ice)


def test_a_deterministic_truth_leaves_the_belief_unidentified():
    """Every step on the ice moves: log(1 − p) is the same on all of them, and the ice's reward absorbs it."""
    fit = fit_world(_world(0.0), cfg=CFG)
    (stuck,) = [e for e in fit.parameters if e.name == "ice.stuck"]
    assert fit.profile.name == "ice.stuck" and fit.profile.span < FLAT_NATS
    assert not stuck.stderr < stuck.belief - stuck.truth  # infinite, or larger than the gap it should measure
    assert verdict(fit, "ice.stuck") == "not identified"


def test_deterministic_answers_are_refused():
    cfg = dataclasses.replace(CFG, teacher=TeacherConfig(beta=None))
    with pytest.raises(ValueError, match="no scale of the score: the belief is not identified"):
        fit_world(_world(0.1), cfg=cfg)


def test_the_log_likelihood_of_hand_made_answers_matches_the_formula():
    """Two answered queries of two steps each, the score written out: r(terrain) − d·Φ + max(log T_H, floor)."""
    world = _world(0.1)
    slots = tuple(parameter_slots(world.params, world.params.dynamics, world.belief().dynamics))
    theta = jnp.asarray(
        [0.5 if n == "sand.speed" else {"speed": 1.0, "noise": 0.05, "stuck": 0.7}[f] for n, f, _ in slots]
    )
    table = {"floor": -1.0, "ice": -0.5, "sand": -2.0, "goal": 0.25}
    log_n = -np.log(2 * np.pi * 0.05**2)  # the Gaussian's log density at its mean, σ = 0.05
    # name: (x, y), action, next (x, y), its score by hand. A push moves 0.5 · speed · action; no wall within 10σ.
    steps = {
        "ice stuck": ([4.5, 1.5], [-1, 0], [4.5, 1.5], table["ice"] + np.log(0.7)),
        "ice moved": ([4.5, 1.5], [-1, 0], [4.02, 1.49], table["ice"] + np.log(0.3) + log_n - 0.5 * (0.4**2 + 0.2**2)),
        "ice far": ([4.5, 1.5], [-1, 0], [4.4, 1.5], table["ice"] - 20.0),  # z = 8: below the floor
        "sand moved": ([5.5, 3.5], [-1, 0], [5.25, 3.53], table["sand"] + log_n - 0.5 * 0.6**2),
        "floor moved": ([8.5, 1.6], [0, 1], [8.45, 2.1], table["floor"] + log_n - 0.5),
        "goal moved": ([1.5, 1.5], [0, 1], [1.5, 2.0], table["goal"] + log_n),
    }
    names = [
        (("ice stuck", "ice moved"), ("sand moved", "floor moved")),
        (("ice far", "goal moved"), ("ice moved", "goal moved")),
    ]
    live = np.array([[[True, True], [True, True]], [[True, True], [True, False]]])  # the very last step ignored
    label = np.array([1.0, 0.0])

    def field(i):  # [Q, 2, L, ·]
        return np.asarray([[[steps[k][i] for k in seg] for seg in pair] for pair in names], np.float32)

    q = Queries(*(jnp.asarray(field(i)) for i in range(3)), jnp.asarray(live), jnp.asarray(label))
    beta, floor, dist = 0.5, -20.0, 0.1
    phi = {
        k: 0.0 if k.startswith("goal") else float(potential(world.params, jnp.asarray(v[0]))) for k, v in steps.items()
    }
    assert phi["ice moved"] == pytest.approx(3.0)  # cells to the goal: a dense reward
    steps = {k: (*v[:3], v[3] - dist * phi[k]) for k, v in steps.items()}
    score = np.where(live, field(3), 0.0).sum(-1)
    d = beta * (score[:, 0] - score[:, 1])
    expected = np.sum(label * -np.log1p(np.exp(-d)) + (1 - label) * -np.log1p(np.exp(d)))
    by_code = jnp.asarray([table.get(t, 0.0) for t in TERRAINS] + [0.0])  # pit and wall: unused
    got = jax.jit(log_likelihood, static_argnums=1)(world.params, slots, theta, by_code, dist, q, beta, floor)
    assert float(got) == pytest.approx(expected, abs=1e-4)
    # the hand-written densities are the world's own, under the person's belief
    pos, act, nxt = (jnp.asarray([v[i] for v in steps.values()], jnp.float32) for i in range(3))
    lp = jax.jit(jax.vmap(log_prob_pos, (None, 0, 0, 0)))(world.belief(), pos, act, nxt)
    r = [table[TERRAINS[int(world.params.grid[int(y), int(x)])]] for x, y in np.asarray(pos)]
    want = [v[3] + dist * phi[k] for k, v in steps.items()]
    assert np.maximum(np.asarray(lp), floor) + r == pytest.approx(want, abs=1e-4)


def test_the_verdict_reads_the_margins():
    def fit(z_truth, z_belief, stderr=0.05, span=30.0):
        e = Estimate("ice.stuck", 0.1, 0.7, 0.6, stderr, z_truth, z_belief)
        return BeliefFit([e], [], 0.0, Profile("ice.stuck", np.linspace(0.05, 0.95, 10), np.r_[-span, np.zeros(9)]))

    assert verdict(fit(8.0, 1.0), "ice.stuck") == "recovered"
    assert verdict(fit(2.0, 1.0), "ice.stuck") == "not told from the truth"
    assert verdict(fit(8.0, 4.0), "ice.stuck") == "away from the belief"
    assert verdict(fit(8.0, 1.0, span=1.0), "ice.stuck") == "not identified"  # a flat profile
    assert verdict(fit(8.0, 1.0, stderr=np.inf), "ice.stuck") == "not identified"
    assert verdict(fit(8.0, 1.0, stderr=0.6), "ice.stuck") == "not identified"  # not 1 SE between 0.1 and 0.7


def test_an_imprecise_learner_sees_every_move_shifted_by_a_smooth_field_of_the_given_rms():
    k_pos, k_field = jax.random.split(jax.random.key(0))
    pos = jax.random.uniform(k_pos, (2000, 2, 3, 2), maxval=20.0)
    stay = jnp.arange(3) == 1  # the middle step of every segment does not move
    nxt = jnp.where(stay[None, None, :, None], pos, pos + 0.5)
    q = Queries(pos, jnp.zeros_like(pos), nxt, jnp.ones(pos.shape[:-1], bool), jnp.ones(2000))
    seen = imprecise_moves(q, 0.06, k_field)
    shift = np.asarray(q.nxt - seen.nxt)
    np.testing.assert_array_equal(shift[:, :, 1], 0.0)  # stays stay stays
    moved = shift[:, :, [0, 2]].reshape(-1, 2)
    assert abs(np.sqrt((moved**2).sum(-1).mean()) - 0.06) < 0.006
    # smooth: two positions a tenth of a cell apart are shifted almost alike
    near = imprecise_moves(q._replace(pos=q.pos + 0.1, nxt=q.nxt + 0.1), 0.06, k_field)
    assert np.abs(np.asarray(near.nxt - 0.1 - seen.nxt)[:, :, 0]).max() < 0.06 * 0.5
    assert imprecise_moves(q, 0.0, k_field) is q
