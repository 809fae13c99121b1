"""``mindgap design reward-plan``: planning on a finished job's learned reward, and its refusals.

The learner's training is replaced by a stand-in whose learned reward is the world's true
(state-form) reward: its own optimum must then be the world's optimal route, and it must rank
the optimal plan above the person's expected one.
"""

import dataclasses
import json
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import pytest

from mindgap.algorithms import methods
from mindgap.cli import main
from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.world import obs_reward
from mindgap.experiments import prefbias_nav
from mindgap.experiments._runfolder import to_jsonable
from mindgap.experiments.reward_optimum import report, reward_plan

JOB = "nav1/prefbias-q30"


@pytest.fixture
def run_folder(tmp_path):
    cfg = dataclasses.replace(prefbias_nav.preset("fast"), worlds=("nav1",))
    root = tmp_path / "nav"
    (root / "jobs").mkdir(parents=True)
    (root / "progress.json").write_text(json.dumps({"experiment": "nav"}))
    (root / "config.json").write_text(json.dumps(to_jsonable(cfg)))
    record = {"final": [-40.0], "routes": [{"goal": 1.0, "better": True}]}
    (root / "jobs" / "nav1__prefbias-q30.json").write_text(json.dumps(record))
    return root


def test_a_run_with_added_learners_finds_their_jobs(run_folder):
    from mindgap.experiments.reward_optimum import _run_job

    config = json.loads((run_folder / "config.json").read_text())
    (run_folder / "config.json").write_text(json.dumps({**config, "methods": ["drlhp"]}))
    (run_folder / "jobs" / "nav1__drlhp-q30.json").write_text("{}")
    name, cfg, job, _ = _run_job(run_folder, "nav1/drlhp-q30")
    assert name == "nav" and cfg.methods == ("drlhp",) and job.method == "drlhp" and job.cfg.queries == 30


@pytest.fixture
def true_reward(monkeypatch):
    params = load_world("nav1").params
    truth = jax.vmap(lambda o, a, n: obs_reward(o, a, n, params))
    carry = SimpleNamespace(
        model=SimpleNamespace(posterior=SimpleNamespace(reward=SimpleNamespace(mean=jnp.zeros((1, 1)))))
    )
    monkeypatch.setattr(methods, "train", lambda *a, **k: {"carry": carry})
    monkeypatch.setattr(methods, "learned_reward", lambda m, c: (lambda p, o, a, n: truth(o, a, n), jnp.zeros((1, 1))))


def test_the_true_reward_asks_for_the_optimal_route(run_folder, true_reward):
    (run_folder / "train" / "nav1__prefbias-q30").mkdir(parents=True)
    (run_folder / "train" / "nav1__prefbias-q30" / "checkpoint.npz").write_bytes(b"")
    rec = reward_plan(run_folder, JOB, rollouts=4)
    seed = rec["seeds"][0]
    assert seed["plan"]["goal"] == 1.0 and seed["plan"]["ice"] > 0.2 and seed["plan"]["sand"] == 0.0
    assert seed["value"]["optimal"] > seed["value"]["expected"]
    # the optimal plan is r̂'s optimum: its value is the optimum's, up to the discretisation's tolerance
    assert seed["value"]["own"] == pytest.approx(seed["value"]["optimal"], abs=0.05)
    assert rec["summary"] == {
        "own_optimum_reaches_goal": 1,
        "ranks_optimal_first": 1,
        "policy_on_better_route": 1,
        "seeds": 1,
    }
    assert "reaches the goal in 1 of 1 seeds" in report(rec)


def test_refusals_are_one_line(run_folder, true_reward, capsys):
    argv = ["design", "reward-plan", "--run", str(run_folder)]
    assert main([*argv, "--job", JOB]) == 2  # no checkpoint
    assert main([*argv, "--job", "nav1/sac"]) == 2  # not finished
    (run_folder / "jobs" / "nav1__sac.json").write_text("{}")
    assert main([*argv, "--job", "nav1/sac"]) == 2  # learns no reward from preferences
    assert main([*argv, "--job", "nav9/prefbias"]) == 2
    assert main(["design", "reward-plan", "--run", str(run_folder.parent), "--job", JOB]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 5 and "no checkpoint" in err[0] and "not finished" in err[1] and "learns no reward" in err[2]
    assert "no job" in err[3] and "not a run folder" in err[4]
