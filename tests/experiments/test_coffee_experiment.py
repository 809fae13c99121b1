import csv
import json

import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.cli import main
from mindgap.data.demos import RatedDemonstrations
from mindgap.envs.coffee import TRUE_SPILL, CoffeeParams, coffee_transitions, make_coffee
from mindgap.experiments import coffee
from mindgap.experiments.coffee_report import correlation, two_sample
from mindgap.teachers.rating import RatingTeacher
from report_check import check_report

COLUMNS = ["participant", "robot", "method", "spill_learned", "wet_weight_learned", "spill_true", "wet_weight_true"]


def rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


def test_reproduce_coffee_fast(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["reproduce", "coffee", "--fast", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Table 2" in printed and "GeReL⁻" in printed
    results = rows(out / "results.csv")
    assert list(results[0])[:7] == COLUMNS
    cfg = coffee.preset("fast")
    for robot in ("mobile", "humanoid"):
        mine = [r for r in results if r["robot"] == robot]
        assert len({r["participant"] for r in mine}) == cfg.participants
        assert sorted({r["method"] for r in mine}) == ["gerel", "gerel-minus"]
        minus = [float(r["spill_learned"]) for r in mine if r["method"] == "gerel-minus"]
        np.testing.assert_allclose(minus, TRUE_SPILL[robot], atol=1e-6)  # GeReL⁻'s belief is the robot's truth
    assert all(0 <= float(r["spill_learned"]) <= 1 and np.isfinite(float(r["wet_weight_learned"])) for r in results)
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["table2"]) == {"q1", "q2"} and "GeReL (factored)" in summary["learned"]
    people = rows(out / "participants.csv")
    assert sum(p["valid"] == "True" for p in people) == 2 * cfg.participants
    assert all(p["dropped"] for p in people if p["valid"] == "False")
    for name in (
        "fig12.png",
        "ratings_by_demo.png",
        "demos.txt",
        "table.md",
        "demos/humanoid/3-sunny-umbrella-spill.png",
    ):
        assert (out / name).stat().st_size > 0, name
    assert "SPILLS" in (out / "demos.txt").read_text()
    check_report(out, tmp_path / "report", "coffee")
    assert json.loads((out / "progress.json").read_text())["missing"] == []
    # a rerun resumes (nothing is refitted) and prints the same tables
    assert main(["reproduce", "coffee", "--fast", "--quiet", "--out", str(out)]) == 0
    assert capsys.readouterr().out.split("results,")[0] == printed.split("results,")[0]

    # the study's own ratings file goes through the real-people path, one fit per participant
    fit = tmp_path / "fit"
    args = ["gerel", "--domain", "coffee", "--minus", "--ratings", str(out / "ratings.csv"), "--quiet"]
    assert main(args + ["--max-iter", "50", "--restarts", "2", "--out", str(fit)]) == 0
    refit = rows(fit / "results.csv")
    assert list(refit[0])[:7] == COLUMNS and len(refit) == 2 * cfg.participants
    assert {r["robot"] for r in refit} == {"mobile", "humanoid"}
    assert all(r["q1"] and r["q2"] for r in refit)


def test_gerel_coffee_simulated_person_and_bad_files(tmp_path, capsys):
    saved = tmp_path / "me.csv"
    args = ["gerel", "--domain", "coffee", "--minus", "--robot", "humanoid", "--max-iter", "50", "--restarts", "2"]
    assert main(args + ["--quiet", "--save-ratings", str(saved)]) == 0
    assert "believes spill" in capsys.readouterr().out
    text = saved.read_text()
    assert text.startswith("participant,robot,demo,step,state,action,rating,q1,q2")
    bad = tmp_path / "bad.csv"
    for body, msg in [
        (text.replace("sunny-umbrella,", "sunny-parasol,", 1), "unknown demonstration 'sunny-parasol'"),
        ("demo,step,state,action,rating,participant\nsunny-no-umbrella,0,0,0,5,\n", "missing participant"),
        ("demo,step,state,action,rating\nsunny-no-umbrella,0,0,0,12\n", "outside"),
    ]:
        bad.write_text(body)
        out = tmp_path / "out"
        assert main(["gerel", "--domain", "coffee", "--ratings", str(bad), "--out", str(out), "--quiet"]) == 2
        assert msg in capsys.readouterr().err
        assert not out.exists()
    # without a robot column GeReL⁻ cannot know the true dynamics; a failed sanity check drops the person
    lines = [line.split(",") for line in text.splitlines()]
    no_robot = "\n".join(",".join(cells[:1] + cells[2:]) for cells in lines) + "\n"
    bad.write_text(no_robot)
    assert main(["gerel", "--domain", "coffee", "--minus", "--ratings", str(bad), "--quiet"]) == 2
    assert "add a robot column or pass --robot" in capsys.readouterr().err
    sanity_top = [cells[:6] + ["10"] + cells[7:] if cells[2] == "sanity-random" else cells for cells in lines]
    bad.write_text("\n".join(",".join(c) for c in sanity_top) + "\n")
    assert main(["gerel", "--domain", "coffee", "--ratings", str(bad), "--quiet"]) == 2
    assert "failed the sanity check" in capsys.readouterr().out
    assert main(["gerel", "--domain", "coffee", "--param", "tied", "--quiet"]) == 2
    assert "does not apply to coffee" in capsys.readouterr().err
    assert main(["gerel", "--param", "factored", "--size", "3", "--quiet"]) == 2
    assert "factored domain" in capsys.readouterr().err


def test_gerel_recovers_a_persons_spill_belief_and_wet_weight():
    # noise-free ratings of the nine demonstrations; the fast preset's fit (shared compiled program)
    study = coffee.make_study()
    mdp = make_coffee("mobile")
    cfg = coffee.preset("fast").gerel
    learned = {}
    for spill, wet in [(0.05, -2.0), (0.3, -1.0), (0.3, -6.0), (0.9, -2.0)]:
        belief = jnp.asarray(coffee_transitions(CoffeeParams(spill)), jnp.float32)
        teacher = RatingTeacher(mdp, jnp.asarray([4.0, wet]), belief)
        rated = RatedDemonstrations(study.demos, teacher.mean_ratings(study.demos))
        learned[spill, wet] = coffee.fit_person(mdp, rated, "gerel", "factored", cfg, key=rng.key(0), normalise="none")
    for (spill, _), f in learned.items():
        assert abs(f["spill_learned"] - spill) < 0.1, (spill, f)
    assert learned[0.3, -6.0]["wet_weight_learned"] < learned[0.3, -1.0]["wet_weight_learned"] - 2.0


def test_two_sample_and_correlation_helpers():
    assert two_sample([1, 2, 3], [1, 2, 3])["p_welch"] == pytest.approx(1.0)
    assert two_sample([1, 1, 2, 2], [4, 5, 5, 4])["p_welch"] < 0.01
    assert np.isnan(two_sample([1], [2, 3])["p_welch"])
    c = correlation([1, 2, 3, np.nan], [2, 4, 7, 1])
    assert c["n"] == 3 and c["spearman"] == pytest.approx(1.0) and 0.9 < c["pearson"] < 1.0
    assert np.isnan(correlation([1, 1, 1], [1, 2, 3])["pearson"])
