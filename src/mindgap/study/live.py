"""Live mode: a training run asks its preference queries through a study store.

``mindgap pebble --world nav1 --teacher study:STORE`` makes :class:`StudyTeacher` the
run's :class:`~mindgap.teachers.host.HostTeacher`: every feedback round it posts its
pairs of segments to the store as one batch, the study app (serving a study file with
``items: {source: live}`` on the same store) shows each pair to one connected
participant, and the run polls the store until every pair is answered or ``timeout``
seconds have passed, with a progress bar. Pairs left unanswered are withdrawn
(``expired``) and count as skipped queries, exactly like B-Pref's skipped answers; an
answer committed before the withdrawal stands.

Store and run meet only through SQLite, so the server and the run are separate
processes (or machines sharing a file system) and either may be restarted: each poll marks
the batch alive, and a batch whose run stopped polling (killed while it waited) is withdrawn
after :data:`~mindgap.study.store.STALE_AFTER` seconds; the restarted run resumes from its
last checkpoint and posts the round again.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..data.segments import SHOWN, Segments
from .items import segment_dict
from .prefs_file import ANSWERS
from .store import Store


def _spec(name: str) -> tuple:
    """A world's name with its ``key=value`` arguments in any order (``gym:ID,b=1,a=2`` = ``gym:ID,a=2,b=1``)."""
    head, _, rest = name.partition(",")
    return head, tuple(sorted(x.strip() for x in rest.split(",") if x.strip()))


class StudyTeacher:
    """People answering through the study app (a :class:`~mindgap.teachers.host.HostTeacher`)."""

    def __init__(self, db, world=None, *, timeout: float = 600.0, poll: float = 0.5, progress: bool = True):
        db = Path(db)
        if not db.is_file():
            raise ValueError(
                f"no study store {db}: start the study first (mindgap study serve --config LIVE.yaml --db {db})"
            )
        self.store = Store(db)
        study = self.store.study_json()
        if study["items"].get("source") != "live" or study["protocol"] == "rating":
            raise ValueError(
                f"{db} holds study {study['name']!r}, which does not take live queries (items: {{source: live}})"
            )
        if world is not None and study["domain"]["name"] == "driving":
            from .driving import driving_world

            want = driving_world(study["domain"]).name
            if want != world.name:
                raise ValueError(f"{db} shows world {want!r}, the run trains on {world.name!r}")
        elif world is not None:
            want = study["domain"].get("world") or study["domain"].get("env", "")
            if _spec(want) != _spec(world.name) and Path(want).stem != world.name:
                raise ValueError(f"{db} shows world {want!r}, the run trains on {world.name!r}")
        self.name = f"study:{db}"
        self.timeout, self.poll, self.progress = timeout, poll, progress
        self.batches: list[int] = []

    def __str__(self) -> str:
        return self.name

    def __call__(self, seg_a: Segments, seg_b: Segments) -> tuple[np.ndarray, np.ndarray]:
        a = {k: np.asarray(getattr(seg_a, k)) for k in SHOWN}
        b = {k: np.asarray(getattr(seg_b, k)) for k in SHOWN}
        k = len(a["mask"])
        batch = self.store.post_live_batch(
            self.name, [{"a": segment_dict(a, i), "b": segment_dict(b, i)} for i in range(k)]
        )
        self.batches.append(batch)
        bar = None
        if self.progress:
            from tqdm import tqdm

            bar = tqdm(total=k, desc=f"answers (batch {batch})", unit="query", leave=False)
        deadline = time.monotonic() + self.timeout
        done = 0
        try:
            while True:
                done = self.store.live_counts(batch, touch=True)["answered"]
                if bar is not None:
                    bar.update(done - bar.n)
                if done >= k or time.monotonic() >= deadline:
                    break
                time.sleep(self.poll)
        finally:
            self.store.close_batch(batch)
            if bar is not None:
                bar.close()
        got = self.store.batch_answers(batch)
        labels = np.zeros(k, np.float32)
        answered = np.zeros(k, bool)
        for i, choice in got.items():
            labels[i], answered[i] = ANSWERS[choice], True
        return labels, answered
