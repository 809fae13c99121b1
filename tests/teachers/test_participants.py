from dataclasses import replace

import jax
import numpy as np
import pytest

from mindgap import rng
from mindgap.envs.coffee import make_coffee
from mindgap.envs.coffee_demos import study_traces, to_demonstrations
from mindgap.teachers.participants import POPULATIONS, Population, recruit, respond, sample_participant, screen

DEMOS = to_demonstrations(study_traces())
SANITY = 8


def draw(pop, n, seed=0):
    keys = jax.random.split(rng.key(seed), n)
    return [sample_participant(k, pop, str(i)) for i, k in enumerate(keys)]


def test_population_answers_resemble_table2_and_set_belief_and_reward():
    drawn = {}
    for robot, (q1, q2) in {"mobile": (2.92, 2.83), "humanoid": (3.58, 3.67)}.items():
        pop = replace(POPULATIONS[robot], inattentive=0.0)
        people = drawn[robot] = draw(pop, 300, seed=len(drawn))
        answers = np.array([[p.q1, p.q2] for p in people])
        assert set(np.unique(answers)) <= {1, 2, 3, 4, 5}
        # 300 people, answer spread about 0.85: the mean is within 0.15 of the target with margin
        assert abs(answers[:, 0].mean() - q1) < 0.15 and abs(answers[:, 1].mean() - q2) < 0.15
        spill = np.array([p.spill for p in people])
        wet = np.array([p.wet_weight for p in people])
        assert np.all((spill > 0) & (spill < 1)) and np.all(wet <= 0)
        # higher answers mean a higher believed spill probability and a larger wetness penalty
        assert np.corrcoef(answers[:, 0], spill)[0, 1] > 0.8
        assert np.corrcoef(answers[:, 1], -wet)[0, 1] > 0.8
    mobile, humanoid = drawn["mobile"], drawn["humanoid"]
    assert np.mean([p.spill for p in humanoid]) > np.mean([p.spill for p in mobile]) + 0.05
    assert np.mean([p.wet_weight for p in humanoid]) < np.mean([p.wet_weight for p in mobile]) - 0.5


def test_the_belief_maps_linearly_from_the_latent_attitude():
    pop = Population("mobile", q1_mean=3.0, q2_mean=1.0, q1_std=0.0, q2_std=0.0, inattentive=0.0)
    p = draw(pop, 1)[0]
    assert p.q1 == 3 and p.q2 == 1
    assert np.isclose(p.spill, pop.spill_at_1 + (pop.spill_at_5 - pop.spill_at_1) / 2)
    assert p.wet_weight == 0.0  # "not care" at all


def test_attentive_ratings_follow_their_model_and_slider():
    pop = replace(POPULATIONS["humanoid"], inattentive=0.0, rating_noise=0.0, slider_step=0.0)
    person = draw(pop, 1, seed=3)[0]
    mdp = make_coffee("humanoid")
    r = respond(rng.key(0), person, pop, mdp, DEMOS)
    expected = np.asarray(person.teacher(mdp, 0.0).mean_ratings(DEMOS))
    low, high = person.slider
    np.testing.assert_allclose(r, low + (high - low) * expected / 10, atol=1e-4)
    assert r.argmin() == SANITY  # random actions are the worst demonstration


def test_inattentive_people_rate_at_random_and_have_no_belief():
    pop = replace(POPULATIONS["mobile"], inattentive=1.0 - 1e-9)
    person = draw(pop, 1)[0]
    assert not person.attentive and np.isnan(person.spill)
    with pytest.raises(ValueError, match="inattentive"):
        person.teacher(make_coffee("mobile"))
    mdp = make_coffee("mobile")
    r = np.stack([respond(k, person, pop, mdp, DEMOS) for k in jax.random.split(rng.key(0), 20)])
    assert np.all((r >= 0) & (r <= 10)) and np.all(r == np.round(r))
    assert 3.5 < r.mean() < 6.5  # uniform on the slider


def test_screen_applies_the_study_filters():
    ok = np.array([5, 6, 2, 3, 7, 4, 4, 3, 1.0])
    assert screen(ok, 5.0, SANITY) == ""
    assert screen(np.r_[ok[:-1], 2.0], 5.0, SANITY) == ""  # a tie with the lowest passes
    assert "sanity" in screen(np.r_[ok[:-1], 2.5], 5.0, SANITY)
    assert "too fast" in screen(ok, 2.9, SANITY)
    assert "same rating" in screen(np.full(9, 4.0), 5.0, SANITY)


def test_recruit_until_enough_are_valid():
    mdp = make_coffee("mobile")
    rs = recruit(rng.key(4), POPULATIONS["mobile"], mdp, DEMOS, 3, sanity=SANITY)
    assert sum(r.valid for r in rs) == 3 and rs[-1].valid
    assert all(r.dropped == screen(r.ratings, r.participant.minutes, SANITY) for r in rs)
    assert len({r.participant.pid for r in rs}) == len(rs)
    lazy = replace(POPULATIONS["mobile"], inattentive=0.999, minutes_inattentive=1.0)
    with pytest.raises(RuntimeError, match="passed the filters"):
        recruit(rng.key(4), lazy, mdp, DEMOS, 2, sanity=SANITY, max_recruits=5)
    with pytest.raises(ValueError, match="unknown robot"):
        Population("drone", 3.0, 3.0)
