"""A world written by a user (examples/point_mass.py) through all five learners, from Python and the command line.

The Python runs and the command-line runs use the same configurations, so the file compiles
each learner once.
"""

import json
import re
from pathlib import Path

import jax
import numpy as np
import pytest

from mindgap.algorithms import eps, pbrl, prefbias
from mindgap.algorithms.eps_config import eps_config
from mindgap.algorithms.expected_policy import ExpectedPolicyConfig, expectation_teacher
from mindgap.algorithms.explicability import explicability_scores
from mindgap.cli import main
from mindgap.envs.interface import Box, Discrete, EnvError
from mindgap.envs.resolve import resolve_env

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "point_mass.py"
SPEC = f"{EXAMPLE}:make_world"
QUIET_SAC = ["--noise-color", "0", "--entropy-bonus", "0"]  # the fast presets' SAC, so the CLI shares their programs


@pytest.fixture(scope="module")
def world():
    return resolve_env(SPEC)


def test_the_example_world_follows_the_interface(world):
    env, p, still = world.env, world.params, world.belief("still")
    key = jax.random.key(0)
    s = env.reset(key, p)
    out = jax.jit(env.step)(key, s, np.ones(2, np.float32), p)
    assert out.state.pos.shape == (2,) and out.reward.shape == ()
    obs = env.observe(s, p)
    nxt = obs + 0.15 + np.array([0.05, 0.0])  # a full push, carried 0.05 to the right by the current
    # at the true density's peak; the person, who does not believe in the current, puts it 0.05/0.03 σ off theirs
    gap = float(env.log_prob(obs, np.ones(2), nxt, p) - env.log_prob(obs, np.ones(2), nxt, still))
    assert gap == pytest.approx(0.5 * (0.05 / 0.03) ** 2, rel=1e-3)
    assert resolve_env(f"{SPEC},drift=0.0").params.drift.tolist() == [0.0, 0.0]  # keyword arguments reach the factory


@pytest.mark.parametrize("method", ["sac", "pebble", "drlhp"])
def test_pebble_drlhp_and_sac_run_on_it(world, method, tmp_path):
    res = pbrl.train(world, pbrl.fast_config(method), seeds=2, teacher="biased", progress=False)
    assert np.all(np.isfinite(res["final_returns"])) and res["final_returns"].shape == (2, 20)
    assert max(r[3] for r in res["curve"]) == (0 if method == "sac" else 30)
    assert res["paths"][0][0].shape[-1] == 2  # observations: nothing to convert to a map
    out = tmp_path / method
    assert main([method, "--env", SPEC, "--fast", "--seeds", "2", "--quiet", *QUIET_SAC, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["world"] == "point-mass" and (out / "trajectories.png").stat().st_size > 0


def test_prefbias_runs_on_it(world, tmp_path):
    res = prefbias.train(world, prefbias.prefbias_config("fast"), seeds=2, teacher="biased", progress=False)
    assert np.all(np.isfinite(res["final_returns"])) and max(r[3] for r in res["curve"]) == 30
    out = tmp_path / "prefbias"
    argv = ["prefbias", "--env", SPEC, "--fast", "--seeds", "2", "--quiet", *QUIET_SAC, "--out", str(out)]
    assert main(argv) == 0
    assert json.loads((out / "summary.json").read_text())["queries"] == 30


def test_eps_runs_on_it(world, tmp_path, monkeypatch):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    person = expectation_teacher(world, policy_cfg=ExpectedPolicyConfig.fast())
    res = eps.train(world, eps_config("fast"), person, seeds=2, progress=False)
    assert np.all(np.isfinite(res["final_returns"])) and max(r[3] for r in res["curve"]) == 30
    scores = explicability_scores(jax.random.key(1), world, person, res["carry"].loop.sac.params.actor, 4)
    assert all(np.isfinite(s["score"]) for s in scores)
    out = tmp_path / "eps"
    argv = ["eps", "--env", SPEC, "--fast", "--seeds", "2", "--rollouts", "4", "--quiet", *QUIET_SAC, "--out", str(out)]
    assert main(argv) == 0
    assert (out / "explicability.json").exists() and not (out / "surrogate.png").exists()


def test_bad_envs_get_one_line_and_nothing_is_written(world, tmp_path, capsys, monkeypatch):
    import dataclasses
    import sys

    monkeypatch.syspath_prepend(str(EXAMPLE.parent))
    sys.modules.pop("point_mass", None)
    bad = {
        "nowhere.py:make_world": "no such file",
        f"{EXAMPLE}:make_planet": "has no function or class 'make_planet'",
        f"{EXAMPLE}:make_world,speed=2": "make_world() failed: TypeError",
        "gym:NoSuchEnv-v0": "gym:NoSuchEnv-v0",
    }
    (tmp_path / "syntax.py").write_text("def make_world(:\n")
    bad[f"{tmp_path / 'syntax.py'}:make_world"] = "cannot import"
    (tmp_path / "notworld.py").write_text("def make_world():\n    return 42\n")
    bad[f"{tmp_path / 'notworld.py'}:make_world"] = "returned int, not a mindgap World"
    (tmp_path / "shapes.py").write_text(
        "import dataclasses, point_mass as pm\n"
        "from mindgap.envs.interface import Box\n"
        "def make_world():\n"
        "    w = pm.make_world()\n"
        "    return dataclasses.replace(w, env=dataclasses.replace(w.env, observation_space=Box((3,))))\n"
    )
    bad[f"{tmp_path / 'shapes.py'}:make_world"] = "observe returns shape (2,), its observation space says (3,)"
    (tmp_path / "discrete.py").write_text(
        "import dataclasses, point_mass as pm\n"
        "from mindgap.envs.interface import Discrete\n"
        "def make_world():\n"
        "    w = pm.make_world()\n"
        "    return dataclasses.replace(w, env=dataclasses.replace(w.env, action_space=Discrete(5)))\n"
    )
    for spec, message in bad.items():
        out = tmp_path / "never"
        assert main(["sac", "--env", spec, "--out", str(out)]) == 2, spec
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err, (spec, err)
        assert not out.exists()
    # a world with discrete actions that PrefBias cannot take (its f_φ and f_ψ are Gaussians over
    # continuous moves; SAC, PEBBLE, DRLHP and EPS take them): refused before anything is written
    spec = f"{tmp_path / 'discrete.py'}:make_world"
    assert main(["prefbias", "--env", spec, "--out", str(tmp_path / "never")]) == 2
    err = capsys.readouterr().err.strip()
    assert "needs a continuous (Box) action space, got Discrete(n=5)" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "never").exists()
    # and the Python API refuses the same world with the same line
    from mindgap import prefbias

    discrete = dataclasses.replace(world, env=dataclasses.replace(world.env, action_space=Discrete(5)))
    with pytest.raises(EnvError, match="continuous"):
        prefbias.train(discrete, prefbias.fast(), progress=False)
    assert Box((2,)).dim == 2


README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.parametrize("method", ["sac", "pebble", "drlhp", "prefbias", "eps"])
def test_the_readme_snippet_of_each_method_runs(method, tmp_path, monkeypatch):
    """Here rather than in test_readme.py: the snippets use this file's configurations, so they compile nothing new."""
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    snippets = [
        s for s in re.findall(r"```python\n(.*?)```", README.read_text(), re.S) if f"import mindgap.{method} " in s
    ]
    assert len(snippets) == 1, method
    namespace: dict = {}
    exec(compile(snippets[0], "README.md", "exec"), namespace)
    result = namespace["result"]
    assert result["final_returns"].shape == (2, 20) and np.all(np.isfinite(result["final_returns"]))
    assert max(r[3] for r in result["curve"]) == (0 if method == "sac" else 30)
