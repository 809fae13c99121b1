"""The planning check: a discretised world is a proper MDP, plans are right, the six worlds behave."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.design.terrain_check import check_world, evaluate, noise_field, person_score
from mindgap.envs.terrain import NAMED_WORLDS, load_world, world_from_dict
from mindgap.envs.terrain.dynamics import log_prob_pos
from mindgap.planning.terrain import compass_actions, discretise, plan, plan_action, rollouts, route_stats
from mindgap.teachers.preference import TeacherConfig

CORRIDOR = {
    "horizon": 30,
    "start_jitter": 0.0,
    "layout": "##########\n#S......G#\n##########",
    "rewards": {"goal": 10.0, "step": -1.0},
    "dynamics": {"floor": {"noise": 0.02}},
}


def test_actions_lie_on_the_square_boundary():
    a = compass_actions(16)
    assert np.allclose(np.abs(a).max(1), 1.0) and len(np.unique(a.round(6), axis=0)) == 16


def test_discretised_transitions_are_distributions():
    w = load_world("d3")
    d = discretise(w.belief(), n=3)
    sums = np.asarray(d.probs.sum(-1))
    np.testing.assert_allclose(sums, 1.0, atol=1e-5)
    assert (np.asarray(d.probs) >= 0).all()
    # nothing lands in a wall: every target with mass is a real sub-cell
    mass_in_wall = np.where(np.asarray(d.targets)[:, None, :] < 0, np.asarray(d.probs)[..., :-1], 0.0)
    assert mass_in_wall.max() == 0.0


def test_corridor_plan_walks_straight_to_the_goal(key):
    w = world_from_dict(CORRIDOR)
    p = plan(w.params, n=4)
    pos, rew, alive = rollouts(key, w.params, plan_action, 50, p)
    st = route_stats(w.params, pos, rew, alive)
    # 7 cells at 0.5 cell per step from the start cell's centre: the goal cell is entered on step 13
    assert st.success == 1.0 and st.steps == pytest.approx(13, abs=0.5)
    assert st.ret == pytest.approx(10 - st.steps, abs=1e-4)
    # the discretised values agree with the rollouts within one step's reward (a position stands
    # for its sub-cell's centre, here 1/8 cell ahead of the true start)
    sid = int(p.grid.index[int(1.5 * 4), int(1.5 * 4)])
    disc = float(jnp.sum(rew * 0.99 ** jnp.arange(rew.shape[1]), 1).mean())
    assert float(p.q[sid].max()) == pytest.approx(disc, abs=1.0)


def test_evaluate_reports_failures():
    from mindgap.planning.terrain import RouteStats

    on_ice = RouteStats(0, 0, 1, 0, 10, 0.8, 0.1, 0.4, 0.5)
    on_sand = RouteStats(0, 0, 1, 0, 10, 0.1, 0.8, 2.0, 2.5)
    ok = evaluate({"true_prefers": "ice", "belief_prefers": "sand", "wider_berth": 1.0}, on_ice, on_sand)
    assert [e.held for e in ok] == [True, True, True]
    bad = evaluate({"true_prefers": "sand", "wider_berth": 3.0}, on_ice, on_sand)
    assert [e.held for e in bad] == [False, False]
    assert "0.8" not in bad[0].measured and "80%" in bad[0].measured
    want = {"person_prefers": "expected"}
    held = [evaluate(want, on_ice, on_sand, {"optimal": a, "expected": b})[0].held for a, b in ((-9, -2), (3, -2))]
    assert held == [True, False]
    assert not evaluate(want, on_ice, None)[0].held  # no belief, no person to score with


def test_person_score_is_the_teachers_sum_of_reward_and_believed_log_density(key):
    """A corridor whose person believes the floor twice as noisy: the score by hand, step by step."""
    w = world_from_dict({**CORRIDOR, "beliefs": {"human": {"floor": {"noise": 0.04}}}})
    p = plan(w.params, n=4)
    pos, rew, alive = rollouts(key, w.params, plan_action, 3, p)
    pos, rew, alive = np.asarray(pos), np.asarray(rew), np.asarray(alive)
    act, log_prob = jax.jit(plan_action), jax.jit(log_prob_pos)  # eager calls would compile at every step
    by_hand = []
    for i in range(3):
        total = 0.0
        for t in np.flatnonzero(alive[i]):
            a = act(p, jnp.asarray(pos[i, t]))
            lp = float(log_prob(w.belief(), jnp.asarray(pos[i, t]), a, jnp.asarray(pos[i, t + 1])))
            total += rew[i, t] + max(lp, TeacherConfig().log_t_floor)  # the teacher floors log T_H
        by_hand.append(total)
    assert person_score(w.params, w.belief(), p, jnp.asarray(pos), jnp.asarray(alive)) == pytest.approx(
        np.mean(by_hand), rel=1e-4
    )


@pytest.mark.parametrize("name", NAMED_WORLDS)
def test_named_world_shows_its_required_behaviour(name):
    """§3.2: optimal vs expected routes (ice vs sand in nav1/d3/d4, a wider berth in nav2/d1/d2)."""
    w = load_world(name)
    chk = check_world(w, n=4, count=100)
    assert chk.expectations, "every named world declares what planning must show"
    for e in chk.expectations:
        assert e.held, f"{name}: {e.text}: {e.measured}"
    assert chk.true.success >= 0.95  # the optimal plan reaches the goal


def test_noise_field_shows_the_pit_term():
    w = load_world("d2")
    true, belief = noise_field(w.params, k=4), noise_field(w.belief(), k=4)
    assert np.nanmax(true) == pytest.approx(0.05, abs=1e-6)  # no pit term in the truth
    h, wd = w.layout.shape
    assert belief.shape == (4 * h, 4 * wd) and np.isnan(belief[0, 0])
    assert np.nanmax(belief) > 0.5 and np.nanmin(belief) < 0.2  # large next to the pit, small far away


def test_plans_are_reproducible(key):
    w = world_from_dict(CORRIDOR)
    p = plan(w.params, n=3)
    a = rollouts(key, w.params, plan_action, 4, p)
    b = rollouts(key, w.params, plan_action, 4, p)
    np.testing.assert_array_equal(np.asarray(a[0]), np.asarray(b[0]))
    assert jax.tree.all(jax.tree.map(lambda x, y: bool(jnp.all(x == y)), a, b))
