import csv
import json

import numpy as np
import pytest

from mindgap.cli import main
from report_check import check_report

COLUMNS = ["setting", "belief_param", "method", "seed", "d_R", "d_Theta", "d_pi"]


@pytest.fixture
def stand_in_fits(monkeypatch):
    """``reproduce table1``'s fits replaced by rows of the real shape, computed by the experiment's own
    metrics from fixed estimates (the true reward, halved for the baselines; the true dynamics):
    seconds instead of compiling four fitting programs. The fits are tested where they live
    (tests/algorithms/test_gerel.py, test_baselines.py) and ``reproduce table1 --fast`` runs for real
    in the slow tier (tests/sweeps/test_real.py, also in two killed-and-retried workers)."""
    from mindgap.experiments import table1

    def fit_one(cfg, method, param, task, rated, policy_demos, key, progress=True):
        w = np.asarray(task.true_weights) * (1.0 if method == "gerel" else 0.5)
        t = np.asarray(task.mdp.transitions)
        m = table1._metrics(task, w, t)
        row = {**m, "iterations": 3, "seconds": 0.01, "w": [float(x) for x in w]}
        curve = [{"iteration": i, **m} for i in (0, 1, 2)]
        restarts = []
        if method == "gerel":
            restarts = [
                {"restart": r, "elbo": -float(r), "chosen": r == 0, "screened_out": r == 2, **m} for r in range(3)
            ]
        return row, curve, restarts

    monkeypatch.setattr(table1, "fit_one", fit_one)


def test_reproduce_table1_fast_writes_its_files(stand_in_fits, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["reproduce", "table1", "--fast", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "GeReL" in printed and "MaxEnt-IRL" in printed
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[:7] == COLUMNS
    assert {r["method"] for r in rows} == {"gerel", "serd", "gerel-minus", "maxent-irl"}
    assert {r["belief_param"] for r in rows} == {"tied", "per-sa"}
    assert {r["setting"] for r in rows} == {"reversed", "rotated"}
    assert all(np.isfinite(float(r[k])) for r in rows for k in ("d_R", "d_Theta", "d_pi"))
    for name in (
        "curves.csv",
        "restarts.csv",
        "demo_counts.csv",
        "summary.json",
        "table.md",
        "rewards_reversed.png",
        "curves_rotated_tied.png",
        "demo_counts_reversed.png",
    ):
        assert (out / name).stat().st_size > 0, name
    check_report(out, tmp_path / "report", "table1")
    summary = json.loads((out / "summary.json").read_text())
    assert "tied|reversed|gerel" in summary["stats"]
    # a second run resumes: every job is already there, the table is the same
    assert main(["reproduce", "table1", "--fast", "--quiet", "--out", str(out)]) == 0
    assert capsys.readouterr().out.split("results,")[0] == printed.split("results,")[0]
    assert main(["reproduce", "table1", "--fast", "--quiet", "--assemble", "--out", str(out)]) == 0
    assert capsys.readouterr().out.split("results,")[0] == printed.split("results,")[0]
    # one job again, by the command its record keeps, into another folder: the same row
    key = "main/rotated/s0/n300/maxent-irl/-"
    record = json.loads((out / "jobs" / (key.replace("/", "__") + ".json")).read_text())
    assert record["command"] == f"mindgap reproduce table1 --fast --out {out} --job {key}"
    again = tmp_path / "again"
    assert main(["reproduce", "table1", "--fast", "--quiet", "--job", key, "--out", str(again)]) == 0
    assert f"record in {again}/jobs/" in capsys.readouterr().out
    assert [p.name for p in (again / "jobs").iterdir()] == [key.replace("/", "__") + ".json"]
    rerun = json.loads((again / "jobs" / (key.replace("/", "__") + ".json")).read_text())
    timeless = [{k: v for k, v in r["row"].items() if k != "seconds"} for r in (rerun, record)]
    assert timeless[0] == timeless[1] and rerun["curve"] == record["curve"]
    progress = json.loads((again / "progress.json").read_text())
    assert progress["done"] == 1 and progress["jobs"] == len(list((out / "jobs").iterdir()))


@pytest.mark.slow  # 47 s cold in the default tier, which runs the same command on stand-in fits (above)
def test_reproduce_table1_fast_for_real(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["reproduce", "table1", "--fast", "--quiet", "--out", str(out)]) == 0
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["method"] for r in rows} == {"gerel", "serd", "gerel-minus", "maxent-irl"}
    assert all(np.isfinite(float(r[k])) for r in rows for k in ("d_R", "d_Theta", "d_pi"))
    restarts = (out / "restarts.csv").read_text().splitlines()
    assert len(restarts) > 1 and "chosen" in restarts[0]
    check_report(out, tmp_path / "report", "table1")


def test_reproduce_refuses_a_folder_of_another_configuration(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text("{}")
    assert main(["reproduce", "table1", "--fast", "--out", str(out)]) == 2
    assert "another configuration" in capsys.readouterr().err


def test_gerel_simulated_then_from_its_ratings_file(tmp_path, capsys):
    ratings = tmp_path / "ratings.csv"
    out = tmp_path / "fit"
    args = ["gerel", "--size", "3", "--demos", "60", "--length", "4", "--max-iter", "50", "--restarts", "2", "--quiet"]
    assert main(args + ["--save-ratings", str(ratings), "--out", str(out)]) == 0
    report = json.loads((out / "posterior.json").read_text())
    assert set(report["metrics"]) >= {"d_R", "d_Theta", "d_pi"}
    assert np.load(out / "posterior.npz")["transitions"].shape == (9, 4, 9)
    assert (out / "posterior.png").stat().st_size > 0
    assert "Up" in capsys.readouterr().out
    out2 = tmp_path / "fit2"
    assert main(args + ["--ratings", str(ratings), "--out", str(out2)]) == 0
    assert json.loads((out2 / "posterior.json").read_text())["n_demos"] == 60


@pytest.mark.parametrize(
    "extra,msg",
    [
        (["--domain", "mars"], "unknown domain"),
        (["--belief", "1,1,2,3"], "not a permutation"),
        (["--corners", "0,0"], "corners"),
        (["--ratings", "RATINGS"], "missing column"),
    ],
)
def test_gerel_bad_input_is_named_and_nothing_is_written(tmp_path, capsys, extra, msg):
    bad = tmp_path / "bad.csv"
    bad.write_text("demo,step,state\n0,0,1\n")
    extra = [str(bad) if x == "RATINGS" else x for x in extra]
    out = tmp_path / "out"
    assert main(["gerel", "--size", "3", "--out", str(out), "--quiet"] + extra) == 2
    assert msg in capsys.readouterr().err
    assert not out.exists()


def test_unknown_experiment(capsys):
    assert main(["reproduce", "table9"]) == 2
    assert "unknown experiment" in capsys.readouterr().err
