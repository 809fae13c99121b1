"""A driving clip's decisions played out in the participant's believed world (§4.4.2, §4.3.1)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.algorithms.sac_loop import rollouts
from mindgap.data.segments import Segments
from mindgap.envs.driving import make_world
from mindgap.envs.driving.params import IDLE, LANE_LEFT, SLOWER
from mindgap.envs.driving.world import observe, state_from_obs
from mindgap.models.mlp import init_mlp
from mindgap.teachers import believed_rollout as br
from mindgap.teachers import drivers as dv
from mindgap.teachers.preference import TeacherConfig

WORLD = make_world(sleet=1.0)
DRY = WORLD.params.with_sleet(0.0)
FLOOR = TeacherConfig().log_t_floor


def _actor(favourite: int, strength: float = 3.0):
    """A categorical π_H that prefers one action everywhere (strength 0: uniform)."""
    (w0, b0), (w1, b1) = init_mlp(jax.random.key(0), (WORLD.env.observation_space.dim, 4, 5))
    return ((w0 * 0, b0), (w1 * 0, b1.at[favourite].set(strength)))


def _clips(action: int, params, count: int = 16, key: int = 3) -> Segments:
    """``count`` episodes where the car takes ``action`` once the front car brakes (IDLE before)."""
    policy = lambda _, o: jnp.where(o[7] > 0.5, float(action), float(IDLE))[None]  # noqa: E731
    obs, _, alive = rollouts(rng.key(key), WORLD.env, params, policy, None, count, WORLD.horizon)
    act = jax.vmap(jax.vmap(lambda o: policy(None, o)))(obs[:, :-1])
    return Segments(obs[:, :-1], act, obs[:, 1:], alive.astype(jnp.float32))


def _one(seg: Segments, i: int) -> Segments:
    return jax.tree.map(lambda x: x[i : i + 1], seg)


def test_an_observation_holds_the_state_that_moves_the_scenario():
    seg = _clips(LANE_LEFT, WORLD.params, count=2)
    for o in seg.obs.reshape(-1, seg.obs.shape[-1]):
        assert np.allclose(observe(state_from_obs(o, WORLD.params), WORLD.params), o, atol=1e-6)


def test_decisions_the_grip_does_not_touch_play_out_as_they_happened():
    """A lane change never brakes: the believed rollout of any belief is the clip itself."""
    seg = _clips(LANE_LEFT, WORLD.params, count=4)
    for belief in (DRY, WORLD.params):
        o_hat, live, crashed = jax.vmap(lambda o, a, n, m: br.believed_steps(o, a, n, m, belief))(*seg[:4])
        assert np.allclose(o_hat, seg.obs, atol=1e-4) and np.array_equal(live, seg.mask > 0)
        assert not bool(crashed.any())


def test_a_dry_road_believer_sees_braking_on_sleet_work_and_is_surprised_by_its_crash():
    """Braking in lane on full sleet crashes in most episodes; played out with the dry road's grip (0.95)
    the same decisions stop in time (the scenario's calibration: never a crash on a dry road). The score is
    Σ_t max(log π_H(a_t|ŝ_t), floor) + floor for the crash the participant did not expect — exactly, for a
    uniform π_H."""
    seg = _clips(SLOWER, WORLD.params)
    crashed = np.asarray(br.clip_crashed(seg))
    assert crashed.mean() > 0.5
    o_hat, live, believed_crash = jax.vmap(lambda o, a, n, m: br.believed_steps(o, a, n, m, DRY))(*seg[:4])
    assert not bool(believed_crash.any())
    braked = (seg.obs[..., 7] > 0.5) & (seg.mask > 0)
    assert bool(jnp.all(jnp.where(braked, o_hat[..., 2] <= seg.obs[..., 2] + 1e-6, True)))  # slower as believed
    uniform = _actor(IDLE, strength=0.0)
    scores = np.asarray(br.believed_scores(seg, uniform, DRY, TeacherConfig()))
    steps = np.asarray(seg.mask.sum(-1))
    assert np.allclose(scores, -np.log(5.0) * steps + FLOOR * crashed, rtol=1e-5)
    decisions = np.asarray(br.believed_scores(seg, uniform, DRY, TeacherConfig(), crash=False))
    assert np.allclose(decisions, -np.log(5.0) * steps, rtol=1e-5)  # the decisions alone: no crash term
    per_step = np.asarray(br.believed_per_step(seg, uniform, DRY, TeacherConfig()))
    assert np.allclose(per_step, scores / steps, rtol=1e-6)
    # judged over the whole clip: a crash clip no longer gains from holding fewer decisions
    length = seg.mask.shape[-1]
    assert (steps[crashed] < length).all()
    whole = np.asarray(br.believed_scores(seg, uniform, DRY, TeacherConfig(), crash=False, whole_clip=True))
    assert np.allclose(whole, -np.log(5.0) * length, rtol=1e-5)


def test_brakers_who_believe_the_road_dry_find_braking_on_sleet_expected_played_out_not_at_its_states(key):
    """At the clip's states a dry-road believer finds each weak braking step all but impossible (log T_H at
    its floor) and picks the lane change; played out in their belief the braking clip shows what they
    expected. Clips that do not crash, so the crash term is not what decides."""
    brake_all, steer = _clips(SLOWER, WORLD.params, count=64, key=5), _clips(LANE_LEFT, WORLD.params, count=64, key=5)
    safe = np.flatnonzero(~np.asarray(br.clip_crashed(brake_all)))
    assert safe.size >= 3
    take = np.resize(safe, 64)
    brake = jax.tree.map(lambda x: x[take], brake_all)
    policies = jax.tree.map(lambda *x: jnp.stack(x), _actor(SLOWER), _actor(SLOWER))
    beliefs = jax.tree.map(lambda *x: jnp.stack(x), DRY, DRY)

    def crowd(rollout):
        return dv.CrowdTeacher(beliefs, policies, jnp.asarray([True, True]), WORLD.env, TeacherConfig(), rollout)

    played = float(jax.jit(crowd(True).answer)(key, brake, steer)[0].mean())
    at_states = float(jax.jit(crowd(False).answer)(key, brake, steer)[0].mean())
    assert played > 0.9 and at_states < 0.1


def test_a_crash_the_rater_did_not_expect_rates_lowest(key):
    seg = _clips(SLOWER, WORLD.params)
    crashed = np.asarray(br.clip_crashed(seg))
    order = np.argsort(~crashed)  # a crash first, then one that stopped in time
    pair = jax.tree.map(lambda x: x[order[[0, -1]]], seg)
    assert crashed[order[0]] and not crashed[order[-1]]
    obs = jnp.concatenate([pair.obs, pair.next_obs[:, -1:]], 1)
    r = dv.rate_rollouts(key, _actor(SLOWER), True, obs, pair.act, pair.mask > 0, noise=0.0, belief=DRY)
    assert r[0] < r[1]


def test_the_participants_front_distance_is_to_the_blue_car_in_any_lane():
    """Fig. 32's "distance with front car": after a lane change the gap to the blue car still counts until
    it is behind; r_A's feature jumps to 1 the moment no car is ahead in the ego's lane."""
    from mindgap.envs.driving.reward import features
    from mindgap.envs.driving.world import decode

    seg = _clips(LANE_LEFT, DRY, count=1)
    n = [decode(o, DRY) for o in seg.next_obs[0]]
    ours = np.array([float(dv.distance_to_front_car(x, DRY.rewards)) for x in n])
    theirs = np.array(
        [float(features(x["y"], x["heading"], x["speed"], x["others_dx"], x["others_y"], x["others_speed"], DRY.rewards)[1])
         for x in n]
    )  # fmt: skip
    beside = np.array([abs(float(x["y"] - x["others_y"][0])) > 2.0 and float(x["others_dx"][0]) > 5.0 for x in n])
    assert beside.any() and np.all(theirs[beside] == 1.0) and np.all(ours[beside] < 1.0)
    behind = np.array([float(x["others_dx"][0]) <= 0 for x in n])
    assert np.all(ours[behind] == 1.0)
    with pytest.raises(AssertionError):
        assert np.allclose(ours, theirs)
