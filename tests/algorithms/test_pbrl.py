"""The preference-learning engine: it learns, it resumes exactly, it checks its settings."""

import jax
import numpy as np
import pytest

from mindgap.algorithms import engine
from mindgap.algorithms.pbrl import FAST_SCHEDULE, method_config, train
from mindgap.envs.terrain import world_from_dict
from mindgap.models.reward_ensemble import RewardConfig
from mindgap.planning.terrain import rollouts

EASY = {
    "name": "easy",
    "horizon": 30,
    "layout": "#########\n#S.....G#\n#.......#\n#########",
    "rewards": {"goal": 10.0, "step": -1.0, "progress": 1.0},
}
TINY = {**FAST_SCHEDULE, "reward": RewardConfig(hidden=(8, 8), updates=10, batch_size=8)}


@pytest.fixture(scope="module")
def easy():
    return world_from_dict(EASY)


def _random_policy(k, pos):
    return jax.random.uniform(jax.random.fold_in(k, (pos * 1000).astype(int).sum()), (2,), minval=-1, maxval=1)


def test_sac_beats_a_random_policy(easy):
    cfg = method_config("sac", **{**TINY, "total_steps": 3000, "eval_episodes": 10})
    res = train(easy, cfg, seeds=2, progress=False)
    learned = res["final_returns"].mean()
    pos, rew, alive = rollouts(jax.random.key(5), easy.params, _random_policy, 50, jax.random.key(6))
    random_return = float(np.asarray(rew).sum(1).mean())
    assert learned > random_return + 10, (learned, random_return)  # the goal is worth +10, random rarely gets it


def test_resume_after_a_kill_gives_the_same_curve(easy, tmp_path, monkeypatch):
    cfg = method_config("pebble", explore_steps=250, **TINY)
    whole = train(easy, cfg, seeds=2, teacher="true", out=tmp_path / "whole", progress=False)

    saves = {"n": 0}
    real_save = engine.save_pytree

    def dying_save(*args, **kw):
        real_save(*args, **kw)
        saves["n"] += 1
        if saves["n"] == 3:  # killed right after the third checkpoint (mid-run, after feedback began)
            raise KeyboardInterrupt

    monkeypatch.setattr(engine, "save_pytree", dying_save)
    with pytest.raises(KeyboardInterrupt):
        train(easy, cfg, seeds=2, teacher="true", out=tmp_path / "killed", progress=False)
    monkeypatch.setattr(engine, "save_pytree", real_save)
    resumed = train(easy, cfg, seeds=2, teacher="true", out=tmp_path / "killed", progress=False)
    assert resumed["curve"] == whole["curve"]
    np.testing.assert_array_equal(resumed["final_returns"], whole["final_returns"])
    assert max(r[3] for r in whole["curve"]) == 30  # the whole budget was used
    other = method_config("pebble", explore_steps=250, **{**TINY, "queries": 20})
    with pytest.raises(ValueError, match="other settings"):
        train(easy, other, seeds=2, teacher="true", out=tmp_path / "whole", progress=False)


def test_config_errors_are_clear():
    with pytest.raises(ValueError, match="multiple of chunk"):
        method_config("sac", total_steps=1234)
    with pytest.raises(ValueError, match="unknown method"):
        method_config("ppo")
    with pytest.raises(ValueError, match="unknown sampler"):
        method_config("pebble", sampler="greedy")
