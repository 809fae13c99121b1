"""A gym world's person believes a dynamics model learned from a variant of the env."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.cli import main
from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.envs.interface import EnvError
from mindgap.models.gaussian_dynamics import DynamicsConfig, dynamics_log_prob
from mindgap.teachers import learned_belief as lb
from mindgap.teachers.preference import TeacherConfig, segment_scores

TRUE = "gym:Pendulum-v1,max_episode_steps=50"
HEAVY = "gym:Pendulum-v1,g=15.0,max_episode_steps=50"  # the person expects stronger gravity
SMALL = lb.BeliefFitConfig(transitions=3000, held_out=500, dynamics=DynamicsConfig(hidden=(32, 32), max_epochs=30))


def test_the_learned_belief_expects_its_own_env_not_the_true_one(tmp_path):
    belief, record = lb.fit_learned_belief(
        gym_world_from_spec(HEAVY), SMALL, true_world=gym_world_from_spec(TRUE), cache_dir=tmp_path
    )
    # Pendulum is deterministic, so a good fit is sharp on its own env's held-out steps and far
    # off on the true env's, whose gravity differs by half
    assert record["held_out_log_lik"] > 3.0
    assert record["true_log_lik"] < record["held_out_log_lik"] - 10.0
    # measured over seeds 0-2: none of the belief's own held-out steps, 71-80% of the true env's, fall
    # below the teacher's floor on log T_H
    assert record["held_out_below_floor"] < 0.02 and record["true_below_floor"] > 0.4
    assert record["transitions"] == 3000 and record["epochs"] >= 1
    assert belief.model.params[0][0].shape == (3 + 1, 32)


def test_a_second_fit_reads_the_cache_and_a_saved_model_loads_back(tmp_path, monkeypatch):
    cfg = lb.BeliefFitConfig.fast()
    first, record = lb.fit_learned_belief(gym_world_from_spec(HEAVY), cfg, cache_dir=tmp_path)

    def no_collect(*_args, **_kwargs):
        raise AssertionError("the cached model should have been read")

    monkeypatch.setattr(lb, "collect", no_collect)
    again, record2 = lb.fit_learned_belief(gym_world_from_spec(HEAVY), cfg, cache_dir=tmp_path)
    loaded, _ = lb.load_learned_belief(record["path"])
    for other in (again, loaded):
        for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(other), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert record2["held_out_log_lik"] == record["held_out_log_lik"]
    # another configuration is another model
    other_cfg = lb.BeliefFitConfig(transitions=cfg.transitions + 1, held_out=cfg.held_out, dynamics=cfg.dynamics)
    assert lb.cache_key(gym_world_from_spec(HEAVY), other_cfg) != lb.cache_key(gym_world_from_spec(HEAVY), cfg)


def test_a_person_s_own_floor_keeps_the_fit_and_is_measured_and_recorded(tmp_path):
    """``min_std``: how sharply the person expects the robot is hers, not the fit's — the same cached model,
    its held-out figures measured at her floor; a floor that is not positive is refused."""
    cfg = lb.BeliefFitConfig.fast()
    sharp, record = lb.fit_learned_belief(gym_world_from_spec(HEAVY), cfg, cache_dir=tmp_path)
    blunt, blunt_record = lb.fit_learned_belief(gym_world_from_spec(HEAVY), cfg, cache_dir=tmp_path, min_std=1.0)
    assert blunt_record["path"] == record["path"] and "person_min_std" not in record
    assert blunt_record["person_min_std"] == 1.0 and float(blunt.min_std) == 1.0
    for a, b in zip(jax.tree.leaves(sharp.model), jax.tree.leaves(blunt.model), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # on the belief env's own held-out steps a floor of one typical step's change scores lower than the fit's
    # (measured: 0.56 against -0.99 nats a step)
    assert blunt_record["held_out_log_lik"] < record["held_out_log_lik"]
    for bad in (0.0, -1.0):
        with pytest.raises(ValueError, match="must be positive"):
            lb.fit_learned_belief(gym_world_from_spec(HEAVY), cfg, cache_dir=tmp_path, min_std=bad)


def test_the_person_scores_segments_with_the_learned_model(tmp_path):
    world = gym_world_from_spec(TRUE)
    belief, _ = lb.fit_learned_belief(gym_world_from_spec(HEAVY), lb.BeliefFitConfig.fast(), cache_dir=tmp_path)
    believing = lb.with_learned_belief(world, HEAVY, belief)
    assert world.env.log_prob is None and list(believing.beliefs) == [HEAVY]
    obs, act, nxt = (jnp.asarray(x) for x in lb.collect(world, 20, seed=3))
    want = dynamics_log_prob(belief.model, obs, act, nxt, lb.BeliefFitConfig.fast().dynamics.min_std)
    np.testing.assert_allclose(believing.env.log_prob(obs, act, nxt, believing.belief()), want, rtol=1e-6)

    from mindgap.data.segments import Segments

    seg = Segments(obs.reshape(2, 10, 3), act.reshape(2, 10, 1), nxt.reshape(2, 10, 3), jnp.ones((2, 10), bool))
    cfg = TeacherConfig(log_t_floor=-1e9)
    with_belief = segment_scores(seg, believing.env, world.params, believing.belief(), cfg)
    reward_only = segment_scores(seg, believing.env, world.params, None, cfg)
    np.testing.assert_allclose(with_belief - reward_only, want.reshape(2, 10).sum(1), rtol=1e-5, atol=1e-4)
    # the belief's model enters the world's fingerprint, so a run folder knows which person it had
    assert len(jax.tree.leaves(believing.fingerprint_tree())) > len(jax.tree.leaves(world.fingerprint_tree()))


def test_a_belief_about_another_kind_of_env_is_refused(tmp_path):
    with pytest.raises(EnvError, match="cannot be a belief about"):
        lb.fit_learned_belief(
            gym_world_from_spec("gym:MountainCarContinuous-v0"),
            lb.BeliefFitConfig.fast(),
            true_world=gym_world_from_spec(TRUE),
            cache_dir=tmp_path,
        )


def test_prefbias_runs_on_a_gym_world_with_a_learned_belief(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "run"
    argv = ["prefbias", "--env", TRUE, "--belief-env", HEAVY, "--fast", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    record = json.loads((out / "belief_model.json").read_text())
    assert record["belief_env"] == HEAVY and record["true_env"] == gym_world_from_spec(TRUE).name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["queries"] == 30
    from PIL import Image

    with Image.open(out / "rollout.gif") as gif:  # the env drew seed 0's greedy episode
        assert gif.n_frames > 10 and gif.size == (250, 250)
    assert "the person's believed dynamics: a model of" in capsys.readouterr().out
    # the saved model can be handed to another run (another method, so another folder)
    saved = record["path"]
    assert (
        main(["pebble", "--env", TRUE, "--belief-env", saved, "--fast", "--quiet", "--out", str(tmp_path / "pb")]) == 0
    )
    # a terrain world states its own beliefs
    assert main(["pebble", "--env", "nav1", "--belief-env", HEAVY, "--fast", "--out", str(tmp_path / "x")]) == 2
    assert "--belief-env is for gym worlds" in capsys.readouterr().err
    assert main(["pebble", "--env", TRUE, "--belief-env", "Pendulum-v1", "--fast", "--out", str(tmp_path / "y")]) == 2
    assert "--belief-env takes gym:ID,key=value or a saved model (.npz), got 'Pendulum-v1'" in capsys.readouterr().err
