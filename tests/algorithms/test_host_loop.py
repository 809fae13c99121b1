"""The host loop: SAC, PEBBLE and DRLHP on gymnasium worlds from the command line, resuming, refusals."""

import csv
import json

import jax
import numpy as np
import pytest

from mindgap.algorithms import engine, host_loop
from mindgap.algorithms.pbrl import fast_config, train
from mindgap.cli import main
from mindgap.envs.gym_world import NO_BELIEF
from mindgap.envs.interface import EnvError
from mindgap.envs.resolve import resolve_env

ENV = "gym:Pendulum-v1,max_episode_steps=50"  # short episodes keep evaluations quick


@pytest.mark.parametrize("method", ["sac", "pebble", "drlhp"])
def test_fast_cli_run_on_pendulum_writes_its_outputs(method, tmp_path, capsys):
    out = tmp_path / method
    teacher = [] if method == "sac" else ["--teacher", "true"]
    assert main([method, "--env", ENV, "--fast", "--steps", "750", *teacher, "--quiet", "--out", str(out)]) == 0
    assert "final return" in capsys.readouterr().out
    for name in ("curve.csv", "curve.png", "trajectories.png", "summary.json", "config.json", "checkpoint.npz"):
        assert (out / name).is_file(), name
    rows = list(csv.DictReader((out / "curve.csv").open()))
    assert [int(r["env_steps"]) for r in rows] == [500, 750]
    returns = [float(r["return"]) for r in rows]
    assert all(-16.3 * 50 <= x <= 0 for x in returns)  # Pendulum's reward is in [-16.3, 0] per step
    summary = json.loads((out / "summary.json").read_text())
    assert summary["world"] == ENV and summary["queries"] == {"sac": 0, "pebble": 10, "drlhp": 20}[method]


def test_resume_after_a_kill_gives_a_complete_curve(tmp_path, monkeypatch, capsys):
    args = ["drlhp", "--env", ENV, "--fast", "--steps", "750", "--teacher", "true", "--quiet", "--out", str(tmp_path)]
    real_save, saves = engine.save_pytree, {"n": 0}

    def dying_save(*a, **kw):
        real_save(*a, **kw)
        saves["n"] += 1
        if saves["n"] == 2:  # killed after the second checkpoint, after two feedback rounds
            raise KeyboardInterrupt

    monkeypatch.setattr(engine, "save_pytree", dying_save)
    with pytest.raises(KeyboardInterrupt):
        main(args)
    monkeypatch.setattr(engine, "save_pytree", real_save)
    assert main(args) == 0
    rows = list(csv.DictReader((tmp_path / "curve.csv").open()))
    assert [(r["env_steps"], r["queries"]) for r in rows] == [("500", "10"), ("750", "20")]
    world = resolve_env(ENV)
    with pytest.raises(ValueError, match="other settings"):
        train(world, fast_config("drlhp", total_steps=750), teacher="true", out=tmp_path, progress=False)


def test_storing_apart_gives_the_same_run_bit_for_bit(monkeypatch):
    """An update step's transition stored by a dispatch of its own (a large buffer) or inside the update's
    program: the same learner, buffer, curve and returns (PEBBLE, so that the stored reward is the learned one)."""
    world, cfg = resolve_env(ENV), fast_config("pebble", total_steps=750)
    real_store, runs = host_loop.store, []
    for limit in (1 << 62, 0):  # never apart; always apart
        calls = []
        monkeypatch.setattr(host_loop, "STORE_APART_BYTES", limit)
        monkeypatch.setattr(host_loop, "store", lambda *a, **kw: calls.append(1) or real_store(*a, **kw))
        runs.append((train(world, cfg, teacher="true", progress=False), len(calls)))
    (whole, none), (apart, stores) = runs
    assert none == 0 and stores > 0
    assert whole["curve"] == apart["curve"] and np.array_equal(whole["final_returns"], apart["final_returns"])
    leaves = [[_host(x) for x in jax.tree.leaves(run["carry"])] for run in (whole, apart)]
    assert len(leaves[0]) == len(leaves[1]) > 0
    assert all(np.array_equal(a, b) for a, b in zip(*leaves, strict=True))


def _host(x):
    """A leaf as a NumPy array (a typed random key as its data)."""
    return np.asarray(jax.random.key_data(x) if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key) else x)


def test_learners_that_need_dynamics_refuse_gym_worlds(tmp_path, capsys):
    from mindgap.algorithms import eps, prefbias
    from mindgap.algorithms.eps_config import eps_config

    world = resolve_env(ENV)
    for mod, who, args in (
        (prefbias, "PrefBias", (prefbias.prefbias_config("fast"),)),
        (eps, "EPS", (eps_config("fast"), None)),
    ):
        with pytest.raises(EnvError) as e:
            mod.train(world, *args, progress=False)
        assert str(e.value) == f"{who} needs {NO_BELIEF}"
    assert main(["pebble", "--env", ENV, "--fast", "--out", str(tmp_path)]) == 2  # the default teacher is biased
    assert "biased teacher needs the person's believed dynamics" in capsys.readouterr().err
    assert main(["drlhp", "--env", "gym:InvertedPendulum-v9", "--fast", "--out", str(tmp_path)]) == 2
    assert "mindgap: error: gym:InvertedPendulum-v9" in capsys.readouterr().err
