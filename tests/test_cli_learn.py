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
    assert main(["sac", "--world", "d1", "--noise-color", "-1", "--out", str(tmp_path)]) == 2
    assert "noise_color must be non-negative" in capsys.readouterr().err
    assert main(["sac", "--world", "d1", "--entropy-bonus", "-0.5", "--out", str(tmp_path)]) == 2
    assert "entropy_bonus must be non-negative" in capsys.readouterr().err


def test_queries_from_is_a_flag_of_every_learner_that_asks_and_a_checked_schedule_field():
    from mindgap.algorithms.eps_config import EPSConfig
    from mindgap.algorithms.pbrl import method_config
    from mindgap.cli import _parser

    parse = _parser().parse_args
    for cmd in ("pebble", "drlhp", "prefbias", "eps"):
        assert parse([cmd, "--world", "d1", "--out", "x"]).queries_from == "anywhere"
        assert parse([cmd, "--world", "d1", "--out", "x", "--queries-from", "start"]).queries_from == "start"
    assert method_config("pebble", queries_from="start").as_dict()["queries_from"] == "start"
    assert "queries_from" not in method_config("pebble").as_dict()  # earlier run folders still resume
    with pytest.raises(ValueError, match="queries_from must be one of anywhere, start"):
        EPSConfig(queries_from="middle").check()


def test_exploration_flags_reach_the_sac_config():
    from mindgap.algorithms.engine import EXPLORATION
    from mindgap.algorithms.pbrl import method_config
    from mindgap.cli import _parser
    from mindgap.commands.learn import fill_from_preset, sac_config
    from mindgap.experiments import eps_common as ec
    from mindgap.experiments.prefbias_common import learners

    def explore(cfg):  # of a SACConfig or the parsed command line
        return {"noise_color": cfg.noise_color, "entropy_bonus": cfg.entropy_bonus}

    parse = _parser().parse_args
    plain = {"noise_color": 0.0, "entropy_bonus": 0.0}
    # every learner explores alike by default; flags override it
    for cmd in ("sac", "pebble", "drlhp", "prefbias", "eps"):
        assert explore(parse([cmd, "--world", "d1", "--out", "x"])) == EXPLORATION != plain
    flags = ["--noise-color", "2", "--entropy-bonus", "0.5"]

    def parsed_sac(argv):  # as the command builds it: the preset's widths and steps, then the flags
        args = parse(argv)
        fill_from_preset(args, method_config(args.command))
        return sac_config(args)

    assert explore(parsed_sac(["drlhp", "--world", "d1", "--out", "x", *flags])) == {
        "noise_color": 2.0,
        "entropy_bonus": 0.5,
    }
    assert explore(parsed_sac(["sac", "--world", "d1", "--out", "x", "--noise-color", "0"]))["noise_color"] == 0
    # and so do the experiments' full learners, the oracle with the rest
    full = learners("full")
    assert explore(full.sac.sac) == explore(full.pebble.sac) == explore(full.prefbias.sac) == EXPLORATION
    person = ec.learners("full")
    assert explore(person.eps.sac) == explore(person.sac.sac) == EXPLORATION
    assert explore(person.person.sac) == plain  # the simulated person's π_H is not one of the learners


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
