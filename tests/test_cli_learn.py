"""``mindgap sac|pebble|drlhp`` on the command line."""

import csv
import json

import pytest

from mindgap.cli import main

WORLD = 'name = "strip"\nhorizon = 20\nlayout = """\n########\n#S....G#\n########\n"""\n[rewards]\ngoal = 10.0\nstep = -1.0\n'


def test_bad_arguments_are_refused(tmp_path, capsys):
    assert main(["sac", "--world", "moon", "--out", str(tmp_path)]) == 2
    assert "unknown world 'moon'" in capsys.readouterr().err
    assert main(["pebble", "--world", "d1", "--hidden", "big", "--out", str(tmp_path)]) == 2
    assert "--hidden must look like" in capsys.readouterr().err
    assert main(["drlhp", "--world", "d1", "--steps", "1500", "--out", str(tmp_path)]) == 2
    assert "multiple of chunk" in capsys.readouterr().err


@pytest.mark.slow
def test_sac_run_writes_curve_pictures_and_resumes(tmp_path, capsys):
    world = tmp_path / "strip.toml"
    world.write_text(WORLD)
    args = ["sac", "--world", str(world), "--steps", "3000", "--seeds", "2", "--hidden", "16,16", "--quiet"]
    out = tmp_path / "run"
    assert main([*args, "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "curve.csv").open()))
    assert [k for k in rows[0]] == ["seed", "env_steps", "return", "queries"]
    assert {int(r["env_steps"]) for r in rows} == {2000, 3000}
    assert (out / "curve.png").stat().st_size > 0 and (out / "trajectories.png").stat().st_size > 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["final_return_per_seed"]) == 2
    assert main([*args, "--out", str(out)]) == 0  # finished run: resumes at the end, same curve
    assert list(csv.DictReader((out / "curve.csv").open())) == rows
