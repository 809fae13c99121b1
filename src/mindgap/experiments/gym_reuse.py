"""A job the person never enters, taken from another run of the same robot (``mindgap reproduce gym --reuse``).

``hopper-fixed-seen`` and ``cheetah-seen`` are ``hopper-fixed`` and ``cheetah`` with another person
(:data:`~.prefbias_gym.DOMAINS`). SAC trains on the env's own reward and never asks her, so its job on
a seen domain is the computation its job on the base domain is: the same env, learner configuration,
steps and seed keys. On the fast preset the two records agree bit for bit in every field the training
makes (the curve, the final returns, the paths and the animation: docs/experiments/gym.md, "The person
as she sees the robot"). ``mindgap reproduce gym --worlds … --out DIR --job DOMAIN/sac --reuse SOURCE``
takes the record from the run folder ``SOURCE`` instead of training its five slices again (1.6
core-hours on the hopper and 2.0 on the cheetah, by the base runs' records), after checking, each refused with one line:

* the job is one the person never enters (:data:`PERSONLESS`);
* ``SOURCE``'s configuration is this run's in every field but those that choose which jobs run
  (:data:`SELECTION`);
* ``SOURCE`` ran exactly one domain with this domain's robot (the same env, belief env, runtime and
  drawing env: the person and PrefBias's posterior may differ), and holds that domain's job whole.

The record written is the one this run would have made: the training's fields from ``SOURCE``, the
person's belief figures (``belief_model``) of this domain, its own key, world and command, the
animation copied under its own name, and ``reused_from`` (the run folder, the job's key there and the
SHA-256 of its record). Written by hand: no library keeps run folders.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from . import prefbias_common as pc
from . import registry
from ._runfolder import RunFolder, partial_seeds, record_path, same_config
from .gym_measures import check_person
from .prefbias_gym import domain, jobs, load_world

PERSONLESS = ("sac",)
"""Job methods that never ask the person: SAC on the env's own reward."""

SELECTION = ("worlds", "budgets", "coin", "methods", "pebble_queries", "levels")
"""Configuration fields that choose which jobs a run holds, not what a job computes."""


def robot(name: str) -> tuple:
    """What a domain's SAC job reads of it: its env, belief env, runtime and drawing env."""
    d = domain(name)
    return (d.env, d.belief_env, d.runtime, d.draw)


def reuse(cfg, out: Path, key: str, source: Path, *, progress: bool = False) -> dict:
    """Write job ``key``'s record in the run folder ``out`` from the run folder ``source``.

    Returns ``{"job": record, "record": path, "notes": [...]}`` as a ``--job`` run does.

    Raises:
        ValueError: the job is not one of this run's, or asks the person; ``source`` is not a run of this
            configuration, ran no domain (or more than one) with this robot, or lacks the job whole;
            ``out`` has the job already, whole or some of its seeds.
    """
    job = pc.select_job(jobs(cfg), key, "gym")[-1]
    if job.method not in PERSONLESS:
        raise ValueError(
            f"--reuse takes a job the person never enters ({', '.join(PERSONLESS)}); {key} is {job.method}"
        )
    source = Path(source)
    stored_path = source / "config.json"
    if not stored_path.is_file():
        raise ValueError(f"--reuse: {source} is not a run folder (no config.json)")
    stored = json.loads(stored_path.read_text())
    if not same_config(stored, cfg, ignore=SELECTION):
        raise ValueError(f"--reuse: {source} ran another configuration than this run's")
    twins = [w for w in stored.get("worlds", ()) if robot(w) == robot(job.world)]
    if len(twins) != 1:
        found = "no domain" if not twins else f"{len(twins)} domains ({', '.join(twins)})"
        raise ValueError(f"--reuse: {source} ran {found} with {job.world}'s robot; it needs exactly one")
    base_key = f"{twins[0]}/{job.key.split('/', 1)[1]}"
    base_path = record_path(source, base_key)
    if not base_path.is_file():
        raise ValueError(f"--reuse: {source} has no whole record of {base_key}")
    text = base_path.read_text()
    base = json.loads(text)
    if base.get("seeds") != cfg.seeds:
        raise ValueError(f"--reuse: {base_key} in {source} has {base.get('seeds')} seeds; this run has {cfg.seeds}")
    folder = RunFolder(out, cfg)
    if folder.done(job.key) is not None:
        raise ValueError(f"--reuse: {out} has a record of {job.key} already")
    if partial_seeds(out, job.key):
        raise ValueError(f"--reuse: {out} has seeds of {job.key} trained apart; finish them with --job {job.key}")
    _, belief = load_world(job.world, cfg, progress=progress, cache_dir=folder.root)
    check_person(job.world, belief, folder.done(f"{job.world}/reference"))
    record = {
        **base,
        "key": job.key,
        "world": job.world,
        "label": job.label,
        "belief_model": None if belief is None else {k: v for k, v in belief.items() if k != "config"},
        "command": f"mindgap reproduce gym --worlds {','.join(cfg.worlds)} --out {out} --job {key} --reuse {source}",
        "reused_from": {"run": str(source), "key": base_key, "sha256": hashlib.sha256(text.encode()).hexdigest()},
    }
    if base.get("rollout"):
        gif = Path("rollouts") / (job.key.replace("/", "__") + ".gif")
        (folder.root / gif).parent.mkdir(parents=True, exist_ok=True)
        tmp = folder.root / (str(gif) + ".part")
        shutil.copyfile(source / base["rollout"], tmp)
        tmp.replace(folder.root / gif)
        record["rollout"] = str(gif)
    folder.save(job.key, record)
    folder.write_progress("gym", [j.key for j in jobs(cfg)], registry.command("gym", cfg, out))
    return {"job": record, "record": record_path(out, job.key), "notes": [f"taken from {base_path}"]}


def check_record(record: dict, source_record: dict) -> list[str]:
    """The fields the training makes on which ``record`` and ``source_record`` differ (empty: the same run)."""
    own = {"key", "world", "label", "belief_model", "command", "rollout", "reused_from", "seconds", "cpu_seconds"}
    return sorted(k for k in set(record) | set(source_record) if k not in own and record.get(k) != source_record.get(k))
