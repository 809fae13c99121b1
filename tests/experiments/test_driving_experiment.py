"""The driving study (``mindgap reproduce driving``): files, values, resume, bad input.

As for the EPS experiments, the default test runs the ``--fast`` preset through the CLI with the
expensive training replaced by stand-ins of the real shape: every participant's π_H is a
hand-made categorical policy (brake when the front car brakes, or change lane), and each
learner's "training" returns actors that drive by a fixed rule (SAC changes lane at once,
DRLHP brakes in its lane, EPS brakes and then changes lane). Everything after training runs
for real: recruiting with the sanity item, r_A from the answers, the greedy episodes in the
sleety world and the behaviours measured on them, the new participants' ratings, Table 5,
the claims, the highway-env frames and GIFs, the report, and resuming.
"""

import csv
import dataclasses
import json
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.cli import main
from mindgap.envs.driving import STUDY_IMPORTANCE, importance_weights
from mindgap.envs.driving.params import IDLE, LANE_LEFT, SLOWER
from mindgap.experiments import driving
from mindgap.experiments._runfolder import to_jsonable
from mindgap.models.mlp import init_mlp
from report_check import check_report

OBS = 11


def _rule_actor(kind: str, hidden=(16,)):
    """A categorical actor whose greedy action follows a rule of the observation (a tiny ReLU network
    set by hand): ``brake`` SLOWER once the front car brakes, ``steer`` LANE_LEFT from the start,
    ``brake_then_steer`` SLOWER while faster than 23 m/s after the onset, then LANE_LEFT."""
    layers = [(w * 0, b * 0) for w, b in init_mlp(jax.random.key(0), (OBS, *hidden, 5))]
    (w0, b0), (w1, b1) = layers[0], layers[-1]
    w0 = w0.at[7, 0].set(1.0)  # h0 = braking flag
    w0 = w0.at[2, 1].set(30.0).at[7, 1].set(30.0)  # h1 = speed + 30 flag
    b0 = b0.at[1].set(-53.0)  # h1 > 0 once the front car brakes, while faster than 23 m/s
    if kind == "brake":
        w1, b1 = w1.at[0, SLOWER].set(10.0), b1.at[IDLE].set(5.0)
    elif kind == "steer":
        b1 = b1.at[LANE_LEFT].set(5.0)
    else:
        w1 = w1.at[1, SLOWER].set(50.0).at[0, LANE_LEFT].set(10.0)
        b1 = b1.at[IDLE].set(5.0)
    middle = [(w.at[0, 0].set(1.0).at[1, 1].set(1.0), b) for w, b in layers[1:-1]]  # pass h0, h1 on
    return ((w0, b0), *middle, (w1, b1))


RULES = {"sac": "steer", "drlhp": "brake", "eps": "brake_then_steer"}


@pytest.fixture
def stand_ins(monkeypatch):
    calls = []

    def fake_policies(world, drivers, cfg):
        kinds = ["brake" if d.biased else "steer" for d in drivers]
        return jax.tree.map(lambda *x: jnp.stack(x), *[_rule_actor(k, cfg.person.sac.hidden) for k in kinds])

    def fake_train(folder, cfg, world, people, job, seeds, *, fresh, progress):
        calls.append(job.key)
        if job.method != "sac":
            crowd = driving.crowd_teacher(folder, cfg, world, people)
            assert crowd.size == cfg.participants
        hidden = job.cfg.sac.hidden
        actors = jax.tree.map(lambda *x: jnp.stack(x), *[_rule_actor(RULES[job.method], hidden)] * seeds)
        loop = SimpleNamespace(sac=SimpleNamespace(params=SimpleNamespace(actor=actors)))
        curve = [(s, t, 1.0, 0) for t in (500, 1000, 1500) for s in range(seeds)]
        return {"curve": curve, "final_returns": np.ones((seeds, 4)), "carry": SimpleNamespace(loop=loop)}

    monkeypatch.setattr(driving, "train_expected_policies", fake_policies)
    monkeypatch.setattr(driving, "train", fake_train)
    return calls


def test_driving_fast_table5_behaviours_figures_and_resume(stand_ins, tmp_path, capsys):
    out = tmp_path / "driving"
    argv = ["reproduce", "driving", "--fast", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert stand_ins == ["driving/sac", "driving/drlhp", "driving/eps", "driving/drlhp-coin"]
    assert "| avg. rating (dissertation) | 7.6 | 5.0 | 5.9 |" in printed
    check_report(out, tmp_path / "report", "driving")
    with (out / "results.csv").open() as f:
        by = {r["method"]: r for r in csv.DictReader(f)}
    # measured on the rules' episodes in the sleety world
    assert float(by["sac"]["changed_mean"]) == 1.0 and float(by["sac"]["collided_mean"]) == 0.0
    assert float(by["sac"]["first_change_mean"]) < 0  # before the front car brakes: at once
    assert float(by["drlhp"]["changed_mean"]) == 0.0 and float(by["drlhp"]["braked_first_mean"]) == 1.0
    assert float(by["eps"]["braked_first_mean"]) > 0.5 and float(by["eps"]["changed_mean"]) > 0.5
    assert float(by["drlhp"]["min_gap_mean"]) < 10.0 and float(by["drlhp"]["collided_mean"]) > 0.5  # braking on sleet
    assert float(by["sac"]["return_mean"]) > float(by["drlhp"]["return_mean"])
    # the raters expect braking (the biased ones by the stand-in π_H): the in-lane brakers are rated above SAC
    ratings = [r for r in csv.DictReader((out / "ratings.csv").open()) if r["valid"] == "True"]
    assert {r["method"] for r in ratings} == {"eps", "sac", "drlhp", "sanity"}
    # the same episodes in a rollouts file, for people to rate in the study app's driving-testing study
    from mindgap.data.rollouts_file import read_rollouts

    shown = read_rollouts(out / "rollouts.json")
    assert shown["domain"] == {"name": "driving", "sleet": 1.0}
    assert sorted((r["method"], r["seed"], r["episode"]) for r in shown["records"]) == sorted(
        {(r["method"], int(r["seed"]), int(r["episode"])) for r in ratings}
    )
    people = json.loads((out / "jobs" / "driving__people.json").read_text())
    assert people["valid"] == 4 and len(people["engineered_weights"]) == 4
    assert sum(people["engineered_weights"]) == pytest.approx(1.0, abs=1e-5)
    summary = json.loads((out / "summary.json").read_text())
    claims = {c["id"]: c for c in summary["claims"]}
    assert {"driving/eps-rated-highest", "driving/sac-steers-first"} <= set(claims)
    assert claims["driving/eps-brakes-then-steers"]["held"]
    # the control: DRLHP on coin-flip answers (the stand-in brakes whatever it is told, so the claim fails)
    control = claims["driving/control"]
    assert control["held"] is False and "coin flips 1 of 1" in control["measured"]
    assert by["drlhp-coin"]["seeds_braking_first"] == "1" and "DRLHP, coin flips" in (out / "table.md").read_text()
    for name in ("frames_eps.png", "episode_sac.gif", "participants.csv", "table.md", "curves.csv"):
        assert (out / name).stat().st_size > 0, name

    stamps = {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")}
    assert main(argv) == 0  # a rerun reads everything back
    assert len(stand_ins) == 4 and capsys.readouterr().out == printed
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")} == stamps


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--sleet", "1.5"], "sleet must be in [0, 1]"),
        (["--traffic", "5"], "traffic must be in 0 … 4"),
        (["--importance", "3,4,6,2"], "importance ratings must be in [1, 5]"),
        (["--importance", "3,4"], "importance must hold 4 ratings"),
        (["--importance", "a,b,c,d"], "--importance takes four numbers"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(flags, message, tmp_path, capsys):
    assert main(["reproduce", "driving", "--fast", "--out", str(tmp_path / "x"), *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert main(["reproduce", "eps", "--fast", "--sleet", "0.5"]) == 2
    assert "--sleet belongs to the driving study" in capsys.readouterr().err


def test_presets_and_the_rerun_command():
    from mindgap.experiments import registry

    full, fast = driving.preset("full"), driving.preset("fast")
    assert full.seeds == 5 and full.eps.lam == 2.0 and full.participants == 14 and full.raters == 15
    assert registry.preset_of("driving", fast) == "fast"
    line = registry.command("driving", full.__class__(sleet=0.5), "runs/d")
    assert line == "mindgap reproduce driving --sleet 0.5 --out runs/d"
    busy = dataclasses.replace(full, traffic=4)
    assert registry.preset_of("driving", busy) == "full"
    assert registry.command("driving", busy, "runs/d") == "mindgap reproduce driving --traffic 4 --out runs/d"
    assert driving.world_of(busy).params.n_traffic == 4
    pytest.importorskip("highway_env")
    from mindgap.experiments.driving_report import highway_version

    drawn = highway_version(busy, importance_weights(STUDY_IMPORTANCE))  # the figures' road: the same cars
    assert drawn.observation_space.shape == (driving.world_of(busy).env.observation_space.dim,)
    drawn.close()
    assert full.answers_by == "rollout-behaviour" and full.rollout and not full.crash
    drlhp = dataclasses.replace(full.eps, method="drlhp")
    assert full.eps.sac.survival_entropy == "neutral" and drlhp.agent_sac().survival_entropy == "neutral"
    assert dataclasses.replace(full.eps, method="eps").agent_sac().survival_entropy == "paid"  # Eq. 4.6's own H_π
    assert driving._sac_cfg(full).sac.survival_entropy == "neutral"
    crash = dataclasses.replace(full, answers_by="rollout")
    assert crash.rollout and crash.crash
    assert registry.command("driving", crash, "runs/d") == "mindgap reproduce driving --answers-by rollout --out runs/d"
    for way in ("expectation", "decisions"):
        other = dataclasses.replace(full, answers_by=way)
        assert registry.preset_of("driving", other) == "full" and not other.rollout
        assert (
            registry.command("driving", other, "runs/d") == f"mindgap reproduce driving --answers-by {way} --out runs/d"
        )
    # a run folder from before the field: it answered by its states, log T_H left out when use_belief was off
    old = json.loads(json.dumps(to_jsonable(full)))
    del old["answers_by"]
    old["teacher"]["use_belief"] = False
    assert registry.command("driving", old, "runs/d").startswith("mindgap reproduce driving --answers-by decisions")


def test_answers_by_decisions_reaches_the_participants(tmp_path, monkeypatch):
    """``--answers-by decisions`` sets how the participants answer (log π_H alone); only the driving study takes it."""
    seen = []
    monkeypatch.setattr(driving, "run", lambda cfg, out, **kw: seen.append(cfg) or {"job": {}})
    assert main(["reproduce", "driving", "--fast", "--answers-by", "decisions", "--job", "driving/people"]) == 0
    assert seen[0].answers_by == "decisions" and seen[0].answer_cfg.use_belief is False
    assert seen[0].answer_cfg.beta == 1.0 and not seen[0].rollout
    # and DRLHP and EPS hand it to the crowd: the engine has a person answer by the learner's teacher config
    learners = {job.key: job.cfg for job in driving.jobs(seen[0]) if job.method in ("drlhp", "eps")}
    assert sorted(learners) == ["driving/drlhp", "driving/drlhp-coin", "driving/eps"]
    assert learners["driving/drlhp"].teacher == learners["driving/eps"].teacher == seen[0].answer_cfg
    assert learners["driving/drlhp-coin"].teacher == dataclasses.replace(seen[0].answer_cfg, beta=0.0)  # a fair coin
    assert main(["reproduce", "eps", "--fast", "--answers-by", "decisions"]) == 2
    with pytest.raises(SystemExit):  # argparse's one line
        main(["reproduce", "driving", "--fast", "--answers-by", "states"])


def test_workers_run_the_participants_first_and_the_testing_phase_last():
    """A sweep backend runs jobs apart: each learner waits for the participants, the testing phase for all."""
    from mindgap.experiments import registry

    jobs = dict(registry.jobs("driving", registry.module("driving").preset("fast")))
    assert jobs["driving/people"] == ()
    assert all(jobs[f"driving/{m}"] == ("driving/people",) for m in ("sac", "drlhp", "eps"))
    assert set(jobs["driving/testing"]) == {"driving/people", "driving/sac", "driving/drlhp", "driving/eps"}


def test_each_participant_keeps_the_seed_whose_greedy_episodes_earn_the_most(monkeypatch):
    """π_H is trained with several seeds per participant; the kept one is the best by the score (here a
    stand-in score, the actor's first-layer sum, so that the choice can be checked)."""
    from mindgap.algorithms.expected_policy import ExpectedPolicyConfig
    from mindgap.algorithms.sac import SACConfig
    from mindgap.envs.driving import make_world
    from mindgap.teachers.drivers import Driver

    world = make_world()
    person = ExpectedPolicyConfig(
        total_steps=200, chunk=100, seeds=3, sac=SACConfig(hidden=(8,), batch_size=16, learning_starts=100)
    )
    cfg = dataclasses.replace(driving.preset("fast"), person=person)
    drivers = [Driver("a", True, (3, 5, 3, 4), 0.0), Driver("b", True, (4, 4, 4, 4), 1.0)]

    def kept(sign):
        monkeypatch.setattr(driving, "_greedy_return_h", lambda key, actor, *a: sign * jnp.sum(actor[0][0]))
        return np.asarray(jnp.sum(driving.train_expected_policies(world, drivers, cfg)[0][0], axis=(1, 2)))

    best, worst = kept(1.0), kept(-1.0)
    assert best.shape == (2,) and np.all(best > worst)  # the same three seeds each time, ranked both ways


def test_the_smallest_gap_counts_only_cars_in_line():
    """A car passing beside the front car mid-lane-change has no bumper gap to it: 2.4 m apart sideways
    (more than a car's 2 m width) and 3 m apart lengthwise is not a gap of -2 m."""
    from mindgap.envs.driving.world import DIST_SCALE, EGO_OBS

    obs = np.zeros((1, 4, EGO_OBS + 3), np.float32)
    ego_y = [1.0, 1.0, 1.6, 1.4]  # lane widths: in the lane, then beside it, then back nearly in line
    ahead = [20.0, 18.0, 3.0, 12.0]  # metres, centre to centre
    obs[0, :, 0], obs[0, :, 3] = ego_y, 1.0
    obs[0, :, EGO_OBS], obs[0, :, EGO_OBS + 1] = np.asarray(ahead) / DIST_SCALE, 1.0
    b = driving.behaviour(obs, np.full((1, 3, 1), IDLE, np.float32), np.ones((1, 3), bool), None)
    # in line at steps 0, 1 (gaps 15, 13 m) and 3 (0.4 lane widths = 1.6 m apart: gap 7 m); step 2 is beside
    assert b["min_gap"][0] == pytest.approx(7.0) and not b["collided"][0]


@pytest.mark.parametrize("braked_first, changed, held", [(0.0, 1.0, False), (1.0, 1.0, True), (0.0, 0.2, True)])
def test_drlhp_must_brake_in_lane_for_its_claim(braked_first, changed, held):
    """Closest to the front car is not enough: DRLHP must also brake before changing lane, or stay in lane."""
    from mindgap.experiments.driving_report import _claims

    row = dict(rating_mean=5.0, return_mean=10.0, first_change_mean=0.0, braked_first_mean=0.0, changed_mean=1.0)
    by = {m: dict(row, min_gap_mean=40.0, collided_mean=0.0) for m in ("eps", "sac")}
    by["drlhp"] = dict(row, min_gap_mean=20.0, collided_mean=0.0, braked_first_mean=braked_first, changed_mean=changed)
    claim = next(c for c in _claims(by) if c["id"] == "driving/drlhp-brakes-in-lane")
    assert claim["held"] is held


def test_the_preference_sanity_item_keeps_every_attentive_recruit(stand_ins, tmp_path, capsys):
    """By default recruits answer the sanity item by which clip they prefer (Σ r_H over the same
    moments), so the crash's penalty settles it for the attentive, steerers included; the item is
    still asked, and ``--sanity expectation`` (the earlier runs' item) is an option."""
    out = tmp_path / "run"
    argv = ["reproduce", "driving", "--fast", "--out", str(out), "--job", "driving/people"]
    assert main(argv) == 0
    assert json.loads((out / "config.json").read_text())["sanity"] == "preference"
    rows = json.loads((out / "jobs" / "driving__people.json").read_text())["participants"]
    assert rows and all(not r["dropped"] for r in rows if r["attentive"])
    assert any(not r["attentive"] for r in rows) or len(rows) == 4  # only the inattentive can be dropped
    with pytest.raises(ValueError, match="sanity must be 'expectation' or 'preference'"):
        dataclasses.replace(driving.preset("fast"), sanity="vote")
    from mindgap.experiments import registry

    old = dataclasses.replace(driving.preset("full"), sanity="expectation")
    assert registry.command("driving", old, "runs/d") == "mindgap reproduce driving --sanity expectation --out runs/d"
    # a run folder from before the option existed holds no ``sanity``: it was the expectation item
    plain = {k: v for k, v in registry._plain(driving.preset("full")).items() if k != "sanity"}
    assert "--sanity expectation" in registry.command("driving", plain, "runs/d")


def test_the_participant_gates_read_what_the_participants_want_and_expect(stand_ins, tmp_path, capsys):
    """``mindgap design driving --run DIR``: a braker's π_H (the stand-in of every dry-road believer) slows at
    the onset and, playing the clips out in the dry road they believe in, finds braking in lane on sleet the
    most expected of the five scripted responses; judged at the clips' own states (log T_H of each weak
    braking step at its floor) it does not."""
    out = tmp_path / "run"
    assert main(["reproduce", "driving", "--fast", "--quiet", "--out", str(out), "--job", "driving/people"]) == 0
    capsys.readouterr()
    status = main(["design", "driving", "--run", str(out), "--episodes", "8"])
    printed = capsys.readouterr().out
    g = json.loads((out / "gates.json").read_text())
    rows = json.loads((out / "jobs" / "driving__people.json").read_text())["participants"]
    brakers = sum(1 for r in rows if not r["dropped"] and r["believed_sleet"] == 0.0)
    assert g["answers_by"] == "rollout-behaviour" and g["gates"]["slows_at_onset"]["value"] == brakers
    assert g["gates"]["braking_most_expected_on_sleet"]["value"] == brakers
    assert "slows_at_onset" in printed and status == (0 if all(v["holds"] for v in g["gates"].values()) else 1)
    assert main(["design", "driving", "--run", str(out), "--episodes", "8", "--answers-by", "expectation"]) in (0, 1)
    states = json.loads((out / "gates-expectation.json").read_text())
    assert states["gates"]["braking_most_expected_on_sleet"]["value"] < brakers or brakers == 0
    assert main(["design", "driving", "--run", str(tmp_path / "none")]) == 2
    assert "no finished participants job" in capsys.readouterr().err


def test_a_learner_control_changes_one_thing_and_resumes(stand_ins, tmp_path, capsys, monkeypatch):
    """``mindgap design driving --run DIR --learner M ...``: the learner trains on the run's participants with
    the answers by coin (β = 0), by one participant, or an exact per-step score; its record is kept."""
    from mindgap.algorithms import eps as eps_alg
    from mindgap.experiments import driving_controls as dc

    out = tmp_path / "run"
    assert main(["reproduce", "driving", "--fast", "--quiet", "--out", str(out), "--job", "driving/people"]) == 0
    seen = []

    def fake(world, cfg, person, seeds=1, out=None, progress=True, fresh=False, person_name="biased"):
        seen.append((cfg, person, person_name))
        actors = jax.tree.map(lambda *x: jnp.stack(x), *[_rule_actor("brake", cfg.sac.hidden)] * seeds)
        loop = SimpleNamespace(sac=SimpleNamespace(params=SimpleNamespace(actor=actors)))
        return {"curve": [(0, 1500, 1.0, 0)], "final_returns": np.ones((seeds, 4)), "carry": SimpleNamespace(loop=loop)}

    monkeypatch.setattr(eps_alg, "train", fake)
    pids = [r["pid"] for r in json.loads((out / "jobs" / "driving__people.json").read_text())["participants"]
            if not r["dropped"]]  # fmt: skip
    assert (
        main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--coin", "--survival-entropy", "neutral"])
        == 0
    )
    cfg, crowd, _ = seen[-1]
    assert cfg.teacher.beta == 0.0 and cfg.sac.survival_entropy == "neutral" and crowd.size == len(pids)
    assert "seeds braking first (in most episodes): 1 of 1" in capsys.readouterr().out
    assert (
        main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--coin", "--survival-entropy", "neutral"])
        == 0
    )
    assert len(seen) == 1  # read back
    assert main(["design", "driving", "--run", str(out), "--learner", "eps", "--only", pids[0], "--lam", "0"]) == 0
    cfg, crowd, name = seen[-1]
    assert crowd.size == 1 and name == pids[0] and cfg.lam == 0.0 and cfg.teacher.beta == 1.0
    assert main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--exact", pids[0], "--road", "0"]) == 0
    cfg, person, _ = seen[-1]
    assert cfg.surrogate == "exact" and person.cfg.use_belief is False  # rollout answers: log π_H per step
    assert (out / "controls" / dc.Control("drlhp", exact=pids[0], road=0.0).name / "record.json").is_file()
    assert seen[-1][0].agent_sac().alpha == pytest.approx(1.0 / cfg.nats_per_unit)  # DRLHP's α: the preset's 1/s_H
    for alpha, want in (("tuned", None), ("0.5", 0.5)):  # the preset before it, and any other fixed value
        assert main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--coin", "--alpha", alpha]) == 0
        assert seen[-1][0].drlhp_alpha == "sac" and seen[-1][0].agent_sac().alpha == want
    capsys.readouterr()
    with pytest.raises(SystemExit):  # argparse: a number or 'tuned'
        main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--alpha", "-1"])
    assert "a positive number or 'tuned'" in capsys.readouterr().err
    assert main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--only", "nobody"]) == 2
    assert not (out / "controls" / dc.Control("drlhp", only="nobody").name).exists()  # nothing half-written
    assert main(["design", "driving", "--run", str(out), "--coin"]) == 2
    assert main(["design", "driving", "--run", str(out), "--learner", "drlhp", "--exact", pids[0], "--coin"]) == 2
    err = capsys.readouterr().err
    assert "no valid participant 'nobody'" in err and "--coin goes with --learner" in err and "does not combine" in err
