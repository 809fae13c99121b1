"""A new preference learner in one file (examples/linear_pebble.py) runs through ``methods.train``, its
generated command and a grid sweep, with no edit elsewhere; the command and the grid give the same run."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from mindgap.cli import main
from mindgap.envs.resolve import import_module
from mindgap.experiments import prefbias_common as pc
from mindgap.experiments._runfolder import RunFolder
from mindgap.sweeps import grid as sweep_grid

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "linear_pebble.py"


@pytest.fixture(scope="module")
def method():
    return import_module(str(EXAMPLE)).METHOD


def _flags(base, cfg, prefix="") -> list[str]:
    """The derived flags that turn config ``base`` into ``cfg``."""
    out = []
    for f in dataclasses.fields(cfg):
        a, b = getattr(base, f.name), getattr(cfg, f.name)
        if a == b:
            continue
        if dataclasses.is_dataclass(b):
            out += _flags(a, b, prefix + f.name + ".")
            continue
        flag = "--" + (prefix + f.name).replace("_", "-")
        if isinstance(b, bool):
            out.append(flag if b else flag.replace("--", "--no-", 1))
        else:
            out += [flag, ",".join(map(str, b)) if isinstance(b, tuple) else str(b)]
    return out


def test_the_example_is_one_file_of_at_most_150_lines():
    assert len(EXAMPLE.read_text().splitlines()) <= 150


def test_a_new_learner_runs_through_a_grid_and_its_generated_command(method, tmp_path, monkeypatch, capsys):
    assert "linear-pebble" in sweep_grid.grid_methods()
    grid = sweep_grid.GridConfig(methods=("linear-pebble",), worlds=("d1",), preset="fast")
    jobs = sweep_grid.jobs(grid)
    assert [j.key for j in jobs] == ["d1/reference", "d1/linear-pebble"]
    folder = RunFolder(tmp_path / "grid", grid)
    pc.run_jobs(folder, jobs, 1, fresh=False, progress=False, assemble_only=False)
    summary = sweep_grid.assemble(grid, tmp_path / "grid")
    assert summary["rows"] == 1 and summary["missing_jobs"] == 0
    record = folder.done("d1/linear-pebble")
    assert record["curve"][-1][3] == jobs[1].cfg.queries  # the whole budget asked and answered
    assert record["reward_error"] is not None  # read through the record's learned_reward

    # the generated command: every field a flag; the grid's config given as flags is the same run
    monkeypatch.setenv("MINDGAP_METHODS", str(EXAMPLE))
    flags = _flags(method.preset("fast"), jobs[1].cfg)
    out = tmp_path / "cli"
    argv = ["linear-pebble", "--env", "d1", "--fast", "--out", str(out), "--quiet", *flags]
    assert main(argv) == 0
    assert "PEBBLE, linear reward (biased teacher) on d1" in capsys.readouterr().out
    config = json.loads((out / "config.json").read_text())["config"]
    assert config == json.loads(json.dumps(jobs[1].cfg.as_dict()))
    summary = json.loads((out / "summary.json").read_text())
    np.testing.assert_allclose(summary["final_return_per_seed"], record["final"], rtol=1e-6)


def test_a_bad_methods_file_is_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINDGAP_METHODS", str(tmp_path / "missing.py"))
    assert main(["linear-pebble", "--help"]) == 2
    assert capsys.readouterr().err.strip().startswith("mindgap: error: MINDGAP_METHODS: no such file")


def test_a_new_learner_joins_the_nav_experiment_beside_pebble(method, tmp_path, monkeypatch, capsys):
    from mindgap.algorithms.engine import Schedule
    from mindgap.experiments import prefbias_nav, registry

    cfg = registry.configure("nav", "fast", worlds=("d1",), methods=("linear-pebble",))
    assert registry.preset_of("nav", cfg) == "fast"  # an option of the preset, not a custom configuration
    jobs = {j.key: j for j in prefbias_nav.jobs(cfg)}
    job, pebble = jobs["d1/linear-pebble-q30"], jobs["d1/pebble-q30"]
    for f in dataclasses.fields(Schedule):  # PEBBLE's schedule, budget and person; its own models
        if f.name != "method":
            assert getattr(job.cfg, f.name) == getattr(pebble.cfg, f.name), f.name
    assert job.cfg.sampler == method.preset("full").sampler and job.label == f"{method.label} (30 queries)"
    out = tmp_path / "nav"
    line = registry.command("nav", cfg, out)
    assert line == f"mindgap reproduce nav --fast --worlds d1 --method linear-pebble --out {out}"

    monkeypatch.setenv("MINDGAP_METHODS", str(EXAMPLE))
    argv = ["reproduce", "nav", "--fast", "--quiet", "--env", "d1", "--method", "linear-pebble", "--out", str(out)]
    assert main([*argv, "--job", "d1/linear-pebble-q30"]) == 0
    record = json.loads((out / "jobs" / "d1__linear-pebble-q30.json").read_text())
    assert record["method"] == "linear-pebble" and record["curve"][-1][3] == 30 and record["reward_error"] is not None
    assert record["command"] == f"{line} --job d1/linear-pebble-q30"
    # refused in one line: a method that learns no reward from preferences, an unknown one, another experiment
    for bad in (["--method", "sac"], ["--method", "nonesuch"]):
        assert main(["reproduce", "nav", "--fast", "--env", "d1", *bad, "--out", str(tmp_path / "x")]) == 2
    assert main(["reproduce", "eps", "--fast", "--method", "linear-pebble"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "learns no reward from preferences" in err[0] and "unknown method 'nonesuch'" in err[1]
    assert "--method adds learners to nav and gym" in err[2]
