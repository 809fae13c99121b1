import numpy as np
import pytest

from mindgap.envs.coffee import (
    ACTIONS,
    DELIVER,
    FACTORS,
    GO,
    IN_CAFE,
    N_STATES,
    RAINING,
    ROBOT_COFFEE,
    TRUE_SPILL,
    UMBRELLA,
    USER_COFFEE,
    WET,
    CoffeeParams,
    bits,
    coffee_transitions,
    event_probability,
    factor_pairs,
    factored_layout,
    make_coffee,
    state_id,
)
from mindgap.envs.coffee_demos import SANITY, SCENARIOS, sanity_trace, study_traces, to_demonstrations, trace_text
from mindgap.models.belief import factored, per_state_action


@pytest.mark.parametrize("robot", ["mobile", "humanoid"])
def test_dynamics_are_stochastic_and_spill_only_when_holding_both(robot):
    t = np.asarray(make_coffee(robot).transitions, np.float64)
    assert t.shape == (64, 4, 64)
    np.testing.assert_allclose(t.sum(-1), 1.0, atol=1e-6)
    b = bits(np.arange(N_STATES))
    nxt = bits(np.arange(N_STATES))
    # the robot loses its coffee: P(robot_coffee 1 -> 0); DeliverCoffee hands it over, any other loss is a spill
    lost = (b[:, None, ROBOT_COFFEE] == 1) & (nxt[None, :, ROBOT_COFFEE] == 0)
    p_lost = (t * lost[:, None, :]).sum(-1)  # [S, A]
    p_spill = np.delete(p_lost, DELIVER, axis=1)  # Go, BuyCoffee, GetUmbrella
    holding_both = (b[:, ROBOT_COFFEE] == 1) & (b[:, UMBRELLA] == 1)
    assert np.all(p_spill[~holding_both] == 0)
    assert np.all(p_spill[:, 1:] == 0)  # only Go can spill
    np.testing.assert_allclose(p_spill[holding_both, GO], TRUE_SPILL[robot], atol=1e-6)
    # delivering needs the office and the coffee, and then it always succeeds
    delivered = (nxt[None, :, USER_COFFEE] == 1) & (b[:, None, USER_COFFEE] == 0)
    p_deliver = (t[:, DELIVER] * delivered).sum(-1)
    can = (b[:, IN_CAFE] == 0) & (b[:, ROBOT_COFFEE] == 1) & (b[:, USER_COFFEE] == 0)
    np.testing.assert_allclose(p_deliver, can.astype(float))


def test_the_humanoid_truly_spills_less_and_rain_wets_without_umbrella():
    assert TRUE_SPILL["humanoid"] < TRUE_SPILL["mobile"]
    t = coffee_transitions(CoffeeParams(spill=0.3, wet=0.8))
    start_rain = state_id(raining=1)
    wet_after = sum(t[start_rain, GO, s] for s in range(N_STATES) if bits(s)[WET])
    assert np.isclose(wet_after, 0.8)
    with_umbrella = state_id(raining=1, umbrella=1)
    assert all(bits(s)[WET] == 0 for s in np.flatnonzero(t[with_umbrella, GO]))
    # rain never changes, and any action but Go dries the robot
    b = bits(np.arange(N_STATES))
    for a in range(len(ACTIONS)):
        for s in range(N_STATES):
            for s2 in np.flatnonzero(t[s, a]):
                assert bits(s2)[RAINING] == b[s, RAINING]
                if a != GO:
                    assert bits(s2)[WET] == 0


def test_factor_pairs_and_event_probability_read_any_tensor():
    pairs = factor_pairs("spill")
    assert len(pairs.states) == 16  # umbrella and coffee held: 2^4 settings of the other four variables
    for p in (0.0, 0.25, 1.0):
        assert np.isclose(event_probability(coffee_transitions(CoffeeParams(spill=p)), "spill"), p)
    with pytest.raises(ValueError, match="unknown factor"):
        factor_pairs("slip")
    with pytest.raises(ValueError, match="probability"):
        CoffeeParams(spill=1.5)
    with pytest.raises(ValueError, match="unknown robot"):
        make_coffee("drone")


def test_factored_space_represents_every_belief_exactly():
    space = factored(*factored_layout(("spill",)))
    assert space.kind == "factored" and space.n_factors == 2  # spill + the fixed rest
    for p in (0.05, 0.6):
        truth = coffee_transitions(CoffeeParams(spill=p))
        theta = space.from_transitions(truth)
        np.testing.assert_allclose(theta[0], [p, 1 - p], atol=1e-6)
        np.testing.assert_allclose(space.to_transitions(theta), truth, atol=1e-6)
    both = factored(*factored_layout(FACTORS, CoffeeParams(spill=0.2, wet=0.7)))
    truth = coffee_transitions(CoffeeParams(spill=0.2, wet=0.7))
    np.testing.assert_allclose(both.to_transitions(both.from_transitions(truth)), truth, atol=1e-6)
    with pytest.raises(ValueError, match="learn it too"):
        factored_layout(("spill",), CoffeeParams(spill=0.2, wet=0.7))


def test_per_sa_space_covers_the_spill_outcome():
    space = per_state_action(make_coffee("mobile").transitions)
    prior_mean = np.asarray(space.mean_transitions(np.ones(space.mask.shape)))
    # a uniform Dirichlet over each pair's support gives the spill outcome a share, not 0
    assert 0.0 < event_probability(prior_mean, "spill") < 0.5


def test_demonstrations_are_possible_for_both_robots_and_the_sanity_one_never_delivers():
    traces = study_traces()
    assert [t.name for t in traces] == list(SCENARIOS) + [SANITY]
    for robot in ("mobile", "humanoid"):
        t = np.asarray(make_coffee(robot).transitions)
        for tr in traces:
            for k, a in enumerate(tr.actions):
                assert t[tr.states[k], a, tr.states[k + 1]] > 0, (robot, tr.name, k)
    sanity = sanity_trace()
    assert not any(bits(s)[USER_COFFEE] for s in sanity.states)
    assert sanity == sanity_trace()  # the same demonstration in every run
    for tr in traces[:-1]:
        assert bits(tr.states[-1])[USER_COFFEE] == 1  # every scenario ends with the coffee delivered
    demos = to_demonstrations(traces)
    assert demos.count == 9 and int(demos.mask.sum()) == sum(len(tr.actions) for tr in traces)
    text = trace_text(traces[2], "humanoid")
    assert "SPILLS" in text and "GetUmbrella" in text and len(text.splitlines()) == len(traces[2].actions) + 1
