"""Real experiments through the backends: a grid sweep read by ``mindgap report``, a ``--fast``
learner on two worlds × two seeds giving the same results on local workers and on a local Ray,
and ``mindgap reproduce table1 --fast --backend local --workers 2`` giving the one-process table.

Each worker compiles its learner's programs (or reads them from the shared cache), so these
take minutes (all are marked slow); the stand-in tests of the machinery are ``test_sweep_backends.py``.
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import threading
import time

import pytest

from mindgap.cli import main


def _spec(path, out, text: str):
    path.write_text(f'[sweep]\nout = "{out}"\n' + text)
    return path


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow  # a minute with a cold compilation cache: a real learner in a worker process
def test_a_grid_sweep_runs_resumes_and_is_read_by_the_report(tmp_path, capsys):
    store = tmp_path / "store"
    spec = _spec(tmp_path / "grid.toml", store, '[grid]\nmethods = ["sac"]\nworlds = ["nav1"]\n')
    assert main(["sweep", str(spec), "--workers", "1", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "2 jobs run, 0 already done, 0 failed" in out
    rows = _rows(store / "results.csv")
    assert [(r["part"], r["experiment"], r["method"], r["world"]) for r in rows] == [("grid", "grid", "sac", "nav1")]
    assert float(rows[0]["random_return"]) == float(rows[0]["random_return"])  # the reference job's number, not NaN
    record = json.loads((store / "sweep.json").read_text())
    assert record["jobs"] == {"ran": 2, "already_done": 0, "failed": 0}
    assert main(["sweep", str(spec), "--workers", "1", "--quiet"]) == 0
    assert "0 jobs run, 2 already done, 0 failed" in capsys.readouterr().out
    assert main(["report", str(store), "--out", str(tmp_path / "report")]) == 0
    md = (tmp_path / "report" / "report.md").read_text()
    assert "## Grid sweep (a sweep file's grid, `mindgap sweep`)" in md and "| nav1 | sac |" in md


GRID = """
[grid]
methods = ["pebble"]
worlds = ["nav1", "nav2"]
seeds = [0, 1]
"""


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:os.fork\\(\\) was called:RuntimeWarning")  # Ray starts its servers
def test_a_fast_learner_on_two_worlds_and_two_seeds_gives_the_same_results_locally_and_on_ray(tmp_path):
    pytest.importorskip("ray")
    local, ray_store = tmp_path / "local", tmp_path / "ray"
    spec = _spec(tmp_path / "grid.toml", local, GRID)
    assert main(["sweep", str(spec), "--backend", "local", "--workers", "2", "--quiet"]) == 0
    assert main(["sweep", str(spec), "--backend", "ray", "--workers", "2", "--quiet", "--out", str(ray_store)]) == 0
    a, b = _rows(local / "results.csv"), _rows(ray_store / "results.csv")
    assert len(a) == 4 and {r["seed"] for r in a} == {"0", "1"} and {r["world"] for r in a} == {"nav1", "nav2"}
    assert a == b
    assert (local / "grid" / "curves.csv").read_text() == (ray_store / "grid" / "curves.csv").read_text()


def _kill_first_worker(logs, stop: threading.Event, killed: list) -> None:
    """SIGKILL the worker named in the first job log's header (``--- KEY: pid N on …``), once."""
    while not stop.is_set() and not killed:
        for log in sorted(logs.glob("*.log")) if logs.exists() else []:
            m = re.match(r"--- (\S+): pid (\d+) ", log.read_text())
            if m:
                os.kill(int(m.group(2)), signal.SIGKILL)
                killed.append((m.group(1), log))
                return
        time.sleep(0.02)


@pytest.mark.slow
def test_table1_on_two_local_workers_gives_the_one_process_table_even_when_a_worker_is_killed(tmp_path, capsys):
    one, two = tmp_path / "one", tmp_path / "two"
    assert main(["reproduce", "table1", "--fast", "--quiet", "--out", str(one)]) == 0
    stop, killed = threading.Event(), []
    t = threading.Thread(target=_kill_first_worker, args=(two / "logs", stop, killed), daemon=True)
    t.start()
    try:
        argv = ["reproduce", "table1", "--fast", "--quiet", "--backend", "local", "--workers", "2", "--out", str(two)]
        assert main(argv) == 0
    finally:
        stop.set()
        t.join()
    assert "20 jobs run, 0 already done, 0 failed" in capsys.readouterr().out
    key, log = killed[0]
    assert log.read_text().count(f"--- {key}: pid") == 2  # killed mid-job, then run again
    assert (two / "table.md").read_text() == (one / "table.md").read_text()  # assembled without --assemble
    metrics = ("setting", "belief_param", "method", "seed", "d_R", "d_Theta", "d_pi", "corr_R", "iterations", "w")
    strip = lambda rows: [{k: r[k] for k in metrics} for r in rows]  # noqa: E731 - "seconds" differs, of course
    assert strip(_rows(two / "results.csv")) == strip(_rows(one / "results.csv"))
    assert (two / "demo_counts.csv").exists() and json.loads((two / "progress.json").read_text())["missing"] == []
