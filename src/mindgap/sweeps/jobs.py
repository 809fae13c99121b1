"""A sweep's jobs and what both backends share: the job contract, the plan and the progress bar.

The job contract is the run folder's (:mod:`~mindgap.experiments._runfolder`): a job is a
module-level function that computes one job and writes its record atomically
(``jobs/KEY.json``); a job whose record exists is done and is not run again. A backend
(:mod:`~.local`, :mod:`~.ray_cluster`) therefore only has to call job functions somewhere,
retry those whose worker died, keep the order a job's ``needs`` ask for, and tell how it went
(progress on the terminal, a log per job, the failures at the end): :class:`Plan` keeps that
account for both, :class:`Progress` shows it, :func:`execute` runs one job in a worker.
"""

from __future__ import annotations

import contextlib
import os
import socket
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from tqdm.auto import tqdm

from .._io import use_compilation_cache

BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class Job:
    """One unit of a sweep.

    Attributes:
        key: its name (``jobs/KEY.json`` in its run folder; shown in progress and failures).
        call: a module-level function (workers import it by name) that computes the job and
            writes ``record`` atomically; what it returns is ignored.
        kwargs: its keyword arguments (picklable).
        record: the file the job writes; the job is done when it exists.
        log: the job's log: its printed output and, when it fails, the traceback.
        needs: keys of jobs whose records this one reads (it runs after them).
        cpus: CPUs a Ray task of this job asks for.
        gpus: GPUs a Ray task of this job asks for.
    """

    key: str
    call: Callable[..., object]
    kwargs: dict
    record: Path
    log: Path
    needs: tuple[str, ...] = ()
    cpus: float = 1.0
    gpus: float = 0.0


@dataclass
class Outcome:
    """How a sweep went: which jobs ran, which were already done, which failed (key → why)."""

    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    logs: dict[str, Path] = field(default_factory=dict)
    seconds: float = 0.0

    def report(self) -> str:
        """A line of totals and, for each failed job, a line with why and where its log is."""
        lines = [
            f"{len(self.ran)} jobs run, {len(self.skipped)} already done, {len(self.failed)} failed "
            f"({self.seconds:.0f} s)"
        ]
        for key, why in self.failed.items():
            log = self.logs.get(key)
            lines.append(f"  failed {key}: {why}" + (f"  (log: {log})" if log and Path(log).exists() else ""))
        return "\n".join(lines)


def execute(call: Callable, kwargs: dict, key: str, log: str, cache_dir: str | None) -> None:
    """Run one job in this process with its output appended to ``log`` (a header line per attempt).

    Raises whatever the job raises (its traceback is in the log), and :class:`RuntimeError`
    when it returns without having written its record.
    """
    if cache_dir:
        use_compilation_cache(cache_dir)
    Path(log).parent.mkdir(parents=True, exist_ok=True)
    with open(log, "a", buffering=1) as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
        print(f"--- {key}: pid {os.getpid()} on {socket.gethostname()}, {time.strftime('%Y-%m-%d %H:%M:%S')}")
        t0 = time.perf_counter()
        try:
            call(**kwargs)
        except BaseException:
            traceback.print_exc()
            raise
        print(f"--- {key}: finished in {time.perf_counter() - t0:.1f} s")


class Plan:
    """Which jobs are left, ready, running, done or failed; how often each was tried."""

    def __init__(self, jobs: list[Job], retries: int):
        keys = [j.key for j in jobs]
        if len(set(keys)) != len(keys):
            raise ValueError("a sweep names the same job twice")
        self.jobs = {j.key: j for j in jobs}
        self.retries = retries
        self.outcome = Outcome(logs={j.key: j.log for j in jobs})
        self.done = {j.key for j in jobs if j.record.exists()}
        self.outcome.skipped = [j.key for j in jobs if j.key in self.done]
        self.todo = [j.key for j in jobs if j.key not in self.done]
        self.running: set[str] = set()
        self.attempts: dict[str, int] = {}
        for j in jobs:
            for n in j.needs:
                if n not in self.jobs:
                    raise ValueError(f"job {j.key} needs {n}, which is not a job of this sweep")

    @property
    def open(self) -> bool:
        return bool(self.todo or self.running)

    def next(self) -> Job | None:
        """The first job left whose needs are done (jobs whose needs failed fail with them)."""
        for key in list(self.todo):
            needs = self.jobs[key].needs
            lost = [n for n in needs if n in self.outcome.failed]
            if lost:
                self.todo.remove(key)
                self.outcome.failed[key] = f"not run: needs {lost[0]}, which failed"
                continue
            if all(n in self.done for n in needs):
                self.todo.remove(key)
                self.running.add(key)
                self.attempts[key] = self.attempts.get(key, 0) + 1
                return self.jobs[key]
        return None

    def abandon(self) -> None:
        """Fail the jobs left, which wait on jobs that failed."""
        for key in self.todo:
            self.outcome.failed[key] = "not run: a job it needs did not finish"
        self.todo = []

    def finished(self, key: str) -> None:
        self.running.discard(key)
        if self.jobs[key].record.exists():
            self.done.add(key)
            self.outcome.ran.append(key)
        else:
            self.outcome.failed[key] = "finished without writing its record"

    def failed(self, key: str, why: str, *, retry: bool) -> bool:
        """Record a failed attempt; put the job back (and return True) if it may be retried."""
        self.running.discard(key)
        if self.jobs[key].record.exists():  # the record was written before the worker went
            self.done.add(key)
            self.outcome.ran.append(key)
            return False
        if retry and self.attempts[key] <= self.retries:
            self.todo.insert(0, key)
            return True
        tries = self.attempts[key]
        self.outcome.failed[key] = why + (f" (after {tries} attempts)" if tries > 1 else "")
        return False


class Progress:
    """One bar for the whole sweep: jobs finished of those to run, with running/failed and ETA."""

    def __init__(self, plan: Plan, enabled: bool, desc: str):
        self.plan = plan
        self.bar = tqdm(total=len(plan.todo), desc=desc, unit="job", disable=not enabled, dynamic_ncols=True)
        if enabled and plan.outcome.skipped:
            self.bar.write(f"{len(plan.outcome.skipped)} of {len(plan.jobs)} jobs already done; running the rest")
        self.show(0)

    def show(self, finished: int = 1, note: str = "") -> None:
        o = self.plan.outcome
        if note:
            self.bar.write(note)
        self.bar.set_postfix_str(f"running {len(self.plan.running)}, failed {len(o.failed)}", refresh=False)
        self.bar.update(finished)

    def close(self) -> None:
        o = self.plan.outcome
        self.bar.n = len(o.ran) + len([k for k in o.failed if k not in o.skipped])
        self.show(0)
        self.bar.close()


def first_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".strip().splitlines()[0]
