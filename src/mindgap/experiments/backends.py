"""Where a sweep's jobs run: worker processes on this machine (``local``) or Ray tasks (``ray``).

The job contract is the run folder's (:mod:`~._runfolder`): a job is a module-level function
that computes one job and writes its record atomically (``jobs/KEY.json``); a job whose
record exists is done and is not run again. A backend therefore only has to call job
functions somewhere, retry those whose worker died, keep the order a job's ``needs`` ask
for, and tell how it went (progress on the terminal, a log per job, the failures at the end).

What is written by hand here, and why:

* **local**: a small pool of spawned worker processes of our own rather than
  :class:`concurrent.futures.ProcessPoolExecutor`, because the executor breaks as a whole
  when one worker is killed (every job in flight fails with it), while this pool knows
  which worker runs which job: a worker that dies (SIGKILL, out of memory) costs only its
  own job, which is retried on a fresh worker. Workers are long-lived, so a job's compiled
  XLA programs serve the next job in the same process.
* **ray**: Ray handles scheduling, placement and retries (``max_retries`` for a task whose
  worker died; an exception raised by the job itself is not retried, it would only fail
  again). What is set by hand are Ray's defaults for a run: a local Ray started for the
  run keeps its session files in a fresh folder under ``/tmp`` (removed at the end when
  every job succeeded), its authentication token in the environment of the run rather than
  in ``~/.ray/auth_token``, a small object store (jobs return nothing: their results are
  files) and no dashboard.

Both backends point every worker at one persistent JAX compilation cache, so a program
compiled by one worker is read from disk by the others.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import secrets
import shutil
import signal
import socket
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import wait
from pathlib import Path

from tqdm.auto import tqdm

from .._io import compilation_cache_dir, use_compilation_cache

BACKENDS = ("local", "ray")

OBJECT_STORE_BYTES = 128 * 1024**2
"""Object store of a local Ray started for a run: jobs write files and return nothing."""


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


def run(jobs: list[Job], backend: str = "local", **kw) -> Outcome:
    """Run the unfinished ``jobs`` on ``backend`` (:func:`run_local` or :func:`run_ray`, ``kw`` theirs)."""
    if backend == "local":
        return run_local(jobs, **kw)
    if backend == "ray":
        return run_ray(jobs, **kw)
    raise ValueError(f"unknown backend {backend!r}: choose from {', '.join(BACKENDS)}")


# ---------------------------------------------------------------------------------------
# what every worker does with one job


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


def _ray_task(call: Callable, kwargs: dict, key: str, log: str, cache_dir: str | None, record: str) -> None:
    execute(call, kwargs, key, log, cache_dir)
    if not Path(record).exists():
        raise RuntimeError(f"{key} finished without writing its record {record}")


# ---------------------------------------------------------------------------------------
# the plan both backends follow


class _Plan:
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


class _Progress:
    """One bar for the whole sweep: jobs finished of those to run, with running/failed and ETA."""

    def __init__(self, plan: _Plan, enabled: bool, desc: str):
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


# ---------------------------------------------------------------------------------------
# local: worker processes on this machine


def _worker(conn, cache_dir: str | None) -> None:
    """A local worker: run the jobs sent over ``conn`` until it closes (the coordinator ended)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the coordinator's to handle
    if cache_dir:
        use_compilation_cache(cache_dir)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        key, call, kwargs, log = task
        try:
            execute(call, kwargs, key, log, None)
            conn.send(("done", key, ""))
        except BaseException as e:  # the job's failure, told to the coordinator; the worker goes on
            conn.send(("error", key, f"{type(e).__name__}: {e}".splitlines()[0]))


class _Worker:
    def __init__(self, ctx, cache_dir: str | None):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker, args=(child, cache_dir), daemon=True)
        self.process.start()
        child.close()  # the worker holds the only other end: when the coordinator dies, its recv ends
        self.job: str | None = None

    def stop(self, kill: bool = False) -> None:
        with contextlib.suppress(OSError, BrokenPipeError):
            if kill:
                self.process.kill()
            else:
                self.conn.send(None)
        self.process.join(timeout=None if not kill else 5)
        self.conn.close()


def run_local(
    jobs: list[Job],
    *,
    workers: int | None = None,
    retries: int = 2,
    progress: bool = True,
    cache_dir: str | None = None,
    desc: str = "sweep",
) -> Outcome:
    """Run the unfinished ``jobs`` in ``workers`` spawned processes (default: one per CPU core).

    A job that raises fails at once (its traceback is in its log); a job whose worker dies
    is retried up to ``retries`` times on a new worker. Jobs whose needs failed are not run.
    """
    t0 = time.perf_counter()
    plan = _Plan(jobs, retries)
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError("--workers must be at least 1")
    cache_dir = compilation_cache_dir() if cache_dir is None else cache_dir
    bar = _Progress(plan, progress, desc)
    ctx = mp.get_context("spawn")  # fork would copy the coordinator's JAX threads and state
    pool: list[_Worker] = []
    try:
        while plan.open:
            while True:  # hand ready jobs to idle workers, starting workers up to ``workers``
                idle = [w for w in pool if w.job is None]
                if not idle and len(pool) >= workers:
                    break
                job = plan.next()
                if job is None:
                    break
                if not idle:
                    pool.append(_Worker(ctx, cache_dir))
                    idle = pool[-1:]
                idle[0].job = job.key
                with contextlib.suppress(OSError):  # a worker that just died is found below
                    idle[0].conn.send((job.key, job.call, job.kwargs, str(job.log)))
                bar.show(0)
            busy = [w for w in pool if w.job is not None]
            if not busy:
                break  # nothing runs and nothing is ready: what is left waits on failed jobs
            ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout=1.0)
            for w in busy:
                message = None
                if w.conn in ready:
                    with contextlib.suppress(EOFError, OSError):
                        message = w.conn.recv()
                if message is not None:
                    what, key, why = message
                    w.job = None
                    if what == "done":
                        plan.finished(key)
                        bar.show(note="" if key in plan.done else f"{key}: finished without writing its record")
                    else:
                        plan.failed(key, why, retry=False)
                        bar.show(note=f"{key} failed: {why}")
                elif w.process.sentinel in ready or (w.conn in ready and not w.process.is_alive()):
                    w.process.join()
                    pool.remove(w)
                    w.conn.close()
                    key, why = w.job, f"worker process died ({_exit_name(w.process.exitcode)})"
                    if plan.failed(key, why, retry=True):
                        bar.show(0, note=f"{key}: {why}; retrying")
                    else:
                        bar.show(note="" if key in plan.done else f"{key}: {why}")
        plan.abandon()
    except BaseException:
        for w in pool:
            w.stop(kill=True)
        raise
    finally:
        bar.close()
    for w in pool:
        w.stop()
    plan.outcome.seconds = time.perf_counter() - t0
    return plan.outcome


def _exit_name(code: int | None) -> str:
    if code is not None and code < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-code).name}"
    return f"exit code {code}"


# ---------------------------------------------------------------------------------------
# ray: tasks on a Ray cluster


def run_ray(
    jobs: list[Job],
    *,
    address: str | None = None,
    workers: int | None = None,
    retries: int = 2,
    progress: bool = True,
    cache_dir: str | None = None,
    desc: str = "sweep",
) -> Outcome:
    """Run the unfinished ``jobs`` as Ray tasks, on the cluster at ``address`` or on a local Ray
    started for the run with ``workers`` CPUs (default: every core).

    Each task asks for its job's ``cpus`` and ``gpus``; a task whose worker died is retried up
    to ``retries`` times by Ray; a job that raises fails at once. With a cluster, the run
    folder must be on a file system every node sees (the jobs write their records there).
    """
    try:
        import ray
        from ray.exceptions import RayTaskError
    except ImportError:
        raise RuntimeError("the ray backend needs Ray: pip install 'mindgap[ray]'") from None
    t0 = time.perf_counter()
    plan = _Plan(jobs, retries)
    if workers is not None and workers < 1:
        raise ValueError("--workers must be at least 1")
    cache_dir = compilation_cache_dir() if cache_dir is None else cache_dir
    with _ray_session(ray, address, workers, progress) as session:
        remote = ray.remote(_ray_task)
        bar = _Progress(plan, progress, desc)
        in_flight: dict = {}
        try:
            while plan.open:
                capacity = max(1, int(ray.cluster_resources().get("CPU", 1)))
                while len(in_flight) < capacity:
                    job = plan.next()
                    if job is None:
                        break
                    task = remote.options(
                        num_cpus=job.cpus,
                        num_gpus=job.gpus,
                        max_retries=retries,
                        retry_exceptions=False,
                        name=job.key,
                    )
                    ref = task.remote(job.call, job.kwargs, job.key, str(job.log), cache_dir, str(job.record))
                    in_flight[ref] = job.key
                    bar.show(0)
                if not in_flight:
                    break  # nothing runs and nothing is ready: what is left waits on failed jobs
                ready, _ = ray.wait(list(in_flight), num_returns=1, timeout=1.0)
                for ref in ready:
                    key = in_flight.pop(ref)
                    try:
                        ray.get(ref)
                        plan.finished(key)
                        bar.show()
                    except RayTaskError as e:
                        why = _first_line(e.cause if e.cause is not None else e)
                        plan.failed(key, why, retry=False)
                        bar.show(note=f"{key} failed: {why}")
                    except Exception as e:  # the worker died more often than Ray retried it
                        plan.failed(key, f"Ray task lost: {_first_line(e)}", retry=False)
                        bar.show(note=f"{key}: Ray task lost ({type(e).__name__})")
            plan.abandon()
        except BaseException:
            for ref in in_flight:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
            raise
        finally:
            bar.close()
        session.keep = bool(plan.outcome.failed)
    plan.outcome.seconds = time.perf_counter() - t0
    return plan.outcome


def _first_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".strip().splitlines()[0]


class _Session:
    keep = False


_TOKENS: list[str] = []


def _token() -> str:
    """This process's token for the local Rays it starts: one for all of them, because Ray
    keeps the first token it reads for the life of the process."""
    if not _TOKENS:
        _TOKENS.append(secrets.token_hex(32))
    return _TOKENS[0]


@contextlib.contextmanager
def _ray_session(ray, address: str | None, cpus: int | None, progress: bool):
    """Connect to the cluster at ``address``, or start a local Ray for the run and stop it after.

    A local Ray gets: its session files in a fresh ``/tmp/mindgap-ray-*`` (short: Ray's
    sockets live there; removed at the end unless a job failed), token authentication with
    a token kept in this run's environment (Ray would otherwise write ``~/.ray/auth_token``),
    the object store at :data:`OBJECT_STORE_BYTES`, no dashboard, and this process's import
    path, so its workers import the same ``mindgap`` as the run.
    """
    session = _Session()
    if ray.is_initialized():
        yield session
        return
    if address:
        ray.init(address=address, log_to_driver=False, logging_level="ERROR")
        if progress:
            print(f"Ray cluster at {address}: {ray.cluster_resources().get('CPU', 0):g} CPUs", flush=True)
        try:
            yield session
        finally:
            ray.shutdown()
        return
    saved = {k: os.environ.get(k) for k in ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "PYTHONPATH")}
    if saved["RAY_AUTH_MODE"] is None:
        os.environ["RAY_AUTH_MODE"] = "token"
        os.environ["RAY_AUTH_TOKEN"] = _token()
        # Ray reads RAY_AUTH_MODE into its configuration when it is imported; read it again
        with contextlib.suppress(Exception):
            from ray._raylet import Config

            Config.initialize("")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
    temp = tempfile.mkdtemp(prefix="mindgap-ray-", dir="/tmp")
    try:
        ray.init(
            num_cpus=cpus or os.cpu_count(),
            include_dashboard=False,
            object_store_memory=OBJECT_STORE_BYTES,
            _temp_dir=temp,
            log_to_driver=False,
            logging_level="ERROR",
        )
        if progress:
            print(
                f"local Ray: {ray.cluster_resources().get('CPU', 0):g} CPUs, session files in {temp} "
                "(removed at the end unless a job fails), token in this run's environment (nothing in ~/.ray)",
                flush=True,
            )
        yield session
    finally:
        ray.shutdown()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        if session.keep:
            print(f"Ray's session files (worker logs) kept in {temp}", file=sys.stderr)
        else:
            shutil.rmtree(temp, ignore_errors=True)
