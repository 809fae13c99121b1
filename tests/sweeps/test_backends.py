"""The backends (:mod:`mindgap.sweeps`) on stand-in jobs: same records on both,
a worker killed mid-job retried, a killed sweep rerun finishing only what is missing, failures
reported with their logs while the other jobs' results are kept.

The stand-in jobs (:mod:`sweep_jobs`) keep the run folder's contract and cost nothing, so these
tests measure the machinery; a real experiment through the backends is ``test_sweep_real.py``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import sweep_jobs as sj

from mindgap import sweeps as backends

HERE = Path(__file__).resolve().parent


@pytest.fixture(autouse=True)
def _importable(monkeypatch):
    """Workers (spawned processes, Ray workers) import the stand-ins from this folder."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))


def _grid(root: Path, **kw) -> list[backends.Job]:
    """Two worlds × two seeds, as a sweep's cells."""
    return [sj.job(root, f"w{w}/seed{s}", float(10 * w + s), **kw) for w in (1, 2) for s in (0, 1)]


def _records(root: Path) -> dict:
    return {p.name: json.loads(p.read_text()) for p in sorted((root / "jobs").glob("*.json"))}


def _runs(root: Path) -> list[str]:
    path = root / "runs.log"
    return [line.split()[0] for line in path.read_text().splitlines()] if path.exists() else []


def _killer(root: Path, stop: threading.Event, killed: list):
    """Kill the first worker that holds a job (SIGKILL), then let every later holder go on."""
    while not stop.is_set():
        for pid_file in (root / "pids").glob("*") if (root / "pids").exists() else []:
            try:
                pid = int(pid_file.read_text())
            except (ValueError, OSError):
                continue
            if not killed:
                os.kill(pid, signal.SIGKILL)
                killed.append((pid_file.name, pid))
            elif pid != killed[0][1]:
                pid_file.unlink(missing_ok=True)  # the retry: let it finish
        time.sleep(0.05)


def _mkdirs(*roots):
    for r in roots:
        r.mkdir(parents=True, exist_ok=True)


def test_local_backend_kills_retries_and_matches_an_undisturbed_run(tmp_path):
    calm, hurt = tmp_path / "calm", tmp_path / "hurt"
    _mkdirs(calm, hurt)
    out = backends.run(_grid(calm), "local", workers=2, progress=False, cache_dir="")
    assert out.failed == {} and sorted(out.ran) == sorted(j.key for j in _grid(calm))

    stop, killed = threading.Event(), []
    t = threading.Thread(target=_killer, args=(hurt, stop, killed), daemon=True)
    t.start()
    try:
        out = backends.run(_grid(hurt, hold=60.0), "local", workers=2, retries=1, progress=False, cache_dir="")
    finally:
        stop.set()
        t.join()
    assert len(killed) == 1, "the test killed one worker mid-job"
    victim = killed[0][0].replace("__", "/")
    assert out.failed == {}
    assert _runs(hurt).count(victim) == 2, "the killed job ran again"
    assert _records(hurt) == _records(calm)
    log = (hurt / "logs" / (killed[0][0] + ".log")).read_text()
    assert log.count(f"--- {victim}: pid") == 2  # one header per attempt


def test_a_job_that_raises_fails_alone_with_its_log_and_is_not_retried(tmp_path):
    jobs = _grid(tmp_path) + [sj.job(tmp_path, "w3/seed0", 1.0, fail=True)]
    jobs.append(dataclasses.replace(sj.job(tmp_path, "w3/summary", 1.0), needs=("w3/seed0",)))
    out = backends.run(jobs, "local", workers=2, progress=False, cache_dir="")
    assert sorted(out.ran) == sorted(j.key for j in _grid(tmp_path))
    assert out.failed["w3/seed0"] == "ValueError: w3/seed0 was told to fail"
    assert out.failed["w3/summary"] == "not run: needs w3/seed0, which failed"
    assert _runs(tmp_path).count("w3/seed0") == 1
    report = out.report()
    assert "4 jobs run, 0 already done, 2 failed" in report
    assert f"(log: {tmp_path / 'logs' / 'w3__seed0.log'})" in report
    assert "Traceback" in (tmp_path / "logs" / "w3__seed0.log").read_text()
    again = backends.run(jobs, "local", workers=2, progress=False, cache_dir="")
    assert sorted(again.skipped) == sorted(j.key for j in _grid(tmp_path)) and not again.ran


_WHOLE = """
import sys
sys.path[:0] = {paths!r}
import sweep_jobs as sj
from pathlib import Path
from mindgap import sweeps as backends

if __name__ == "__main__":
    root = Path({root!r})
    jobs = [sj.job(root, f"w{{i}}/s0", float(i), hold=0.0 if i < 2 else 60.0) for i in range(5)]
    backends.run(jobs, "local", workers=2, progress=False, cache_dir="")
"""


def test_a_sweep_killed_as_a_whole_reruns_only_its_missing_jobs(tmp_path):
    script = tmp_path / "sweep.py"
    script.write_text(_WHOLE.format(paths=[str(HERE), *sys.path], root=str(tmp_path)))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while len(list((tmp_path / "pids").glob("*"))) < 2 if (tmp_path / "pids").exists() else True:
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the coordinator and its workers at once
        proc.wait()
    before = _records(tmp_path)
    assert sorted(before) == ["w0__s0.json", "w1__s0.json"]  # the two quick jobs finished, the rest held
    started = _runs(tmp_path)
    jobs = [sj.job(tmp_path, f"w{i}/s0", float(i)) for i in range(5)]
    out = backends.run(jobs, "local", workers=2, progress=False, cache_dir="")
    assert sorted(out.skipped) == ["w0/s0", "w1/s0"]
    assert sorted(out.ran) == ["w2/s0", "w3/s0", "w4/s0"]
    assert _runs(tmp_path)[len(started) :].count("w0/s0") == 0
    assert len(_records(tmp_path)) == 5 and {k: _records(tmp_path)[k] for k in before} == before


@pytest.mark.filterwarnings("ignore:os.fork\\(\\) was called:RuntimeWarning")  # Ray starts its servers
def test_ray_backend_gives_the_local_backends_records_and_survives_a_killed_worker(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))  # a local Ray run leaves nothing in the home folder
    (tmp_path / "home").mkdir()
    local, ray_dir = tmp_path / "local", tmp_path / "ray"
    _mkdirs(local, ray_dir)
    backends.run(_grid(local), "local", workers=2, progress=False, cache_dir="")
    stop, killed = threading.Event(), []
    t = threading.Thread(target=_killer, args=(ray_dir, stop, killed), daemon=True)
    t.start()
    try:
        out = backends.run(_grid(ray_dir, hold=60.0), "ray", workers=2, retries=1, progress=False, cache_dir="")
    finally:
        stop.set()
        t.join()
    assert len(killed) == 1
    assert out.failed == {} and len(out.ran) == 4
    assert _runs(ray_dir).count(killed[0][0].replace("__", "/")) == 2
    assert _records(ray_dir) == _records(local)
    assert list((tmp_path / "home").iterdir()) == []
