"""The absorbing state of a learned reward (Kostrikov et al. 2019) in the buffer, the SAC loop and PEBBLE."""

import argparse
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.algorithms import engine, pbrl
from mindgap.algorithms.pbrl import FAST_SCHEDULE, PbRLConfig, method_config, train
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.data.replay import relabel, replay_add, replay_init, terminal_bonus
from mindgap.data.segments import AbsorbingSegments, Segments
from mindgap.envs.terrain import world_from_dict
from mindgap.models.reward_ensemble import (
    REWARD_BOUND,
    AbsorbingParams,
    RewardConfig,
    absorbing_reward,
    ensemble_reward,
    reward_init,
)

GAMMA = 0.9


class Lin(NamedTuple):
    w: jax.Array
    r_abs: jax.Array


def _lin_reward(p, o, a, o2):
    return p.w * o[:, 0] + a[:, 0]


def _lin_absorbing(p, o2):
    return p.r_abs * o2[:, 0]


def _buffer(terminal_at=(2, 5), n=8, capacity=12, scale=1.0):
    buf = replay_init(capacity, 2, 2)
    for i in range(n):
        o = scale * jnp.array([i, 0.0])
        buf = replay_add(buf, o, jnp.array([0.1 * i, 0.0]), o + scale, float(i), -7.0, i in terminal_at, i % 3)
    return buf


def test_terminal_bonus_is_the_discounted_value_of_the_absorbing_state():
    assert terminal_bonus(0.5, GAMMA) == pytest.approx(sum(GAMMA**k * 0.5 for k in range(1, 2000)))


def test_relabel_adds_the_absorbing_value_to_terminal_transitions_only():
    buf = _buffer()
    p = Lin(jnp.asarray(2.0), jnp.asarray(-0.4))
    new = relabel(buf, _lin_reward, p, chunk=5, absorbing_fn=_lin_absorbing, gamma=GAMMA)
    r = 2.0 * np.arange(8) + 0.1 * np.arange(8)
    r_abs = -0.4 * (np.arange(8) + 1)  # of the next observation, x = i + 1
    expect = r + np.where(np.isin(np.arange(8), (2, 5)), GAMMA * r_abs / (1 - GAMMA), 0.0)
    np.testing.assert_allclose(np.asarray(new.reward[:8]), expect, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(new.reward[8:]), 0.0)  # empty slots untouched (zeros)
    plain = relabel(buf, _lin_reward, p, chunk=5)  # without: exactly as before
    np.testing.assert_allclose(np.asarray(plain.reward[:8]), r, rtol=1e-6)
    for f in ("obs", "act", "next_obs", "env_reward", "terminal", "ep_step", "ptr", "size"):
        np.testing.assert_array_equal(np.asarray(getattr(new, f)), np.asarray(getattr(buf, f)))
    with pytest.raises(ValueError, match="gamma"):
        relabel(buf, _lin_reward, p, absorbing_fn=_lin_absorbing)


def test_relabel_with_the_ensemble_and_its_absorbing_reward(key):
    state = reward_init(key, 2, 2, RewardConfig(members=3, hidden=(8,)), absorbing="terminal")
    w = jax.random.normal(key, state.params.absorb.shape) * 0.05
    params = state.params._replace(absorb=w)
    buf = _buffer(scale=0.1)  # observations within [−1, 1], where the radial basis features are
    new = relabel(buf, ensemble_reward, params, absorbing_fn=absorbing_reward, gamma=GAMMA)
    r = np.asarray(ensemble_reward(params, buf.obs[:8], buf.act[:8], buf.next_obs[:8]))
    r_abs = np.asarray(absorbing_reward(params, buf.next_obs[:8]))
    assert np.ptp(r_abs) > 0.01  # it depends on the terminal state
    terminal = np.asarray(buf.terminal[:8])
    np.testing.assert_allclose(np.asarray(new.reward[:8])[~terminal], r[~terminal], rtol=1e-6)
    np.testing.assert_allclose(
        np.asarray(new.reward[:8])[terminal], (r + GAMMA * r_abs / (1 - GAMMA))[terminal], rtol=1e-5
    )


NEXT_TO_GOAL = {
    "name": "next-to-goal",
    "horizon": 6,
    "layout": "#####\n#SG.#\n#...#\n#####",
    "rewards": {"goal": 10.0, "step": -1.0, "progress": 1.0},
}


def test_run_chunk_stores_the_bonus_on_terminal_transitions(key):
    world = world_from_dict(NEXT_TO_GOAL)
    cfg = SACConfig(hidden=(8,), batch_size=8, gamma=GAMMA)
    rs = reward_init(key, 2, 2, RewardConfig(members=2, hidden=(8,)), absorbing="single")
    params = rs.params._replace(absorb=jnp.array([[0.6], [0.2]]))
    ls = loop_init(key, world.env, world.params, cfg, 300)
    kw = dict(n_steps=300, cfg=cfg, phase="random", reward_fn=ensemble_reward)
    with_bonus = run_chunk(ls, world.env, world.params, params, absorbing_fn=absorbing_reward, **kw).replay
    without = run_chunk(ls, world.env, world.params, params, **kw).replay
    terminal = np.asarray(with_bonus.terminal)
    assert terminal.sum() >= 5 and (~terminal).sum() >= 5  # goals reached and horizons hit
    truncated = np.asarray(with_bonus.ep_step) == NEXT_TO_GOAL["horizon"] - 1
    assert (truncated & ~terminal).any()  # horizon ends get no bonus (checked below with the rest)
    bonus = GAMMA * (REWARD_BOUND * np.tanh(np.array([0.6, 0.2]) / REWARD_BOUND)).mean() / (1 - GAMMA)
    np.testing.assert_array_equal(np.asarray(without.terminal), terminal)  # the same experience
    r = np.asarray(without.reward)
    np.testing.assert_allclose(np.asarray(with_bonus.reward), r + np.where(terminal, bonus, 0.0), rtol=1e-5)
    np.testing.assert_allclose(  # what is stored while acting is what relabelling writes
        np.asarray(relabel(with_bonus, ensemble_reward, params, absorbing_fn=absorbing_reward, gamma=GAMMA).reward),
        np.asarray(with_bonus.reward),
        rtol=1e-5,
        atol=1e-6,
    )


TINY = {**FAST_SCHEDULE, "reward": RewardConfig(hidden=(8, 8), updates=10, batch_size=8)}


def test_pebble_with_an_absorbing_state_learns_r_abs_and_keeps_the_buffer_consistent():
    easy = world_from_dict({**NEXT_TO_GOAL, "horizon": 30})  # episodes end at the goal often
    cfg = method_config(
        "pebble", explore_steps=250, absorbing=True, **{**TINY, "total_steps": 1000, "queries": 20}
    )  # two feedback rounds; one absorbing state per terminal state
    res = train(easy, cfg, seeds=1, teacher="true", progress=False)
    c = res["carry"]
    params = c.model.params
    assert isinstance(params, AbsorbingParams) and isinstance(c.prefs.seg_a, AbsorbingSegments)
    assert np.asarray(c.prefs.seg_a.absorbed).any()  # some queried segments reached the goal
    assert np.any(np.asarray(params.absorb) != 0.0, axis=-1).all()  # the preferences moved r_abs
    assert max(r[3] for r in res["curve"]) == 20
    buf = c.loop.replay
    assert np.asarray(buf.terminal).any()
    # the last feedback round relabelled the buffer, later steps were stored with the same
    # reward: every stored reward is the ensemble's, plus the bonus on terminal transitions
    again = jax.vmap(lambda b, p: relabel(b, ensemble_reward, p, absorbing_fn=absorbing_reward, gamma=cfg.sac.gamma))(
        buf, params
    )
    np.testing.assert_allclose(np.asarray(again.reward), np.asarray(buf.reward), rtol=1e-4, atol=1e-5)


def test_host_answers_keep_absorbing_steps():
    seg = AbsorbingSegments(
        *(np.zeros((2, 3, 4, 2)) for _ in range(3)), np.ones((2, 3, 4), bool), np.zeros((2, 3, 4), bool)
    )
    seen = []

    class Teacher:
        name = "t"

        def __call__(self, a, b):
            seen.append(a)
            return np.ones(a.mask.shape[0]), np.ones(a.mask.shape[0], bool)

    labels, answered = engine.host_answers(Teacher(), seg, seg, jnp.zeros(2, jnp.int32), 3, 10)
    assert isinstance(seen[0], AbsorbingSegments) and seen[0].absorbed.shape == (6, 4)
    assert bool(answered.all())
    plain = Segments(*seg[:4])
    engine.host_answers(Teacher(), plain, plain, jnp.zeros(2, jnp.int32), 3, 10)
    assert type(seen[-1]) is Segments


def test_the_switch_in_configs_and_on_the_command_line():
    assert "absorbing" not in PbRLConfig().as_dict()  # run folders from before the option still resume
    assert "absorbing_state" not in PbRLConfig().as_dict()
    assert PbRLConfig(absorbing=True).as_dict()["absorbing"] is True
    assert PbRLConfig(absorbing=True).as_dict()["absorbing_state"] == "terminal"
    with pytest.raises(ValueError, match="absorbing_state"):
        method_config("pebble", absorbing=True, absorbing_state="every")
    for method in ("pebble", "drlhp"):
        assert method_config(method).absorbing == pbrl.ABSORBING_DEFAULT[method]
        assert method_config(method, absorbing=True).absorbing
    with pytest.raises(ValueError, match="absorbing"):
        method_config("sac", absorbing=True)
    assert method_config("sac").absorbing is False

    from mindgap.commands import learn

    p = argparse.ArgumentParser()
    learn.add_parsers(p.add_subparsers(dest="command"))
    base = ["pebble", "--world", "d1", "--out", "x"]
    assert p.parse_args(base).absorbing is None  # the method's default
    assert p.parse_args([*base, "--absorbing"]).absorbing is True
    assert p.parse_args([*base, "--no-absorbing"]).absorbing is False
    assert p.parse_args([*base, "--absorbing-state", "single"]).absorbing_state == "single"
    with pytest.raises(SystemExit):
        p.parse_args(["sac", "--world", "d1", "--out", "x", "--absorbing"])
