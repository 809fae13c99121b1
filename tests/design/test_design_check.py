"""The design check: exact finite-horizon plans, the belief's identifiability, the verdict, the command."""

import dataclasses
import json

import numpy as np
import pytest

from mindgap.cli import main
from mindgap.commands.design import prefbias_overrides
from mindgap.design.design_check import DesignConfig, design_check
from mindgap.envs.terrain import world_from_dict
from mindgap.planning.finite_horizon import backward, forward
from mindgap.planning.terrain import discretise
from mindgap.teachers.preference import TeacherConfig

LAYOUT = "##########\n#G~~~~~~S#\n#.######.#\n#::::::::#\n##########"
SPEC = {
    "name": "corridors",
    "horizon": 40,
    "episode_ends": False,
    "layout": LAYOUT,
    "rewards": {"form": "state", "step": -1.0, "goal": 1.0},
    "dynamics": {"ice": {"stuck": 0.1}, "sand": {"speed": 0.5}},
    "beliefs": {"human": {"ice": {"stuck": 0.7}}},
}
CFG = DesignConfig(n=2)  # the command's settings at `--resolution 2`: the tests share its compiled programs


def _world(**patch):
    return world_from_dict({**SPEC, **patch})


@pytest.fixture(scope="module")
def valid():
    return design_check(_world(), cfg=CFG)


def test_a_world_with_an_identifiable_bias_on_the_shortcut_is_a_valid_test(valid):
    assert valid.outcomes["optimal"].ice > 0.1 and valid.outcomes["optimal"].sand < 1e-6  # the icy shortcut
    assert valid.outcomes["unaware"].sand > 0.1 and valid.outcomes["unaware"].ice < 0.02  # the sandy detour
    assert valid.normalised["unaware"] < 0.8 and valid.normalised["unbiased"] > 0.9
    assert valid.bias["ice"] < -0.3 and abs(valid.bias["sand"]) < 0.05  # −KL(Bern 0.1 ‖ Bern 0.7) ≈ −0.8 on moves
    (stuck,) = [p for p in valid.parameters if p.biased]
    assert stuck.name == "ice.stuck" and (stuck.truth, stuck.belief) == pytest.approx((0.1, 0.7))
    assert stuck.identified and stuck.z > 3
    assert all(c.met for c in valid.conditions) and valid.valid


def test_a_belief_in_more_noise_where_the_truth_is_precise_is_not_identified():
    """The truth produces one outcome (up to σ = 0.05): log T_H hardly varies between outcomes."""
    world = _world(beliefs={"human": {"ice": {"noise": 0.3}}}, dynamics={"sand": {"speed": 0.5}})
    chk = design_check(world, cfg=CFG)
    (noise,) = [p for p in chk.parameters if p.biased]
    assert noise.name == "ice.noise" and not noise.identified and not chk.valid


def test_deterministic_answers_identify_no_belief():
    chk = design_check(_world(), cfg=dataclasses.replace(CFG, teacher=TeacherConfig(beta=None)))
    assert all(not np.isfinite(p.stderr) for p in chk.parameters) and not chk.identifiable
    assert not chk.conditions[0].met and "no scale" in chk.conditions[0].why


def test_the_dissertation_s_conventions_are_reported_as_broken_conditions():
    world = _world(episode_ends=True, rewards={"step": -1.0, "goal": 10.0, "progress": 1.0})
    texts = {c.text: c.met for c in design_check(world, cfg=CFG).conditions}
    assert not texts["r_H depends on (s, a) only, as the learner's r_w does"]
    assert not texts["segments have equal length (a fixed horizon)"]


def test_finite_horizon_values_on_a_corridor_match_a_hand_count():
    """From the start, 6 cells of ice at 0.5 cell a step, then in the goal: the
    planned value is the expected number of steps outside the goal, negated."""
    world = _world(dynamics={"ice": {"stuck": 0.0}, "sand": {"speed": 0.5}})
    d = discretise(world.params, 2)
    v0, policy = backward(d, d.rewards, world.horizon)
    out = forward(d, world.params, policy, d.rewards)
    assert out.goal > 0.99 and out.ice > 0
    assert -16.5 < out.ret < -12.5  # 7 cells from the start's centre to the goal's edge: about 14 steps
    assert forward(d, world.params, "uniform", d.rewards).ret < out.ret - 10


def _corridors_file(tmp_path):
    """The corridors world as a world file: ice truly sticks 1 step in 10, the person believes 7."""
    path = tmp_path / "corridors.toml"
    path.write_text(
        'name = "corridors"\nhorizon = 40\nepisode_ends = false\nlayout = """\n' + LAYOUT + '\n"""\n'
        '[rewards]\nform = "state"\nstep = -1.0\ngoal = 1.0\n[dynamics]\nice = { stuck = 0.1 }\n'
        "sand = { speed = 0.5 }\n[beliefs.human]\nice = { stuck = 0.7 }\n"
    )
    return path


def test_the_command_prints_writes_and_refuses(tmp_path, capsys):
    path = _corridors_file(tmp_path)
    out = tmp_path / "check"
    assert main(["design", "check", str(path), "--resolution", "2", "--out", str(out)]) == 0
    assert "verdict: VALID test of PrefBias" in capsys.readouterr().out
    rec = json.loads((out / "corridors.json").read_text())
    assert rec["valid"] and rec["parameters"][0]["name"] == "floor.speed"
    bad = tmp_path / "bad.toml"
    bad.write_text(path.read_text().replace('form = "state"', 'form = "episode"'))
    assert main(["design", "check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "form must be one of transition, state" in err and err.count("\n") == 1
    assert main(["design", "check", "examples/point_mass.py:make_world"]) == 2
    assert "not a terrain world" in capsys.readouterr().err


def test_the_command_fits_the_belief_by_maximum_likelihood(tmp_path, capsys):
    path = _corridors_file(tmp_path)
    out = tmp_path / "check"
    assert main(["design", "check", str(path), "--resolution", "2", "--fit", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "maximum-likelihood fit to 800 simulated answers (β = 1)" in text
    (line,) = [ln for ln in text.splitlines() if ln.strip().startswith("ice.stuck") and "recovered" in ln]
    assert "0.100 →  0.700" in line
    fit = json.loads((out / "corridors.json").read_text())["fit"]
    (stuck,) = [p for p in fit["parameters"] if p["name"] == "ice.stuck"]
    assert stuck["verdict"] == "recovered" and stuck["z_belief"] <= 3 <= stuck["z_truth"]
    assert fit["profile"]["name"] == "ice.stuck" and len(fit["profile"]["grid"]) == 10
    assert main(["design", "check", str(path), "--resolution", "2", "--fit", "--beta", "inf"]) == 1
    assert "maximum-likelihood fit: not run: deterministic answers" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, msg",
    [
        (["--set", "nonsense=1"], "expected FIELD=VALUE with FIELD one of"),
        (["--set", "belief_prior_std=-1"], "belief_prior_std must be positive"),
        (["--set", "absorbing=no"], "absorbing is true or false"),
        (["--updates", "30"], "multiple of check_every"),
        (["--rounds", "7"], "multiple of rounds"),
    ],
)
def test_the_recovery_command_names_bad_input_in_one_line(tmp_path, capsys, extra, msg):
    out = tmp_path / "rec"
    assert main(["design", "recovery", "nav1", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.strip().count("\n") == 0
    assert not out.exists()


def test_set_reads_a_switch_as_a_boolean():
    """`absorbing=false` turns the switch off: read as a literal it was the string "false", which is true."""
    got = prefbias_overrides(["absorbing=false", "stay_head=True", "log_f_floor=-20", "absorbing_state=single"])
    assert got == {"absorbing": False, "stay_head": True, "log_f_floor": -20, "absorbing_state": "single"}
    assert got["absorbing"] is False


def test_the_oracle_line_says_whether_every_seed_beats_random(tmp_path):
    from mindgap.commands.design import oracle_line

    jobs = tmp_path / "jobs"
    jobs.mkdir()
    (jobs / "nav2__reference.json").write_text(json.dumps({"random_return": -138.0}))
    (jobs / "nav2__sac.json").write_text(json.dumps({"final": [-43.7, -209.0, -44.6]}))
    text, rec = oracle_line(tmp_path, "nav2")
    assert "2 of 3 SAC seeds above" in text and "NOT reliable" in text and rec["lowest"] == -209.0
    (jobs / "nav2__sac.json").write_text(json.dumps({"final": [-43.7, -44.6]}))
    assert oracle_line(tmp_path, "nav2")[1]["reliable"]
    assert "no finished SAC" in oracle_line(tmp_path, "nav1")[0]

