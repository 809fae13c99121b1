"""``mindgap worlds list|show|plan`` from the command line."""

import json

from mindgap.cli import main

WORLD = """
name = "fork"
horizon = 40
layout = '''
#######
#~~~~~#
#S###G#
#:::::#
#######
'''
[rewards]
goal = 10.0
step = -1.0
[dynamics]
sand = { speed = 0.5, stuck = 0.5 }
[beliefs.person]
ice = { speed = 0.3, noise = 0.3 }
sand = { speed = 0.9, stuck = 0.0 }
[expect]
true_prefers = "ice"
belief_prefers = "sand"
"""


def test_list_names_the_six_worlds(capsys):
    assert main(["worlds", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in ("nav1", "nav2", "d1", "d2", "d3", "d4"))


def test_show_draws_a_world_and_its_belief(tmp_path, capsys):
    assert main(["worlds", "show", "d3", "--out", str(tmp_path / "d3.svg")]) == 0
    assert (tmp_path / "d3.svg").read_text().startswith("<?xml")
    assert main(["worlds", "show", "d3", "--belief", "--out", str(tmp_path / "noise.png")]) == 0
    assert (tmp_path / "noise.png").stat().st_size > 1000


def test_plan_a_world_file(tmp_path, capsys):
    path = tmp_path / "fork.toml"
    path.write_text(WORLD)
    out = tmp_path / "plan"
    assert main(["worlds", "plan", str(path), "--resolution", "3", "--rollouts", "20", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "[ok] optimal route spends more steps on ice" in printed and "reference return" in printed
    report = json.loads((out / "plan.json").read_text())["fork"]
    assert report["optimal"]["ice"] > report["optimal"]["sand"]
    assert report["expected"]["sand"] > report["expected"]["ice"]
    for name in ("fork-routes.png", "fork-routes.svg", "fork-rollout.gif"):
        assert (out / name).stat().st_size > 0


def test_plan_fails_when_the_behaviour_is_not_shown(tmp_path, capsys):
    path = tmp_path / "wrong.toml"
    path.write_text(WORLD.replace('belief_prefers = "sand"', 'belief_prefers = "ice"'))
    assert main(["worlds", "plan", str(path), "--resolution", "3", "--rollouts", "20", "--out", str(tmp_path)]) == 1
    assert "FAILED" in capsys.readouterr().out


def test_malformed_world_file_names_row_and_column(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(WORLD.replace("#S###G#", "#S##xG#"))
    assert main(["worlds", "show", str(path), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "row 3, column 5: unknown character 'x'" in err and "bad.toml" in err
    assert not (tmp_path / "x.png").exists()


def test_unknown_world_is_an_error(tmp_path, capsys):
    assert main(["worlds", "plan", "moon", "--out", str(tmp_path)]) == 2
    assert "unknown world 'moon'" in capsys.readouterr().err
