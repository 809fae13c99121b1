"""EPS on a gymnasium world: π_H learned in the env the person imagines, explicability from host rollouts."""

import json

import jax
import numpy as np

from mindgap.algorithms.explicability_host import explicability_scores_host
from mindgap.cli import main
from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.models.mlp import init_mlp
from mindgap.teachers.expectation import ExpectationTeacher
from mindgap.teachers.learned_belief import BeliefFitConfig, fit_learned_belief, with_learned_belief

TRUE = "gym:Pendulum-v1,max_episode_steps=30"
HEAVY = "gym:Pendulum-v1,g=15.0,max_episode_steps=30"


def test_an_agent_that_is_what_the_person_expects_scores_zero(tmp_path):
    world = gym_world_from_spec(TRUE)
    model, _ = fit_learned_belief(world, BeliefFitConfig.fast(), cache_dir=tmp_path)
    believing = with_learned_belief(world, world.name, model)
    expected = init_mlp(jax.random.key(0), (3, 8, 2))
    person = ExpectationTeacher(model, expected, believing.env)
    same = jax.tree.map(lambda x: x[None], expected)
    # T_A and T_H the same model, the agent π_H itself: every log-ratio is 0
    (score,) = explicability_scores_host(believing, person, model, same, episodes=4)
    assert abs(score["score"]) < 1e-3 and abs(score["dynamics_part"]) < 1e-6 and abs(score["policy_part"]) < 1e-3
    other = jax.tree.map(lambda x: x[None], init_mlp(jax.random.key(1), (3, 8, 2)))
    (away,) = explicability_scores_host(believing, person, model, other, episodes=8)
    assert away["score"] < -1.0 and away["policy_part"] > 1.0  # a KL: positive for another policy
    assert np.isfinite(away["stochastic_return"])


def test_eps_runs_on_a_gym_world_with_a_learned_belief(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    common = ["--env", TRUE, "--fast", "--quiet", "--rollouts", "3"]
    assert main(["eps", *common, "--belief-env", HEAVY, "--out", str(tmp_path / "biased")]) == 0
    scores = json.loads((tmp_path / "biased" / "explicability.json").read_text())
    assert len(scores) == 1 and np.isfinite(scores[0]["score"]) and scores[0]["policy_part"] != 0.0
    record = json.loads((tmp_path / "biased" / "belief_model.json").read_text())
    assert record["belief_env"] == HEAVY
    policies = list((tmp_path / "cache" / "expected_policy").glob("*.npz"))
    assert len(policies) == 1  # π_H, trained once in the env the person imagines
    # an unbiased person believes a model of the true env itself, and expects a policy trained there
    assert main(["eps", *common, "--person", "unbiased", "--out", str(tmp_path / "unbiased")]) == 0
    record = json.loads((tmp_path / "unbiased" / "belief_model.json").read_text())
    assert record["belief_env"] == gym_world_from_spec(TRUE).name
    assert len(list((tmp_path / "cache" / "expected_policy").glob("*.npz"))) == 2
    capsys.readouterr()
    # without a belief a biased person cannot be simulated on a gym world
    assert main(["eps", *common, "--out", str(tmp_path / "none")]) == 2
    assert "--belief-env" in capsys.readouterr().err
