"""The driving study's simulated participants (§4.4.2): answers, beliefs, expectation answers, ratings."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.data.segments import Segments
from mindgap.envs.driving import STUDY_IMPORTANCE, make_world
from mindgap.envs.driving.params import IDLE, LANE_LEFT, SLOWER
from mindgap.models.mlp import init_mlp
from mindgap.teachers import drivers as dv
from mindgap.teachers.preference import TeacherConfig

WORLD = make_world()


def _actor(favourite: int, strength: float = 3.0):
    """A categorical π_H that prefers one action everywhere (zero weights, a biased last layer)."""
    layers = init_mlp(jax.random.key(0), (WORLD.env.observation_space.dim, 4, 5))
    (w0, b0), (w1, b1) = layers
    return ((w0 * 0, b0), (w1 * 0, b1.at[favourite].set(strength)))


def _episode(action: int, key=0):
    """One episode on a dry road where the car takes ``action`` once the front car brakes, IDLE before."""
    from mindgap.algorithms.sac_loop import rollouts

    params = WORLD.params.with_sleet(0.0)
    policy = lambda _, o: jnp.where(o[7] > 0.5, float(action), float(IDLE))[None]  # noqa: E731
    obs, _, alive = rollouts(rng.key(key), WORLD.env, params, policy, None, 1, WORLD.horizon)
    act = jax.vmap(lambda o: policy(None, o))(obs[0, :-1])
    return Segments(obs[:, :-1], act[None], obs[:, 1:], alive)


def _frames(seg: Segments) -> jax.Array:
    """A one-episode segment's observations with the last one: [1, T+1, d]."""
    return jnp.concatenate([seg.obs, seg.next_obs[:, -1:]], 1)


def test_recruits_answer_around_the_study_with_spread_and_the_availability_bias():
    pop = dv.DriverPopulation()
    people = [dv.sample_driver(jax.random.fold_in(rng.key(1), i), pop, f"p{i}", 1.0) for i in range(300)]
    attentive = [d for d in people if d.attentive]
    answers = np.array([d.importance for d in attentive])
    assert np.allclose(answers.mean(0), STUDY_IMPORTANCE, atol=0.25) and answers.std(0).min() > 0.4
    assert set(np.unique(answers)) <= {1, 2, 3, 4, 5}
    assert abs(np.mean([d.biased for d in people]) - 12 / 14) < 0.07
    assert abs(1 - len(attentive) / len(people) - pop.inattentive) < 0.06
    w = attentive[0].weights
    assert w.sum() == pytest.approx(1.0) and np.all(np.argsort(w) == np.argsort(attentive[0].importance, kind="stable"))
    assert np.allclose(dv.engineered_weights(attentive), np.mean(answers, 0) / np.mean(answers, 0).sum(), atol=1e-6)


def test_the_reward_follows_the_weights():
    """A lane change scores better for someone who weighs speed, braking for someone who weighs staying in lane."""
    steer, brake = _episode(LANE_LEFT), _episode(SLOWER)
    params = WORLD.params

    def ret(seg, weights):
        p = dv.RewardH(jnp.asarray(weights, jnp.float32), params)
        return float(dv.participant_reward(p, seg.obs[0], seg.act[0], seg.next_obs[0]).sum())

    speedy, lane_keeper = dv.importance_weights([5, 1, 1, 1]), dv.importance_weights([1, 1, 1, 5])
    assert ret(steer, speedy) > ret(brake, speedy)
    assert ret(brake, lane_keeper) > ret(steer, lane_keeper)


def test_crowd_answers_follow_what_each_participant_expects(key):
    """Bradley–Terry on Σ log T_H + log π_H: people expecting braking pick the braking segment, people
    expecting a lane change the other, and an inattentive crowd answers at random."""
    steer, brake = _episode(LANE_LEFT), _episode(SLOWER)
    k = 200
    seg_a = jax.tree.map(lambda x: jnp.repeat(x, k, 0), brake)
    seg_b = jax.tree.map(lambda x: jnp.repeat(x, k, 0), steer)
    dry = WORLD.params.with_sleet(0.0)
    beliefs = jax.tree.map(lambda *x: jnp.stack(x), dry, dry)

    def crowd(favourite, attentive=True):
        policies = jax.tree.map(lambda *x: jnp.stack(x), _actor(favourite), _actor(favourite))
        return dv.CrowdTeacher(beliefs, policies, jnp.asarray([attentive] * 2), WORLD.env, TeacherConfig(beta=1.0))

    brakers = jax.jit(crowd(SLOWER).answer)(key, seg_a, seg_b)[0]
    steerers = jax.jit(crowd(LANE_LEFT).answer)(key, seg_a, seg_b)[0]
    random = jax.jit(crowd(SLOWER, attentive=False).answer)(key, seg_a, seg_b)[0]
    assert float(brakers.mean()) > 0.9 and float(steerers.mean()) < 0.1
    assert 0.35 < float(random.mean()) < 0.65


def test_sanity_bias_question_and_ratings(key):
    cfg = TeacherConfig()
    assert not dv.sanity_fails(key, -40.0, -5.0, True, cfg)  # the collision is far less expected
    assert dv.bias_answer(key, 0.0, True, WORLD.params) and not dv.bias_answer(key, 1.0, True, WORLD.params)
    steer, brake = _episode(LANE_LEFT), _episode(SLOWER)
    obs = jnp.concatenate([_frames(steer), _frames(brake)])
    act = jnp.concatenate([steer.act, brake.act])
    alive = jnp.concatenate([steer.mask, brake.mask])
    r = dv.rate_rollouts(key, _actor(SLOWER), True, obs, act, alive, noise=0.0)
    assert r[1] > r[0] and set(r) <= set(range(1, 11))
    played = dv.rate_rollouts(
        key, _actor(SLOWER), True, obs, act, alive, noise=0.0, belief=WORLD.params.with_sleet(0.0)
    )
    assert np.array_equal(played, r)  # a π_H that ignores the state rates the played-out decisions alike
    assert dv.rating_fails(np.array([5.0, 1.0, 7.0]), sanity=1) == ""
    assert "sanity" in dv.rating_fails(np.array([5.0, 6.0, 7.0]), sanity=1)
    assert "same rating" in dv.rating_fails(np.array([4.0, 4.0]), sanity=0)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        dv.check_sleet_level(1.5)
    with pytest.raises(ValueError, match="share"):
        dv.DriverPopulation(biased=1.2)


def test_the_sanity_item_compares_how_expected_each_episode_looks_per_step():
    """The collision ends its episode after 5 steps, braking in time lasts 15: a sum of log-likelihoods
    favours the shorter for a participant with no preference among actions; per step it does not."""
    from mindgap.experiments.driving import _segment, sanity_segments

    collision, safe = (_segment(*ep, WORLD.horizon) for ep in sanity_segments(WORLD, WORLD.horizon))
    assert int(collision.mask.sum()) < int(safe.mask.sum()) == WORLD.horizon
    cfg = TeacherConfig()
    teacher = dv.ExpectationTeacher(WORLD.params.with_sleet(0.0), _actor(IDLE, strength=0.0), WORLD.env)
    sums = [float(dv.segment_scores(s, teacher, cfg)[0]) for s in (collision, safe)]
    means = [float(dv.per_step_scores(s, teacher, cfg)[0]) for s in (collision, safe)]
    assert sums[0] > sums[1] and means[0] < means[1]
    for s, total, mean in zip((collision, safe), sums, means):
        assert mean == pytest.approx(total / int(s.mask.sum()), rel=1e-6)


def test_a_participant_who_judges_decisions_scores_log_pi_alone():
    """``use_belief=False``: Σ_t log π_H(a_t|s_t) over the live steps, the road's response left out."""
    from mindgap.models.categorical import categorical_log_prob

    seg = _episode(SLOWER)
    actor = _actor(SLOWER, strength=1.0)
    teacher = dv.ExpectationTeacher(WORLD.params.with_sleet(0.0), actor, WORLD.env)
    decisions = float(dv.segment_scores(seg, teacher, TeacherConfig(use_belief=False))[0])
    log_pi = categorical_log_prob(actor, seg.obs[0], seg.act[0])
    assert decisions == pytest.approx(float(jnp.sum(jnp.where(seg.mask[0], log_pi, 0.0))), rel=1e-5)
    assert float(dv.segment_scores(seg, teacher, TeacherConfig())[0]) != pytest.approx(decisions, rel=1e-3)


def test_a_relative_participant_scores_each_decision_against_the_state_s_most_expected():
    """``relative=True``: log π_H(a|s) − max_a' log π_H(a'|s), so the expected decision scores 0 in any
    state however sure the person is, and another decision scores the log-ratio to it."""
    slower, idle = _episode(SLOWER), _episode(IDLE)
    cfg = TeacherConfig(use_belief=False, relative=True)
    sure, unsure = _actor(IDLE, strength=3.0), _actor(IDLE, strength=0.5)
    for actor, gap in ((sure, 3.0), (unsure, 0.5)):
        teacher = dv.ExpectationTeacher(WORLD.params.with_sleet(0.0), actor, WORLD.env)
        assert float(dv.segment_scores(idle, teacher, cfg)[0]) == pytest.approx(0.0, abs=1e-5)
        # every live step after the onset is a SLOWER: each scores −gap (logits differ by `gap`)
        braking = int(jnp.sum(slower.mask[0] * (slower.obs[0, :, 7] > 0.5)))
        assert float(dv.segment_scores(slower, teacher, cfg)[0]) == pytest.approx(-gap * braking, rel=1e-4)
    # without `relative`, how sure the person is shows in every step, the expected decision's too
    plain = [float(dv.segment_scores(idle, dv.ExpectationTeacher(WORLD.params, a, WORLD.env), TeacherConfig(use_belief=False))[0])
             for a in (sure, unsure)]  # fmt: skip
    assert plain[0] > plain[1] + 1.0


def test_reward_sums_add_the_participant_s_reward_over_the_live_steps():
    seg = _episode(SLOWER)
    reward = dv.RewardH(jnp.asarray([0.1, 0.2, 0.3, 0.4], jnp.float32), WORLD.params.with_sleet(0.0))
    per_step = dv.participant_reward(reward, seg.obs[0], seg.act[0], seg.next_obs[0])
    expected = float(jnp.sum(jnp.where(seg.mask[0] > 0, per_step, 0.0)))
    assert float(dv.reward_sums(seg, reward)[0]) == pytest.approx(expected, rel=1e-6)
    cut = Segments(seg.obs, seg.act, seg.next_obs, seg.mask.at[0, 5:].set(0.0))  # five steps shown
    assert float(dv.reward_sums(cut, reward)[0]) == pytest.approx(float(jnp.sum(per_step[:5])), rel=1e-6)
