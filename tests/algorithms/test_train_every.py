"""``SACConfig.train_every``: the updates follow every k-th step of a chunk, in the jitted loop (also
vmapped over seeds) and in the host loop; with k = 1 the loop is the one it was."""

import jax
import numpy as np
import pytest

from mindgap.algorithms import engine
from mindgap.algorithms.pbrl import fast_config, train
from mindgap.algorithms.sac import SACConfig
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.envs.resolve import resolve_env
from mindgap.envs.terrain import world_from_dict

OPEN = {
    "name": "open",
    "horizon": 40,
    "layout": "#######\n#.....#\n#..S..#\n#....G#\n#######",
    "rewards": {"step": -1.0},
}


@pytest.mark.parametrize("every", [1, 2, 5])
def test_the_jitted_loop_updates_after_every_kth_step(every):
    world = world_from_dict(OPEN)
    cfg = SACConfig(hidden=(8,), batch_size=8, learning_starts=20, train_every=every, utd=2)
    keys = jax.random.split(jax.random.key(0), 2)
    ls = jax.vmap(lambda k: loop_init(k, world.env, world.params, cfg, 200))(keys)

    def chunk(ls, n, phase):
        return jax.vmap(lambda s: run_chunk(s, world.env, world.params, None, n_steps=n, cfg=cfg, phase=phase))(ls)

    ls = chunk(ls, 20, "random")
    assert np.all(np.asarray(ls.sac.updates) == 0)
    ls = chunk(ls, 30, "train")
    np.testing.assert_array_equal(np.asarray(ls.sac.updates), [2 * (30 // every)] * 2)  # utd updates each time
    assert np.all(np.asarray(ls.steps) == 50)


def test_the_host_loop_updates_after_every_kth_step(tmp_path):
    world = resolve_env("gym:Pendulum-v1,max_episode_steps=50")
    cfg = fast_config("sac", total_steps=750, eval_every=250, chunk=250)
    cfg = cfg.__class__(**{**cfg.__dict__, "sac": cfg.sac.__class__(**{**cfg.sac.__dict__, "train_every": 5})})
    res = train(world, cfg, seeds=1, teacher="true", progress=False)
    trained = 750 - cfg.sac.learning_starts
    assert int(np.asarray(res["carry"].loop.sac.updates)[0]) == trained // 5 * cfg.sac.utd


def test_a_chunk_that_is_not_a_multiple_is_refused():
    cfg = fast_config("sac")
    bad = cfg.__class__(**{**cfg.__dict__, "sac": cfg.sac.__class__(**{**cfg.sac.__dict__, "train_every": 7})})
    with pytest.raises(ValueError, match="multiple of sac.train_every"):
        bad.check()
    with pytest.raises(ValueError, match="train_every must be at least 1"):
        SACConfig(train_every=0)
    assert "train_every" not in cfg.as_dict()["sac"]  # recorded only when set: earlier run folders resume
    assert engine.Schedule().as_dict()["sac"].get("train_every") is None
