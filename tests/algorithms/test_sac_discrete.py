"""Discrete SAC (Christodoulou 2019) on a world whose Env declares a Discrete action space, through the
same loop and engine as continuous SAC."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.algorithms import pbrl
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_discrete import discrete_sac_init, discrete_sac_losses, target_entropy
from mindgap.algorithms.sac_loop import evaluate, loop_init, run_chunk
from mindgap.data.batch import Batch
from mindgap.envs.interface import Box, Discrete, Env, EnvError, Step, World, check_env
from mindgap.models.categorical import action_input, categorical_log_prob, logits

LENGTH, HORIZON = 4, 8


def _reset(key, params):
    return jnp.zeros((2,), jnp.int32)  # position, step


def _step(key, s, action, params):
    a = jnp.asarray(action).astype(jnp.int32).reshape(())  # 0 left, 1 stay, 2 right
    pos = jnp.clip(s[0] + a - 1, 0, LENGTH)
    nxt = jnp.stack([pos, s[1] + 1])
    return Step(nxt, (pos == LENGTH).astype(jnp.float32), jnp.zeros((), bool), nxt[1] >= HORIZON)


def _observe(s, params):
    return jnp.stack([s[0] / LENGTH, s[1] / HORIZON]).astype(jnp.float32)


def _reward(obs, act, next_obs, params):
    return (next_obs[0] >= 1.0).astype(jnp.float32)


def _log_prob(obs, act, next_obs, params):
    a = jnp.round(jnp.asarray(act).reshape(())) - 1
    want = jnp.clip(obs[0] * LENGTH + a, 0, LENGTH) / LENGTH
    return jnp.where(jnp.abs(next_obs[0] - want) < 1e-4, 0.0, -30.0)


CHAIN = Env(_reset, _step, _observe, Box((2,)), Discrete(3), reward=_reward, log_prob=_log_prob)
"""A chain of 5 cells: reward 1 per step spent at the right end; the best return is 5 of 8 steps."""
WORLD = World("chain", CHAIN, jnp.zeros(()), {"same": jnp.zeros(())}, horizon=HORIZON)
CFG = SACConfig(hidden=(32, 32), batch_size=64, learning_starts=0, lr=3e-3)


def test_learns_a_small_discrete_problem():
    """Greedy return after 1500 steps: every one of 3 seeds near the best (5), far above random (about 0.5)."""
    keys = jax.random.split(rng.key(0), 3)
    loop = jax.vmap(lambda k: loop_init(k, CHAIN, None, CFG, 2000))(keys)
    loop = jax.vmap(lambda ls: run_chunk(ls, CHAIN, None, None, n_steps=300, cfg=CFG, phase="random"))(loop)
    loop = jax.vmap(lambda ls: run_chunk(ls, CHAIN, None, None, n_steps=1200, cfg=CFG, phase="train"))(loop)
    assert loop.replay.act.shape[-1] == 1 and set(np.unique(loop.replay.act[:, :1500])) <= {0.0, 1.0, 2.0}
    ev = jax.vmap(lambda k, a: evaluate(k, CHAIN, a, None, 4, HORIZON)[0])(keys, loop.sac.params.actor)
    random_return = float(np.mean(np.asarray(loop.replay.env_reward[:, :300]))) * HORIZON
    assert random_return < 1.5
    assert np.all(np.asarray(ev).mean(-1) >= 4.0), np.asarray(ev)


def test_the_update_takes_expectations_over_actions_exactly(key):
    state = discrete_sac_init(key, 2, 3, CFG)
    obs = jax.random.uniform(key, (5, 2))
    batch = Batch(obs, jnp.array([[0.0], [1.0], [2.0], [1.0], [0.0]]), jnp.ones(5), obs[::-1], jnp.zeros(5))
    _, actor_loss, y = discrete_sac_losses(state.params, batch, CFG)
    p = state.params
    lp = logits(p.actor, batch.next_obs)
    q_next = jnp.min(jax.vmap(lambda c: _mlp(c, batch.next_obs))(p.target), 0)
    want = 1.0 + CFG.gamma * jnp.sum(jnp.exp(lp) * (q_next - jnp.exp(p.log_alpha) * lp), -1)
    assert np.allclose(y, want, atol=1e-6)
    assert np.allclose(jnp.exp(logits(p.actor, obs)).sum(-1), 1.0, atol=1e-6)
    assert np.allclose(
        categorical_log_prob(p.actor, obs, batch.act),
        jnp.take_along_axis(logits(p.actor, obs), batch.act.astype(int), -1)[:, 0],
    )
    assert target_entropy(CFG, 5) == pytest.approx(0.5 * np.log(5))
    assert np.array_equal(action_input(batch.act, 3), jax.nn.one_hot(batch.act[:, 0].astype(int), 3))
    assert action_input(obs, 2) is obs  # a continuous action is itself


def test_a_neutral_survival_entropy_charges_the_target_entropy_per_step(key):
    """``survival_entropy="neutral"``: the soft value pays α·(H − H̄) a step instead of α·H, so the target
    of a live step moves by exactly −γ α H̄ and a terminal step's not at all; ``paid`` is standard SAC. On a
    tiny chain whose episodes can end early, the paid entropy makes every step alive worth ≈ α H̄ more."""
    import dataclasses

    from mindgap.algorithms.sac import SURVIVAL_ENTROPY

    state = discrete_sac_init(key, 2, 3, CFG)
    obs = jax.random.uniform(key, (4, 2))
    terminal = jnp.array([0.0, 1.0, 0.0, 1.0])
    batch = Batch(obs, jnp.array([[0.0], [1.0], [2.0], [1.0]]), jnp.ones(4), obs[::-1], terminal)
    neutral = dataclasses.replace(CFG, survival_entropy="neutral")
    y_paid = discrete_sac_losses(state.params, batch, CFG)[2]
    y_neutral = discrete_sac_losses(state.params, batch, neutral)[2]
    charge = CFG.gamma * float(jnp.exp(state.params.log_alpha)) * target_entropy(CFG, 3)
    assert np.allclose(y_neutral - y_paid, -charge * (1.0 - terminal), atol=1e-6)
    assert SURVIVAL_ENTROPY == ("paid", "neutral") and CFG.survival_entropy == "paid"
    with pytest.raises(ValueError, match="survival_entropy"):
        SACConfig(survival_entropy="bonus")
    # the continuous SAC's target moves by −γ α H̄ too, H̄ = −dim(A) by default
    from mindgap.algorithms.sac import sac_init, sac_losses

    c_state = sac_init(key, 2, 1, CFG)
    c_batch = Batch(obs, jnp.zeros((4, 1)), jnp.ones(4), obs[::-1], terminal)
    diff = sac_losses(c_state.params, c_batch, key, neutral)[2] - sac_losses(c_state.params, c_batch, key, CFG)[2]
    assert np.allclose(diff, CFG.gamma * float(jnp.exp(c_state.params.log_alpha)) * 1.0 * (1.0 - terminal), atol=1e-5)


def _mlp(p, x):
    from mindgap.models.mlp import mlp

    return mlp(p, x)


def test_check_env_names_who_needs_what():
    check_env(CHAIN, discrete_actions=True, density=True, who="x")
    with pytest.raises(EnvError, match="continuous"):
        check_env(CHAIN, who="PrefBias")
    with pytest.raises(EnvError, match="at least two"):
        check_env(Env(_reset, _step, _observe, Box((2,)), Discrete(1)), discrete_actions=True)


def test_the_engine_runs_drlhp_on_a_discrete_world():
    """The engine's schedule unchanged: feedback rounds, a reward ensemble on one-hot actions, relabelling."""
    cfg = pbrl.fast_config("drlhp", sac=SACConfig(hidden=(16, 16), batch_size=32, learning_starts=250))
    res = pbrl.train(WORLD, cfg, seeds=2, teacher="true", progress=False)
    assert res["final_returns"].shape == (2, 20) and np.all(np.isfinite(res["final_returns"]))
    assert int(res["carry"].queries.min()) == cfg.queries
    first = res["carry"].model.params[0][0]
    assert first.shape[-2] == 2 + 3  # obs + one-hot action
