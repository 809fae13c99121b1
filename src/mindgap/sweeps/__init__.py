"""Sweeps: many jobs of mindgap's experiments run on worker processes or a Ray cluster.

* :mod:`~.jobs`: the :class:`Job` type, the job contract and what the backends share;
* :mod:`~.local` and :mod:`~.ray_cluster`: the two backends;
* :mod:`~.spec`, :mod:`~.grid`, :mod:`~.parts`: a sweep file (``mindgap sweep SPEC``), its grid
  of learners × worlds × settings, and the parts it is cut into (each a run folder).

:func:`run` runs jobs on a backend by name.
"""

from __future__ import annotations

from .jobs import BACKENDS, Job, Outcome
from .local import run_local
from .ray_cluster import run_ray

__all__ = ["BACKENDS", "Job", "Outcome", "run", "run_local", "run_ray"]


def run(jobs: list[Job], backend: str = "local", **kw) -> Outcome:
    """Run the unfinished ``jobs`` on ``backend`` (:func:`run_local` or :func:`run_ray`, ``kw`` theirs)."""
    if backend == "local":
        return run_local(jobs, **kw)
    if backend == "ray":
        return run_ray(jobs, **kw)
    raise ValueError(f"unknown backend {backend!r}: choose from {', '.join(BACKENDS)}")
