"""What the PrefBias experiments ``nav``, ``priors`` and ``sampling`` share (dissertation §3.4).

* **Learners** on one schedule: a PrefBias loop (:mod:`~mindgap.algorithms.prefbias`) and
  the PEBBLE and SAC runs of :mod:`~mindgap.algorithms.pbrl` that copy its steps, chunks,
  evaluation, SAC settings, rounds, segments and exploration, so that methods differ only
  in how they learn the reward. Presets ``fast`` (tiny; tests and dry runs) and ``full``
  (PrefBias's defaults, 50 000 steps, with 80 queries a round).
* **Jobs** in a :class:`~._runfolder.RunFolder`: ``WORLD/reference`` (a uniformly random
  policy's return and the planning check's routes) and one job per learner, all seeds
  vmapped inside one call of the existing ``train``. A finished job is one JSON record;
  an unfinished one resumes from its engine checkpoint under ``train/``. A learner job's seeds
  may also train one at a time (``--seed``, :mod:`~._seed_slices`: a full job outlasts a session).
* **Metrics**: the normalised score, the route each seed takes, the errors of the learned
  belief and reward (:mod:`~.world_measures`: on any world, what its map allows);
  **reports**: result rows, curve rows, markdown tables, bar charts.
"""

from __future__ import annotations

import dataclasses
import io
import json
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._io import atomic_write
from ..algorithms import methods, pbrl
from ..algorithms.engine import Schedule
from ..algorithms.prefbias import PrefBiasLoopConfig, prefbias_config
from ..models.reward_ensemble import RewardConfig
from ..planning.terrain_maps import noise_maps, stay_maps, table_noise_map, table_stay_map
from . import _seed_slices as slices
from . import registry
from ._runfolder import RunFolder
from ._runfolder import nan_to_none as nan_to_none  # a record's maps (eps_common reads it here)
from .claim_sources import claim as claim  # the experiments' claims, with their sources' ids
from .world_measures import (
    experiment_world,
    has_map,
    reference_record,
    reward_error,
    route_means,
    route_of,
    seed_route_share,
)

# ---------------------------------------------------------------------------------------
# configurations


@dataclasses.dataclass(frozen=True)
class Learners:
    """The three learners of an experiment, on one schedule (the query budget is set per job)."""

    prefbias: PrefBiasLoopConfig
    pebble: pbrl.PbRLConfig
    sac: pbrl.PbRLConfig


@dataclasses.dataclass(frozen=True)
class ReferenceConfig:
    """The per-world reference job: a random policy and the planning check (:func:`check_world`)."""

    random_episodes: int = 100
    """Episodes of the uniformly random policy (the 0 of the normalised score)."""
    plan_resolution: int = 4
    """Sub-cells per cell side of the planning check."""
    plan_rollouts: int = 200
    """Rollouts of each planned route."""
    seed: int = 0


def _schedule(pb: PrefBiasLoopConfig) -> dict:
    """The fields of a PrefBias run that its PEBBLE and SAC counterparts copy."""
    names = ("total_steps", "chunk", "eval_every", "eval_episodes", "sac", "seed", "teacher")
    return {n: getattr(pb, n) for n in names}


def learners(preset: str) -> Learners:
    """``full``: PrefBias's defaults (50 000 steps) with 80 queries a round (as PEBBLE's
    measured nav runs); ``fast``: :func:`prefbias_config` ``("fast")`` — 1500 steps, 30 queries,
    tiny networks — and a small reward ensemble for PEBBLE."""
    if preset == "full":
        pb = prefbias_config("full", per_round=80)
        reward = RewardConfig()
    elif preset == "fast":
        pb = prefbias_config("fast")
        reward = RewardConfig(hidden=(16, 16), batch_size=16, updates=20)
    else:
        raise ValueError(f"unknown preset {preset!r}: use 'fast' or 'full'")
    rounds = dict(
        queries=pb.queries,
        per_round=pb.per_round,
        feedback_every=pb.feedback_every,
        segment=pb.segment,
        explore_steps=pb.explore_steps,
        reward=reward,
    )
    return Learners(
        prefbias=pb,
        pebble=pbrl.method_config("pebble", **_schedule(pb), **rounds),
        sac=pbrl.method_config("sac", **_schedule(pb)),
    )


# ---------------------------------------------------------------------------------------
# jobs


class Job(NamedTuple):
    """One checkpointed unit of work.

    Attributes:
        key: its name in the run folder, ``WORLD/NAME``.
        world: a named world or world file.
        method: ``reference``, ``sac``, ``pebble``, ``prefbias`` or a registered preference learner's name.
        label: legend and table label.
        cfg: :class:`ReferenceConfig`, :class:`~mindgap.algorithms.pbrl.PbRLConfig` or
            :class:`~mindgap.algorithms.prefbias.PrefBiasLoopConfig`.
        tags: columns this job adds to every CSV row (e.g. queries, prior, sampler).
    """

    key: str
    world: str
    method: str
    label: str
    cfg: object
    tags: dict


def reference_job(world: str, cfg: ReferenceConfig) -> Job:
    return Job(f"{world}/reference", world, "reference", "reference", cfg, {})


def prefbias_job(world: str, cfg: PrefBiasLoopConfig, label: str, name: str, **tags) -> Job:
    """A PrefBias job; ``tags`` are the settings that distinguish it (for the CSV rows). With
    ``person="coin"`` its person answers by a fair coin (:func:`coin_flips`), so the tag and the
    config cannot disagree."""
    if tags.get("person") == "coin":
        cfg = coin_flips(cfg)
    return Job(f"{world}/{name}", world, "prefbias", label, cfg, {"queries": cfg.queries, **tags})


def oracle_job(world: str, learn: Learners) -> Job:
    return Job(f"{world}/sac", world, "sac", "SAC (oracle)", learn.sac, {"queries": 0})


PERSONS = {"biased": "biased", "unbiased": "unbiased", "reward-only": "true", "coin": "biased"}
"""Who answers a learner's queries, and the engine's teacher for them: the world's biased person
(r_H + log T_H), the same person without the bias (r_H + log T, the true dynamics), a person who
scores by r_H alone (B-Pref's teacher; a separate control, not the unbiased person), or a coin
(the biased person at β = 0, :func:`coin_flips`: every answer a fair coin, the control that shows
a learner learns from what the answers contain)."""


def coin_flips(cfg):
    """A learner's config whose person answers by a fair coin: Bradley–Terry at β = 0 (Eq. 3.4), so
    P(σ₁ ≻ σ₂) = ½ whatever the segments; the schedule, queries and everything else unchanged."""
    return dataclasses.replace(cfg, teacher=dataclasses.replace(cfg.teacher, beta=0.0))


def pebble_job(world: str, learn: Learners, queries: int, person: str = "biased") -> Job:
    """A PEBBLE job; with ``person="unbiased"`` the person scores by the true dynamics (tag ``person``)."""
    cfg = dataclasses.replace(learn.pebble, queries=queries)
    if person == "biased":
        return Job(
            f"{world}/pebble-q{queries}", world, "pebble", f"PEBBLE ({queries} queries)", cfg, {"queries": queries}
        )
    label = f"PEBBLE ({queries} queries, {person} person)"
    return Job(
        f"{world}/pebble-q{queries}-{person}", world, "pebble", label, cfg, {"queries": queries, "person": person}
    )


def method_job(world: str, name: str, learn: Learners, queries: int) -> Job:
    """A job of the registered preference learner ``name`` on PEBBLE's schedule and person.

    Its config is its ``full`` preset with every field of the engine's
    :class:`~mindgap.algorithms.engine.Schedule` (steps, rounds, SAC, the person's knobs, seed)
    taken from ``learn.pebble``, at ``queries``: what differs from PEBBLE is the method's own
    models and sampler, nothing of the schedule.

    Raises:
        ValueError: ``name`` is not registered, or is not a preference learner.
    """
    method = methods.get(name)
    if not method.learns_reward_from_preferences:
        raise ValueError(f"{name} learns no reward from preferences: an experiment's learners beside PEBBLE must")
    schedule = {f.name: getattr(learn.pebble, f.name) for f in dataclasses.fields(Schedule) if f.name != "method"}
    cfg = dataclasses.replace(method.preset("full"), **{**schedule, "queries": queries})
    return Job(
        f"{world}/{name}-q{queries}", world, name, f"{method.label} ({queries} queries)", cfg, {"queries": queries}
    )


def teacher_of(job: Job) -> str:
    """The engine's teacher for a job (:data:`PERSONS`); SAC's reward is the truth (``true``)."""
    person = job.tags.get("person", "biased")
    if person not in PERSONS:
        raise ValueError(f"{job.key}: unknown person {person!r}: choose from {', '.join(PERSONS)}")
    return "true" if job.method == "sac" else PERSONS[person]


def compute_job(
    folder: RunFolder, job: Job, seeds: int, *, fresh: bool, progress: bool, seed_ids: tuple[int, ...] | None = None
) -> dict:
    """The record of one job of these experiments: the reference or a learner's training (of the
    seeds ``seed_ids`` alone: a seed slice's partial record, :mod:`~._seed_slices`)."""
    world = experiment_world(job.world, "this experiment")
    if job.method == "reference":
        return _reference(world, job.cfg)
    out = job_dir(folder, job, seed_ids)
    return _learn(world, job, seeds, out, fresh=fresh, progress=progress, seed_ids=seed_ids)


def trains_seeds(job: Job) -> bool:
    """Whether ``job`` trains seeds of a registered learner (the jobs ``--seed`` may slice)."""
    return job.method in methods.METHODS


def job_dir(folder: RunFolder, job: Job, seed_ids: tuple[int, ...] | None = None) -> Path:
    """Where a job keeps its engine checkpoint (and anything else it stores beside its record); with
    ``seed_ids``, where those seeds trained apart keep theirs."""
    return slices.slice_dir(train_dir(folder.root, job), seed_ids)


def train_dir(root: Path, job: Job) -> Path:
    """:func:`job_dir` of the run folder at ``root``."""
    return root / "train" / job.key.replace("/", "__")


def run_jobs(
    folder: RunFolder,
    jobs: list[Job],
    seeds: int,
    *,
    fresh: bool,
    progress: bool,
    assemble_only: bool,
    compute=compute_job,
    rerun: str = "",
) -> dict[str, dict]:
    """Each job's record, computing (or resuming) the unfinished ones unless ``assemble_only``.

    ``compute(folder, job, seeds, fresh=, progress=) → dict`` makes a job's record (jobs run
    in order, so a job may read the records of those before it). ``rerun`` is the command
    line of the run; a new record keeps ``rerun --job KEY``, the line that computes it again.
    """
    records = {}
    for i, job in enumerate(jobs):
        rec = folder.done(job.key)
        if rec is None and not assemble_only:
            t0 = time.perf_counter()
            rec = compute(folder, job, seeds, fresh=fresh, progress=progress)
            rec.update(key=job.key, world=job.world, method=job.method, label=job.label, tags=job.tags)
            rec["seconds"] = time.perf_counter() - t0
            if rerun:
                rec["command"] = f"{rerun} --job {job.key}"
            folder.save(job.key, rec)
            if progress:
                what = f"final return {_pm(rec['final'])}" if "final" in rec else rec.get("done", "done")
                print(f"[{i + 1}/{len(jobs)}] {job.key}: {what} ({rec['seconds']:.0f} s)", flush=True)
        if rec is not None:
            records[job.key] = rec
    return records


def select_job(jobs: list[Job], key: str, name: str = "this experiment") -> list[Job]:
    """The job named ``key`` and, before it, the jobs whose records it reads (Policy Shaping's sources).

    Raises:
        ValueError: no job of that name (the message lists some that exist).
    """
    by_key = {job.key: job for job in jobs}
    if key not in by_key:
        some = ", ".join(list(by_key)[:6])
        raise ValueError(f"{name} has no job {key!r}: its jobs are named like {some}, …")
    job = by_key[key]
    needs = tuple(job.cfg) if job.method == "shaping" else ()
    return [by_key[k] for k in needs] + [job]


def _reference(world, cfg: ReferenceConfig) -> dict:
    return reference_record(world, cfg.random_episodes, cfg.seed, cfg.plan_resolution, cfg.plan_rollouts)


def learned_stay(res: dict, world) -> tuple[np.ndarray, np.ndarray]:
    """A PrefBias run's learned belief f_φ and agent model f_ψ as stay-probability maps [seeds, H, W] (NaN on walls)."""
    belief, agent = stay_maps(res["carry"], world.params)
    return np.asarray(belief), np.asarray(agent)


def biased_parts(world) -> list[str]:
    """Which parts of the terrain table the person gets wrong: ``noise`` (of a move) and/or ``stay``
    (the probability of not moving), compared cell by cell with the truth's."""
    parts = []
    for name, table in (("noise", table_noise_map), ("stay", table_stay_map)):
        gap = np.abs(np.asarray(table(world.belief())) - np.asarray(table(world.params)))
        if np.nanmax(gap) > 1e-3:
            parts.append(name)
    return parts


def learned_noise(res: dict, world, cfg: PrefBiasLoopConfig) -> tuple[np.ndarray, np.ndarray]:
    """A PrefBias run's learned belief f_φ and agent model f_ψ as noise maps [seeds, H, W] (NaN on walls)."""
    belief, agent = noise_maps(res["carry"], world.params, cfg.prefbias.dynamics.min_std)
    return np.asarray(belief), np.asarray(agent)


def _learn(world, job: Job, seeds: int, out: Path, *, fresh: bool, progress: bool, seed_ids=None) -> dict:
    """Train every seed of one learner, or the seeds ``seed_ids`` of it (vmapped, checkpointed in
    ``out``), and measure them; a slice keeps each seed's maps whole in ``seed_maps``."""
    kw = dict(seeds=seeds, out=out, progress=progress, fresh=fresh)
    if seed_ids is not None:
        kw["seed_ids"] = tuple(seed_ids)
    res = methods.train(job.method, world, job.cfg, teacher=teacher_of(job), **kw)
    learned = methods.learned_reward(job.method, res["carry"])
    final = np.asarray(res["final_returns"], np.float64)
    if not np.all(np.isfinite(final)):
        raise FloatingPointError(f"{job.key}: non-finite returns; the run diverged")
    rec = {
        "seeds": len(final),
        "curve": [[int(s), int(t), float(r), int(q)] for s, t, r, q in res["curve"]],
        "final": [float(x) for x in final.mean(1)],
        "final_episodes": int(final.shape[1]),
        "paths": [[np.round(np.asarray(p, np.float64), 4).tolist() for p in seed] for seed in res["paths"]],
        "routes": [route_of(world, paths) for paths in res["paths"]],
        "reward_error": None if learned is None else reward_error(world, *learned).tolist(),
    }
    if job.method == "prefbias" and has_map(world):
        person = np.asarray(table_noise_map(world.belief()))
        belief, agent = learned_noise(res, world, job.cfg)
        rec["belief_error"] = noise_rms_error(belief, person).tolist()
        rec["dynamics_error"] = noise_rms_error(agent, person).tolist()
        rec["belief_map"] = nan_to_none(belief.mean(0))  # NaN on walls in every seed
        rec["dynamics_map"] = nan_to_none(agent.mean(0))
        maps = {"belief_map": belief, "dynamics_map": agent}
        if job.cfg.prefbias.stay_head:  # the probability of not moving: what the redesigned worlds' person misjudges
            person_stay = np.asarray(table_stay_map(world.belief()))
            belief, agent = learned_stay(res, world)
            rec["belief_stay_error"] = noise_rms_error(belief, person_stay).tolist()
            rec["dynamics_stay_error"] = noise_rms_error(agent, person_stay).tolist()
            rec["belief_stay_map"] = nan_to_none(belief.mean(0))
            maps["belief_stay_map"] = belief
        if seed_ids is not None:  # the means over seeds are made again when the job is assembled
            rec["seed_maps"] = {k: [nan_to_none(m, None) for m in v] for k, v in maps.items()}
    return rec


def map_array(rows) -> np.ndarray:
    """A map stored by a record (None on walls) back as an array with NaN."""
    return np.array([[np.nan if x is None else x for x in row] for row in rows], np.float64)


# ---------------------------------------------------------------------------------------
# metrics


MIN_GAP = 1.0
"""The oracle must beat the random policy by at least this (a step's reward) to normalise by it."""


def normalised(returns, random_return: float, oracle_return: float) -> np.ndarray:
    """``(R − R_random) / (R_oracle − R_random)``: 0 a uniformly random policy, 1 the SAC oracle
    (:func:`oracle_return`).

    NaN where the oracle beats the random policy by less than :data:`MIN_GAP` (an oracle
    that has learned nothing, as in the ``fast`` presets, gives no scale).
    """
    gap = oracle_return - random_return
    r = np.asarray(returns, np.float64)
    return (r - random_return) / gap if gap >= MIN_GAP else np.full_like(r, np.nan)


def noise_rms_error(learned: np.ndarray, person: np.ndarray) -> np.ndarray:
    """Per seed, RMS over passable cells of the learned noise map minus the person's (cells).

    ``learned`` [seeds, H, W] (NaN on walls, :func:`~mindgap.models.prefbias_nets.belief_noise_map`),
    ``person`` [H, W] (:func:`~mindgap.models.prefbias_nets.table_noise_map` of the person's
    belief). The ``belief_noise_rms_error`` of ``mindgap prefbias``.
    """
    return np.sqrt(np.nanmean((np.asarray(learned) - person) ** 2, axis=(1, 2)))


def _pm(values) -> str:
    v = np.asarray(values, np.float64)
    return f"{v.mean():.1f} ± {v.std():.1f}"


# ---------------------------------------------------------------------------------------
# running and reporting


def run_experiment(
    cfg,
    out: Path,
    jobs: list[Job],
    write_outputs,
    *,
    fresh: bool,
    progress: bool,
    assemble_only: bool,
    compute=compute_job,
    references=("reference",),
    name: str = "this experiment",
    only: str | None = None,
    check=experiment_world,
    seed_ids: tuple[int, ...] | None = None,
    sliceable=None,
):
    """Run (or resume) ``jobs`` in the run folder ``out``, then ``write_outputs(cfg, out, records)``.

    ``assemble_only`` writes the outputs from the finished jobs and runs nothing; ``compute``
    makes a job's record (:func:`run_jobs`); ``references`` are the methods that learn nothing;
    ``name`` is how a refused world is told (every world is checked before anything is written).
    ``only`` runs one job (and those whose records it reads) and writes no outputs.
    ``check(world, name)`` refuses a job's world with one line (default :func:`experiment_world`;
    the ``gym`` experiment checks its domain names).
    ``sliceable(job)`` says which jobs may train seed by seed (None: none; ``compute`` then takes
    ``seed_ids=``): with ``only`` and ``seed_ids``, those seeds of the job train apart
    (:func:`~._seed_slices.run_seeds`), and a job some of whose seeds trained apart finishes so.
    Returns the summary, with ``missing_jobs``: how many jobs have no record yet; with
    ``only``, ``{"job": its record}`` (a seed's partial record with ``seed_ids``, its path and notes).
    """
    out = Path(out)
    everything = [job.key for job in jobs]
    if seed_ids is not None and only is None:
        raise ValueError("--seed trains seeds of one job: name it with --job KEY")
    if only is not None:
        jobs = select_job(jobs, only, name)
    if seed_ids is not None:
        seed_ids = slices.check(jobs[-1], seed_ids, cfg.seeds, sliceable, name)
    for spec in dict.fromkeys(job.world for job in jobs):
        check(spec, name)
    folder = RunFolder(out, cfg, fresh=fresh)
    rerun = registry.command(name, cfg, out) if name in registry.NAMES else ""
    kw = dict(fresh=fresh, progress=progress, rerun=rerun)
    if seed_ids is not None:
        summary = slices.run_seeds(folder, jobs[-1], cfg.seeds, seed_ids, compute, **kw)
        folder.write_progress(name, everything, rerun)
        return summary
    if sliceable is not None:  # jobs whose seeds began apart finish apart
        for job in jobs:
            slices.complete(folder, job, cfg.seeds, compute, assemble_only=assemble_only, **kw)
    records = run_jobs(
        folder,
        jobs,
        cfg.seeds,
        fresh=fresh,
        progress=progress,
        assemble_only=assemble_only,
        compute=compute,
        rerun=rerun,
    )
    folder.write_progress(name, everything, rerun)
    if only is not None:
        return {"job": records[only]}
    if not any(r["method"] not in references for r in records.values()):
        raise RuntimeError(f"{out} has no finished learner jobs to assemble")
    summary = write_outputs(cfg, out, records)
    summary["missing_jobs"] = len(jobs) - len(records)
    return summary


def result_row(rec: dict, reference: dict | None, oracle: dict | None) -> dict:
    """One learner's results: return, normalised score, routes and errors (means and stds over seeds).

    ``normalised`` is :func:`normalised` per seed against the random policy of ``reference``
    and the oracle's median seed (:func:`oracle_return`; NaN without them). ``goal_seeds`` is the
    share of seeds whose greedy rollouts reach the goal in most episodes, reported apart from the
    route they take.
    """
    final = np.asarray(rec["final"], np.float64)
    rand = reference["random_return"] if reference else float("nan")
    orc = oracle_return(oracle) if oracle else float("nan")
    norm = normalised(final, rand, orc) if reference and oracle else np.full_like(final, np.nan)
    row = {
        "method": rec["method"],
        "world": rec["world"],
        **rec["tags"],
        "label": rec["label"],
        "seeds": len(final),
        "return_mean": float(final.mean()),
        "return_std": float(final.std()),
        "normalised_mean": float(norm.mean()),
        "normalised_std": float(norm.std()),
        "better_route": seed_route_share(rec, reference),
        "goal_seeds": goal_seed_share(rec["routes"]),
        **route_means(rec["routes"]),
    }
    for name in ("reward_error", "belief_error", "dynamics_error", "belief_stay_error", "dynamics_stay_error"):
        if rec.get(name) is not None:
            v = np.asarray(rec[name], np.float64)
            row[f"{name}_mean"], row[f"{name}_std"] = float(v.mean()), float(v.std())
    plan = reference.get("plan_return") if reference else None
    row.update(random_return=rand, oracle_return=orc, plan_return=np.nan if plan is None else plan)
    if oracle and reference:
        row["oracle_seeds_above_random"] = int((seed_returns(oracle) > rand).sum())
    return row


def oracle_return(oracle: dict) -> float:
    """The oracle's return for the normalised score: the median over its seeds of each seed's mean
    final return. The mean let one failed oracle seed (nav2: one of five below the random policy)
    move every learner's score; the median is that of the seeds that learned, whatever one does."""
    return float(np.median(seed_returns(oracle)))


def seed_returns(rec: dict) -> np.ndarray:
    """A learner's final return per seed ([seeds]; a record's ``final`` holds each seed's mean greedy return)."""
    final = np.asarray(rec["final"], np.float64)
    return final.reshape(len(final), -1).mean(1)


def goal_seed_share(routes: list[dict]) -> float:
    """Share of seeds whose greedy rollouts reach the goal in most episodes (NaN off the map)."""
    goals = [r["goal"] for r in routes if r.get("goal") is not None]
    return float(np.mean([g > 0.5 for g in goals])) if goals else float("nan")


def curve_rows(rec: dict) -> list[dict]:
    """Rows of curves.csv: method, world, the job's tags (queries, …), seed, step, return, queries shown so far."""
    base = {"method": rec["method"], "world": rec["world"], **rec["tags"]}
    return [{**base, "seed": s, "step": t, "return": r, "queries_shown": q} for s, t, r, q in rec["curve"]]


def split(records: dict[str, dict]) -> tuple[dict, dict, list[dict]]:
    """(reference record per world, oracle record per world, the other learners in job order)."""
    refs = {r["world"]: r for r in records.values() if r["method"] == "reference"}
    oracles = {r["world"]: r for r in records.values() if r["method"] == "sac"}
    learned = [r for r in records.values() if r["method"] not in ("reference", "sac")]
    return refs, oracles, learned


def fmt(mean: float, std: float | None = None, digits: int = 1) -> str:
    if mean is None or not np.isfinite(mean):
        return "–"
    s = f"{mean:.{digits}f}".replace("-", "−")
    return s if std is None else f"{s} ± {std:.{digits}f}"


def share(x: float) -> str:
    return "–" if not np.isfinite(x) else f"{x:.0%}"


def markdown(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows]) + "\n"


def save_bars(path: Path, panels: list[tuple[str, dict[str, list[float]]]], title: str = "") -> Path:
    """Bar charts side by side: per panel ``(y label, {label: values per seed})``; mean ± std, seeds as dots."""
    import matplotlib.pyplot as plt

    from ..plotting.terrain import METHOD_COLOURS

    fig, axes = plt.subplots(1, len(panels), figsize=(3.3 * len(panels), 3.2), squeeze=False)
    for ax, (ylabel, groups) in zip(axes[0], panels):
        for i, values in enumerate(groups.values()):
            v = np.asarray([x for x in values if x is not None and np.isfinite(x)], np.float64)
            if not len(v):
                continue
            col = METHOD_COLOURS[i % len(METHOD_COLOURS)]
            ax.bar(i, v.mean(), yerr=v.std(), color=col, alpha=0.6, capsize=4)
            ax.plot(np.full(len(v), i) + np.linspace(-0.15, 0.15, len(v)), v, "o", color=col, ms=3)
        ax.set_xticks(range(len(groups)), list(groups), fontsize=7, rotation=15)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=150)
    plt.close(fig)
    atomic_write(Path(path), buf.getvalue())
    return Path(path)


def write_summary(out: Path, summary: dict) -> None:
    """summary.json (NaN written as null, so any JSON reader takes it) and table.md."""
    atomic_write(out / "summary.json", json.dumps(_finite(summary), indent=2))
    atomic_write(out / "table.md", summary["table_md"])


def _finite(obj):
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj
