"""Stand-in jobs for the backend tests: cheap, deterministic, and keeping the run folder's contract.

``write_record`` writes a record computed from the job's key and arguments (atomically, as
every experiment's job does) after appending a line to ``runs.log`` (so a test can count how
often a job ran); with ``hold`` it first writes its process id to ``pids/KEY`` and waits for
that file to be removed or ``hold`` seconds to pass, so that a test can kill it mid-job.
"""

from __future__ import annotations

import hashlib
import os
import time
from pathlib import Path

from mindgap.experiments._runfolder import RunFolder, record_path


def write_record(root: str, key: str, value: float, hold: float = 0.0, fail: bool = False) -> None:
    root = Path(root)
    with open(root / "runs.log", "a") as f:
        f.write(f"{key} {os.getpid()}\n")
    if hold:
        pid = root / "pids" / key.replace("/", "__")
        pid.parent.mkdir(parents=True, exist_ok=True)
        pid.write_text(str(os.getpid()))
        t0 = time.monotonic()
        while pid.exists() and time.monotonic() - t0 < hold:
            time.sleep(0.05)
    if fail:
        raise ValueError(f"{key} was told to fail")
    digest = hashlib.sha256(f"{key}:{value!r}".encode()).hexdigest()
    score = int(digest[:8], 16) / 2**32 * value
    print(f"{key}: score {score}")
    RunFolder(root, CONFIG).save(key, {"key": key, "value": value, "score": score})


CONFIG = {"stand-in": 1}
"""The stand-in sweep's configuration (its run folder's ``config.json``)."""


def job(root: Path, key: str, value: float, **kw):
    """A :class:`~mindgap.sweeps.Job` of :func:`write_record`."""
    from mindgap.sweeps import Job

    kwargs = {"root": str(root), "key": key, "value": value, **kw}
    log = Path(root) / "logs" / (key.replace("/", "__") + ".log")
    return Job(key, write_record, kwargs, record_path(root, key), log)
