"""The local backend: a pool of spawned worker processes on this machine.

A small pool of its own rather than :class:`concurrent.futures.ProcessPoolExecutor`, because
the executor breaks as a whole when one worker is killed (every job in flight fails with it),
while this pool knows which worker runs which job: a worker that dies (SIGKILL, out of
memory) costs only its own job, which is retried on a fresh worker. Workers are long-lived,
so a job's compiled XLA programs serve the next job in the same process, and every worker
points at one persistent JAX compilation cache, so a program compiled by one is read from
disk by the others.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import time
from multiprocessing.connection import wait

from .._io import compilation_cache_dir, use_compilation_cache
from .jobs import Job, Outcome, Plan, Progress, execute


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
    plan = Plan(jobs, retries)
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError("--workers must be at least 1")
    cache_dir = compilation_cache_dir() if cache_dir is None else cache_dir
    bar = Progress(plan, progress, desc)
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
