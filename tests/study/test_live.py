"""Live mode: a training run asks people through the study store and waits for their answers."""

import threading
import time

import jax
import numpy as np
import pytest
from fastapi.testclient import TestClient
from study_helpers import Participant, study_file

from mindgap.algorithms.pbrl import FAST_SCHEDULE, method_config, train
from mindgap.data.segments import SHOWN, Segments
from mindgap.envs.terrain import load_world, world_from_dict
from mindgap.models.reward_ensemble import RewardConfig
from mindgap.study.app import create_app
from mindgap.study.items import random_segments, true_returns
from mindgap.study.live import StudyTeacher
from mindgap.study.server import open_study
from mindgap.teachers.host import HostTeacher, SimulatedHostTeacher
from mindgap.teachers.preference import TeacherConfig

EASY = """name = "easy"
horizon = 30
layout = \"\"\"
#########
#S.....G#
#.......#
#########
\"\"\"
[rewards]
goal = 10.0
step = -1.0
progress = 1.0
"""
TINY = {
    **FAST_SCHEDULE,
    "explore_steps": 250,
    "queries": 12,
    "per_round": 6,
    "reward": RewardConfig(hidden=(8, 8), updates=10, batch_size=8),
}


def _live(tmp_path, world="nav1"):
    config = study_file(
        tmp_path, "terrain-live", participants=2, min_seconds=0, domain={"name": "terrain", "world": world}
    )
    study, store, renderer = open_study(config, tmp_path / "live.sqlite")
    return store, TestClient(create_app(study, store, renderer))


class People:
    """Participants answering through the app in a thread, preferring the higher return under ``params``."""

    def __init__(self, client, store, params):
        self.stop = threading.Event()
        self.answered = 0
        items = {}

        def choose(item_id):
            q = store.live_query(int(item_id.split("-")[1]))
            import json

            data = json.loads(q["data"])
            seg = {s: {k: np.asarray([data[s][k]]) for k in ("obs", "act", "next_obs", "mask")} for s in "ab"}
            d = float(true_returns(params, seg["a"])[0] - true_returns(params, seg["b"])[0])
            items[item_id] = d
            return "equal" if d == 0 else ("a" if d > 0 else "b")

        self.people = [Participant(client, p["token"], choose) for p in store.participants()]
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self.stop.is_set():
            for p in self.people:
                html = p.get()
                if 'action="/p/' + p.token + '/finish"' in html:
                    continue  # waiting page: nothing to answer yet
                p.step()
            time.sleep(0.02)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(10)


def _pairs(params, k, seed=0):
    s = random_segments(jax.random.key(seed), params, 2 * k, 8)
    return (Segments(*(s[f][:k] for f in SHOWN)), Segments(*(s[f][k:] for f in SHOWN)))


def test_the_study_teacher_returns_what_people_answered(tmp_path):
    store, client = _live(tmp_path)
    world = load_world("nav1")
    teacher = StudyTeacher(store.path, world, timeout=60, poll=0.05, progress=False)
    assert isinstance(teacher, HostTeacher)
    seg_a, seg_b = _pairs(world.params, 5)
    with People(client, store, world.params):
        labels, answered = teacher(seg_a, seg_b)
    a = {k: np.asarray(getattr(seg_a, k)) for k in SHOWN}
    b = {k: np.asarray(getattr(seg_b, k)) for k in SHOWN}
    d = true_returns(world.params, a) - true_returns(world.params, b)
    assert answered.all()
    assert np.array_equal(labels, np.where(d == 0, 0.5, (d > 0).astype(np.float32)))
    assert store.live_counts() == {"open": 0, "answered": 5, "expired": 0}


def test_unanswered_queries_are_withdrawn_after_the_timeout(tmp_path):
    store, client = _live(tmp_path)
    world = load_world("nav1")
    teacher = StudyTeacher(store.path, world, timeout=0.3, poll=0.05, progress=False)
    pairs = _pairs(world.params, 3)
    start = time.monotonic()
    labels, answered = teacher(*pairs)
    assert 0.3 <= time.monotonic() - start < 5
    assert not answered.any()
    assert store.live_counts() == {"open": 0, "answered": 0, "expired": 3}
    token = store.participants()[0]["token"]
    p = Participant(client, token, lambda i: "a")
    p.step(), p.step()  # consent, instructions
    assert "Waiting for the next question" in p.get()  # nothing left to answer


def test_a_batch_whose_run_stopped_polling_is_withdrawn_before_anyone_is_given_it(tmp_path):
    store, client = _live(tmp_path)
    datas = [{"a": {"obs": [[0.0, 0.0]]}, "b": {"obs": [[1.0, 1.0]]}} for _ in range(2)]
    dead = store.post_live_batch("study:dead-run", datas)  # its run was killed: it never polls again
    alive = store.post_live_batch("study:live-run", datas)
    time.sleep(0.3)
    store.live_counts(alive, touch=True)  # the live run polls
    pid = store.participants()[0]["id"]
    qid = store.claim_live(pid, stale_after=0.2)
    assert store.live_query(qid)["batch_id"] == alive  # never the dead run's query
    assert store.live_counts(dead) == {"open": 0, "answered": 0, "expired": 2}
    assert store.live_counts(alive)["open"] == 2
    # with the default (30 s) a run that polls every half second is never withdrawn
    assert store.claim_live(pid) == qid and store.live_counts(alive)["open"] == 2


def test_a_study_for_another_world_is_refused(tmp_path):
    store, _ = _live(tmp_path)
    with pytest.raises(ValueError, match="shows world 'nav1', the run trains on 'd1'"):
        StudyTeacher(store.path, load_world("d1"))


@pytest.mark.slow
def test_pebble_learns_from_people_answering_in_the_study_app(tmp_path):
    (tmp_path / "easy.toml").write_text(EASY)
    world = world_from_dict(__import__("tomllib").loads(EASY))
    store, client = _live(tmp_path, world=str(tmp_path / "easy.toml"))
    teacher = StudyTeacher(store.path, world, timeout=60, poll=0.05, progress=False)
    cfg = method_config("pebble", **TINY)
    with People(client, store, world.params):
        res = train(world, cfg, seeds=2, teacher=teacher, progress=False)
    assert len(teacher.batches) == 2  # two rounds of 6 queries for each of 2 seeds
    assert store.live_counts() == {"open": 0, "answered": 24, "expired": 0}
    assert int(np.asarray(res["carry"].prefs.count).sum()) == 24
    assert [int(q) for _, _, _, q in res["curve"][-2:]] == [12, 12]


@pytest.mark.slow
def test_prefbias_learns_from_people_answering_in_the_study_app(tmp_path):
    """PrefBias (§3.3) asks its queries through the running study, like PEBBLE; every answer is in its dataset."""
    from mindgap.algorithms.prefbias import prefbias_config
    from mindgap.prefbias import train as prefbias_train

    (tmp_path / "easy.toml").write_text(EASY)
    world = world_from_dict(__import__("tomllib").loads(EASY))
    store, client = _live(tmp_path, world=str(tmp_path / "easy.toml"))
    teacher = StudyTeacher(store.path, world, timeout=60, poll=0.05, progress=False)
    cfg = prefbias_config("fast", explore_steps=250, queries=12, per_round=6)
    with People(client, store, world.params):
        res = prefbias_train(world, cfg, seeds=1, teacher=teacher, progress=False)
    assert len(teacher.batches) == 2  # two rounds of 6 queries
    assert store.live_counts() == {"open": 0, "answered": 12, "expired": 0}
    assert int(np.asarray(res["carry"].prefs.count).sum()) == 12
    assert [int(q) for _, _, _, q in res["curve"][-1:]] == [12]


@pytest.mark.slow
def test_a_live_run_killed_while_it_waits_resumes_and_finishes_with_people_answering(tmp_path):
    """Either side may restart: here the training run is SIGKILLed while its first round waits for
    answers; started again on the same run folder it resumes and finishes, answered through the app."""
    import os
    import signal
    import subprocess
    import sys

    (tmp_path / "easy.toml").write_text(EASY)
    world = world_from_dict(__import__("tomllib").loads(EASY))
    store, client = _live(tmp_path, world=str(tmp_path / "easy.toml"))
    argv = [sys.executable, "-m", "mindgap.cli", "pebble", "--env", str(tmp_path / "easy.toml"), "--fast"]
    argv += ["--queries", "12", "--per-round", "6", "--teacher", f"study:{store.path}", "--answer-timeout", "120"]
    argv += ["--out", str(tmp_path / "run"), "--quiet"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 300
    while store.live_counts()["open"] == 0 and time.monotonic() < deadline and run.poll() is None:
        time.sleep(0.2)
    assert store.live_counts()["open"] == 6, run.stdout.read().decode() if run.poll() is not None else "no batch"
    os.killpg(run.pid, signal.SIGKILL)  # killed while it waits: its batch stays open in the store
    run.wait()
    run = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    with People(client, store, world.params):
        out, _ = run.communicate(timeout=600)
    assert run.returncode == 0, out.decode()
    summary = __import__("json").loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["queries"] == 12  # both rounds of the resumed run answered
    counts = store.live_counts()
    assert counts["answered"] >= 12 and counts["open"] == 0


@pytest.mark.slow
def test_the_host_path_gives_the_jitted_path_s_results(tmp_path):
    """With a deterministic simulated person, asking outside jit changes nothing."""
    world = world_from_dict(__import__("tomllib").loads(EASY))
    cfg = method_config("pebble", **{**TINY, "teacher": TeacherConfig(beta=None)})
    jitted = train(world, cfg, seeds=2, teacher="true", progress=False)
    host = SimulatedHostTeacher(
        world.env, world.params, None, TeacherConfig(beta=None, use_belief=False), key=jax.random.key(0)
    )
    hosted = train(world, cfg, seeds=2, teacher=host, progress=False)
    assert host.calls == 2
    np.testing.assert_allclose(np.asarray(hosted["curve"]), np.asarray(jitted["curve"]), rtol=1e-5, atol=1e-5)
