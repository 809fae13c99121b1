"""Seed slices: one seed of a learner job trained alone, resumable, and the job assembled from its seeds.

Why: a job trains all its seeds at once, and a job of a full preset takes longer than a
session holds a machine (gym: about an hour a job or more on a 2-core CPU, docs/experiments/gym.md, "The
budget"). ``mindgap reproduce NAME --out DIR --job KEY --seed I`` trains seed ``I`` of the job alone,
so a few hours finish whole pieces that can be committed and picked up elsewhere:

* the slice trains from the key seed ``I`` has in the whole job (the engine's ``seed_ids``:
  :func:`~mindgap.algorithms.engine.seed_keys`; on the host loop its envs' and evaluation episodes'
  seeds too), checkpointing under ``DIR/train/WORLD__JOB/seed-I/`` (a kill resumes it);
* a finished slice writes its *partial record* ``DIR/seeds/WORLD__JOB/seed-I.json``: the job's
  record for that seed alone (curve rows name the seed by its index in the job), plus the
  per-seed values of fields the record averages over seeds (``seed_maps``);
* when every seed has one, the job's record ``DIR/jobs/WORLD__JOB.json`` is assembled from them
  (:func:`assemble`: the whole job's fields and shapes, with ``seeds_apart: true``), and the job
  counts as done for ``--assemble``, the tables and ``mindgap report``.

A job with some partial records finishes in slices: a run without ``--seed`` (the whole
experiment, or ``--job KEY``) trains its missing seeds apart and assembles, so no seed is
trained twice and one record never mixes seeds trained together with seeds trained apart. A job
whose record exists already has nothing to slice. Only learner jobs are sliced (their seeds are
independent runs of the engine); a job that is not (a reference, people, Policy Shaping, a fit) is
refused, as are the experiments whose jobs are run whole (:data:`EXPERIMENTS` lists the others).

What a slice reproduces (docs/experiments/gym.md, "Seed slices", measures it): seed ``I`` alone is
bit for bit seed ``I`` of any job of that configuration trained apart, whatever its seed count.
It is the whole job's seed ``I`` only for ``I = 0``, and then up to rounding (one seed's arithmetic
is not a batch's): a whole job vmaps its seeds, and JAX draws every row of a vmapped batch of
mindgap's ``rbg`` keys from the batch's first key, so the whole job's seed ``I`` draws block ``I`` of
seed 0's stream where seed ``I`` alone draws from its own key. Seeds trained apart are other, equally
random seeds, marked ``seeds_apart`` in the record.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .._io import atomic_write
from ._runfolder import RunFolder, nan_to_none, partial_path, partial_seeds, record_path

EXPERIMENTS = ("nav", "priors", "sampling", "gym")
"""The experiments whose learner jobs can be trained seed by seed (``--seed``)."""

PER_SEED = (
    "final",
    "paths",
    "routes",
    "reward_error",
    "belief_error",
    "dynamics_error",
    "belief_stay_error",
    "dynamics_stay_error",
)
"""Record fields that hold one entry per seed (None where the job has none)."""

SEED_ZERO = ("rollout",)
"""Record fields made from seed 0 alone (the gym experiment's animation of seed 0's policy)."""

_OWN = ("seed", "seconds", "cpu_seconds", "command", "seed_maps")
"""A partial record's own fields, not the job's. ``seconds`` is the slice's wall time,
``cpu_seconds`` the process's CPU time over it: a slice stopped for a while (``kill -STOP``) or
sharing its core shows in the first and not in the second."""

_LOCAL = {"belief_model": ("path",)}
"""Entries of shared fields that name the machine a seed ran on (the learned belief's cache file):
left out when the seeds' records are compared, seed 0's kept."""


def check(job, seed_ids, seeds: int, sliceable: Callable | None, name: str) -> tuple[int, ...]:
    """The seeds to train apart, or a one-line refusal.

    Raises:
        ValueError: the experiment runs its jobs whole (``sliceable`` None), the job is not one of
            seed-trained learners, or a seed is outside ``0 … seeds − 1``.
    """
    if sliceable is None:
        raise ValueError(f"--seed: {name} runs its jobs whole; seeds are sliced in {', '.join(EXPERIMENTS)}")
    if not sliceable(job):
        raise ValueError(f"--seed: {job.key} is a {job.method} job, not a seed-trained learner; it runs whole")
    ids = tuple(dict.fromkeys(int(i) for i in seed_ids))
    bad = [i for i in ids if not 0 <= i < seeds]
    if bad:
        raise ValueError(f"--seed {bad[0]}: {job.key} has {seeds} seed(s), numbered 0 to {seeds - 1}")
    return ids


def run_seeds(
    folder: RunFolder,
    job,
    seeds: int,
    ids: tuple[int, ...],
    compute: Callable,
    *,
    fresh: bool,
    progress: bool,
    rerun: str = "",
) -> dict:
    """Train the seeds ``ids`` of ``job`` apart (one after another, each resumable); assemble the job
    when every seed has its partial record.

    ``compute(folder, job, seeds, fresh=, progress=, seed_ids=)`` is the experiment's job record
    for the seeds ``seed_ids`` alone. Returns what ``mindgap reproduce --job KEY`` prints: ``job``
    (the last seed's partial record, or the job's record when it was made whole), ``record`` (its
    path) and ``notes``.
    """
    whole = folder.done(job.key)
    if whole is not None and not whole.get("seeds_apart"):
        note = f"{job.key} is done (its seeds trained together); nothing to train apart"
        return {"job": whole, "record": record_path(folder.root, job.key), "notes": [note]}
    rec = None
    for i in ids:
        path = partial_path(folder.root, job.key, i)
        if path.exists():
            rec = json.loads(path.read_text())
            continue
        t0, c0 = time.perf_counter(), time.process_time()
        rec = compute(folder, job, seeds, fresh=fresh, progress=progress, seed_ids=(i,))
        rec.update(key=job.key, world=job.world, method=job.method, label=job.label, tags=job.tags, seed=i)
        rec["seconds"] = time.perf_counter() - t0
        rec["cpu_seconds"] = time.process_time() - c0
        if rerun:
            rec["command"] = f"{rerun} --job {job.key} --seed {i}"
        atomic_write(path, json.dumps(rec))
        if progress:
            print(f"{job.key} seed {i}: final return {np.mean(rec['final']):.1f} ({rec['seconds']:.0f} s)", flush=True)
    notes = [f"seed {i} of {job.key}: partial record in {partial_path(folder.root, job.key, i)}" for i in ids]
    if finish(folder, job, seeds, rerun=rerun) is not None:
        notes.append(f"all {seeds} seeds trained apart: the job's record is {record_path(folder.root, job.key)}")
    else:
        left = sorted(set(range(seeds)) - set(partial_seeds(folder.root, job.key)))
        notes.append(f"seeds still to train: {', '.join(map(str, left))} (--job {job.key} --seed N)")
    return {"job": rec, "record": partial_path(folder.root, job.key, ids[-1]), "notes": notes}


def finish(folder: RunFolder, job, seeds: int, *, rerun: str = "") -> dict | None:
    """The job's record assembled from its seeds' partial records and saved, or None while a seed has none."""
    done = folder.done(job.key)
    if done is not None:
        return done
    if partial_seeds(folder.root, job.key) != list(range(seeds)):
        return None
    partials = [json.loads(partial_path(folder.root, job.key, i).read_text()) for i in range(seeds)]
    rec = assemble(partials)
    if rerun:
        rec["command"] = f"{rerun} --job {job.key}"
    folder.save(job.key, rec)
    return rec


def complete(folder: RunFolder, job, seeds: int, compute: Callable, **kw) -> dict | None:
    """A job some of whose seeds were trained apart: train the rest apart (unless ``assemble_only``)
    and assemble it. None when it has no partial records (it runs whole) or, assembling only, lacks some."""
    if folder.done(job.key) is not None or not partial_seeds(folder.root, job.key):
        return None
    if kw.pop("assemble_only", False):
        return finish(folder, job, seeds, rerun=kw.get("rerun", ""))
    run_seeds(folder, job, seeds, tuple(range(seeds)), compute, **kw)
    return folder.done(job.key)


def assemble(partials: list[dict]) -> dict:
    """The job's record from its seeds' partial records (seed 0 first, one seed each).

    Per-seed fields (:data:`PER_SEED`) are joined in seed order, curve rows ordered as the whole
    job writes them (by step, then seed), fields averaged over seeds (a partial record's
    ``seed_maps``) averaged again from each seed's full-precision values, :data:`SEED_ZERO`
    fields taken from seed 0; every other field must be the same in every partial record (up to
    :data:`_LOCAL`, which may name the machine).

    Raises:
        ValueError: the partial records are not seeds 0, 1, … of one job, or differ in a field
            that no seed may change.
    """
    first = partials[0]
    key = first.get("key", "the job")
    if [p.get("seed") for p in partials] != list(range(len(partials))):
        raise ValueError(
            f"{key}: partial records of seeds {[p.get('seed') for p in partials]}, not 0 to {len(partials) - 1}"
        )
    maps = first.get("seed_maps") or {}
    rec = {}
    for name, value in first.items():
        if name in _OWN:
            continue
        if name == "curve":
            rows = [row for p in partials for row in p["curve"]]
            rec[name] = sorted(rows, key=lambda row: (row[1], row[0]))
        elif name == "seeds":
            rec[name] = sum(p["seeds"] for p in partials)
        elif name in maps:
            stack = [m for p in partials for m in p["seed_maps"][name]]
            rec[name] = nan_to_none(np.asarray(_nan(stack), np.float32).mean(0))
        elif name in PER_SEED and value is not None:
            rec[name] = [x for p in partials for x in p[name]]
        elif name in SEED_ZERO:
            rec[name] = value
        elif any(_shared(name, p.get(name)) != _shared(name, value) for p in partials[1:]):
            raise ValueError(f"{key}: its seeds' partial records differ in {name!r}; they cannot make one record")
        else:
            rec[name] = value
    rec["seconds"] = sum(p.get("seconds", 0.0) for p in partials)
    cpu = [p.get("cpu_seconds") for p in partials]
    if all(c is not None for c in cpu):
        rec["cpu_seconds"] = sum(cpu)
    rec["seeds_apart"] = True
    return rec


def _shared(name: str, value):
    """``value`` of the shared field ``name`` as the seeds' records must agree on it (:data:`_LOCAL`)."""
    if name in _LOCAL and isinstance(value, dict):
        return {k: v for k, v in value.items() if k not in _LOCAL[name]}
    return value


def _nan(rows):
    """A map stored with None on walls, as floats with NaN (nested lists, any depth)."""
    if isinstance(rows, list):
        return [_nan(r) for r in rows]
    return np.nan if rows is None else rows


def slice_dir(job_dir: Path, seed_ids: tuple[int, ...] | None) -> Path:
    """Where a job keeps its engine checkpoint: ``job_dir`` for the whole job, ``job_dir/seed-I`` for
    seed ``I`` trained apart (``seed-I-J`` for seeds trained together apart from the others)."""
    if seed_ids is None:
        return Path(job_dir)
    return Path(job_dir) / ("seed-" + "-".join(str(int(i)) for i in seed_ids))
