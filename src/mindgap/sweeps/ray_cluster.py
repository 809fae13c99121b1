"""The Ray backend: a sweep's jobs as tasks on a Ray cluster, or on a local Ray started for the run.

Ray handles scheduling, placement and retries (``max_retries`` for a task whose worker died;
an exception raised by the job itself is not retried, it would only fail again). What is set
by hand are Ray's defaults for a run: a local Ray started for the run keeps its session files
in a fresh folder under ``/tmp`` (removed at the end when every job succeeded), its
authentication token in the environment of the run rather than in ``~/.ray/auth_token``, a
small object store (jobs return nothing: their results are files) and no dashboard. Every
task points at one persistent JAX compilation cache.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from .._io import compilation_cache_dir
from .jobs import Job, Outcome, Plan, Progress, execute, first_line

OBJECT_STORE_BYTES = 128 * 1024**2
"""Object store of a local Ray started for a run: jobs write files and return nothing."""


def _ray_task(call: Callable, kwargs: dict, key: str, log: str, cache_dir: str | None, record: str) -> None:
    execute(call, kwargs, key, log, cache_dir)
    if not Path(record).exists():
        raise RuntimeError(f"{key} finished without writing its record {record}")


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
    plan = Plan(jobs, retries)
    if workers is not None and workers < 1:
        raise ValueError("--workers must be at least 1")
    cache_dir = compilation_cache_dir() if cache_dir is None else cache_dir
    with _ray_session(ray, address, workers, progress) as session:
        remote = ray.remote(_ray_task)
        bar = Progress(plan, progress, desc)
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
                        why = first_line(e.cause if e.cause is not None else e)
                        plan.failed(key, why, retry=False)
                        bar.show(note=f"{key} failed: {why}")
                    except Exception as e:  # the worker died more often than Ray retried it
                        plan.failed(key, f"Ray task lost: {first_line(e)}", retry=False)
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
