"""Experiment ``table1``: GeReL vs SERD vs GeReL⁻ vs MaxEnt-IRL on grid7 (Table 1, Figs. 4–7).

For each belief setting (``reversed``, ``rotated``) and seed: a grid with an informative
corner pair, random demonstrations rated by a :class:`RatingTeacher`, and the four
learners given the same number of demonstrations (MaxEnt-IRL gets demonstrations of
the person's softmax policy instead of ratings). GeReL and SERD run with both belief
parameterisations (``tied``, ``per-sa``); GeReL⁻ and MaxEnt-IRL do not learn a belief,
so their one fit appears under both. A second sweep refits on nested subsets of
100–3000 demonstrations for the data-efficiency figure.

Every fit is a checkpointed job: a killed run resumes where it stopped.
"""

from __future__ import annotations

import json
import time
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from .. import rng
from .._io import atomic_write
from ..algorithms.gerel import GeReLConfig, fit_gerel
from ..algorithms.maxent_irl import MaxEntConfig, fit_maxent_irl
from ..algorithms.serd import SERDConfig, fit_serd
from ..envs.grid import CORNERS, move_targets
from ..feedback.demos import policy_demonstrations, random_demonstrations
from ..metrics import all_metrics
from ..models.belief import BeliefSpace, per_state_action, tied
from ..planning.grid_task import GridTask, make_grid
from ..teachers.rating import RatingTeacher
from . import registry
from ._runfolder import RunFolder, write_csv
from .table1_report import render_figures, summarise

METHODS = ("gerel", "serd", "gerel-minus", "maxent-irl")
RESULT_COLUMNS = ["setting", "belief_param", "method", "seed", "d_R", "d_Theta", "d_pi"]


@dataclass(frozen=True)
class Table1Config:
    """What ``mindgap reproduce table1`` runs."""

    seeds: int = 10
    """Seeds per setting (each: its own corner pair, demonstrations and ratings)."""
    demos: int = 2000
    """Rated demonstrations per fit (random demonstrations are weak evidence: docs/experiments/table1.md)."""
    length: int = 10
    """Steps per demonstration."""
    size: int = 7
    """Grid side."""
    settings: tuple[str, ...] = ("reversed", "rotated")
    """Beliefs of the simulated person."""
    belief_params: tuple[str, ...] = ("tied", "per-sa")
    """Belief parameterisations of GeReL and SERD."""
    demo_counts: tuple[int, ...] = (100, 300, 1000, 3000)
    """Demonstration counts of the data-efficiency sweep (tied belief)."""
    demo_count_seeds: int = 2
    """Seeds of the data-efficiency sweep."""
    gerel: GeReLConfig = field(default_factory=GeReLConfig)
    serd: SERDConfig = field(default_factory=SERDConfig)
    maxent: MaxEntConfig = field(default_factory=MaxEntConfig)


def preset(name: str) -> Table1Config:
    """``full`` (the real numbers) or ``fast`` (seconds; used by the tests and ``scripts/main.sh``)."""
    if name == "full":
        return Table1Config()
    if name == "fast":
        return Table1Config(
            seeds=1,
            demos=300,
            demo_counts=(100, 300),  # 300 reuses the main fits
            demo_count_seeds=1,
            gerel=GeReLConfig(restarts=4, keep=2, screen_iter=60, anneal_iter=60, max_iter=150),
            serd=SERDConfig(restarts=4, keep=2, screen_iter=60, max_iter=150),
            maxent=MaxEntConfig(max_iter=150),
        )
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def make_data(cfg: Table1Config, setting: str, seed: int, n_demos: int):
    """Grid task, rated random demonstrations and demonstrations of the person's policy."""
    task = make_grid(cfg.size, setting, seed=seed)
    key = jax.random.fold_in(rng.key(seed), zlib.crc32(setting.encode()) & 0x7FFFFFFF)
    k_demo, k_rate, k_policy, k_fit = jax.random.split(key, 4)
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    demos = random_demonstrations(k_demo, task.mdp, n_demos, cfg.length)
    rated = teacher.rate(k_rate, demos)
    policy_demos = policy_demonstrations(k_policy, task.mdp, teacher.policy(), n_demos, cfg.length)
    return task, rated, policy_demos, k_fit


def belief_space(task: GridTask, param: str) -> BeliefSpace:
    if param == "tied":
        return tied(move_targets(task.size), task.mdp.n_actions)
    if param in ("per-sa", "full"):
        return per_state_action(task.mdp.transitions, full=param == "full")
    raise ValueError(f"unknown belief parameterisation {param!r}: use tied, per-sa or full")


def _metrics(task: GridTask, w, t) -> dict:
    return all_metrics(task.mdp, jnp.asarray(w), jnp.asarray(t), task.true_weights, task.human_transitions)


def prior_metrics(task: GridTask, param: str) -> dict:
    """Metrics of an untrained fit: zero reward weights, the belief prior's mean transitions."""
    space = belief_space(task, param)
    prior_t = space.mean_transitions(jnp.ones(space.mask.shape))
    return all_metrics(task.mdp, jnp.zeros(task.mdp.n_features), prior_t, task.true_weights, task.human_transitions)


def fit_one(cfg: Table1Config, method: str, param: str, task, rated, policy_demos, key, progress=True):
    """Fit one method; returns ``(metrics row, curve rows, restart rows)``."""
    t0 = time.perf_counter()
    restarts: list[dict] = []
    if method in ("gerel", "gerel-minus"):
        gcfg = replace(cfg.gerel, freeze_belief=method == "gerel-minus")
        res = fit_gerel(task.mdp, rated, belief_space(task, param), gcfg, key=key, progress=progress)
        w, t = res.mu, res.transitions
        iters, ws, ts = res.curve()
        iterations = res.run.iterations
        if method == "gerel":
            chosen = int(res.run.ids[res.best])
            for rid, (mu_r, t_r) in res.restart_estimates().items():
                m = _metrics(task, mu_r, t_r)
                elbo = res.run.dropped[rid][1] if rid in res.run.dropped else res.elbo[list(res.run.ids).index(rid)]
                restarts.append(
                    {
                        "restart": rid,
                        "elbo": float(elbo),
                        "chosen": rid == chosen,
                        "screened_out": rid in res.run.dropped,
                        **m,
                    }
                )
    elif method == "serd":
        res = fit_serd(task.mdp, rated, belief_space(task, param), cfg.serd, key=key, progress=progress)
        w, t = res.weights, res.transitions
        iters, ws, ts = res.curve()
        iterations = res.run.iterations
    elif method == "maxent-irl":
        res = fit_maxent_irl(task.mdp, policy_demos, cfg.maxent, key=key, progress=progress)
        w, t = res.weights, np.asarray(task.mdp.transitions)
        iters, ws = res.curve()
        ts = np.broadcast_to(t, (len(iters),) + t.shape)
        iterations = res.run.iterations
    else:
        raise ValueError(f"unknown method {method!r}: use one of {METHODS}")
    seconds = time.perf_counter() - t0
    row = {
        **_metrics(task, w, t),
        "iterations": int(iterations),
        "seconds": seconds,
        "w": [float(x) for x in np.asarray(w)],
    }
    curve = [{"iteration": int(i), **_metrics(task, wi, ti)} for i, wi, ti in zip(iters, ws, ts)]
    return row, curve, restarts


def _jobs(cfg: Table1Config):
    """``(sweep, setting, seed, n_demos, method, param)`` for every fit."""
    for setting in cfg.settings:
        for seed in range(cfg.seeds):
            for method in METHODS:
                params = cfg.belief_params if method in ("gerel", "serd") else ("-",)
                for param in params:
                    yield "main", setting, seed, cfg.demos, method, param
    for setting in cfg.settings:
        for seed in range(cfg.demo_count_seeds):
            for n in cfg.demo_counts:
                for method in METHODS:
                    yield "demos", setting, seed, n, method, "tied" if method in ("gerel", "serd") else "-"


def job_keys(cfg: Table1Config) -> list[str]:
    """The keys of the jobs that fit something (a data-efficiency job on the main sweep's data reads its record)."""
    keys = [_key(*job) for job in _jobs(cfg)]
    return [k for k in keys if not _same_data(cfg, k)]


def run(
    cfg: Table1Config,
    out: Path,
    *,
    fresh: bool = False,
    progress: bool = True,
    shard=None,
    assemble_only: bool = False,
    only: str | None = None,
) -> dict | None:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    ``shard=(i, n)`` runs only the ``i``-th of ``n`` interleaved slices of the
    (setting, seed) groups, so ``n`` processes can share one run folder; a final call
    without ``shard`` assembles the outputs (and runs whatever is still missing).
    ``assemble_only`` writes the outputs from the finished jobs and runs nothing. ``only``
    runs the one job of that key (its record's ``command`` names it), writes no outputs and
    returns ``{"job": its record}``.
    """
    out = Path(out)
    jobs = list(_jobs(cfg))
    everything = [_key(*job) for job in jobs]
    if only is not None:
        if only not in everything:
            raise ValueError(f"table1 has no job {only!r}: its jobs are named like {everything[0]}")
        if _same_data(cfg, only):
            raise ValueError(f"{only} reads the record of {_main_of(only)}: run that job")
        jobs = [job for job in jobs if _key(*job) == only]
    folder = RunFolder(out, cfg, fresh=fresh and shard is None)
    rerun = registry.command("table1", cfg, out)
    if shard is not None:
        i, n_shards = shard
        groups = sorted({(j[0], j[1], j[2]) for j in jobs})
        mine = {g for k, g in enumerate(groups) if k % n_shards == i}
        jobs = [j for j in jobs if (j[0], j[1], j[2]) in mine]
    data_cache: dict = {}
    records = []
    for sweep, setting, seed, n, method, param in tqdm(jobs, desc="table1", disable=not progress or assemble_only):
        key = _key(sweep, setting, seed, n, method, param)
        rec = folder.done(key)
        if rec is None and _same_data(cfg, key):
            same = folder.done(_main_of(key))  # the main sweep already fitted these data
            rec = None if same is None else {**same, "sweep": "demos"}
        if rec is None and assemble_only:
            continue
        if rec is None:
            dkey = (setting, seed)
            if dkey not in data_cache:
                data_cache.clear()
                data_cache[dkey] = make_data(cfg, setting, seed, max(cfg.demos, *cfg.demo_counts))
            task, rated, policy_demos, k_fit = data_cache[dkey]
            row, curve, restarts = fit_one(
                cfg,
                method,
                param if param != "-" else cfg.belief_params[0],
                task,
                rated.take(n),
                policy_demos.take(n),
                k_fit,
                progress,
            )
            rec = {
                "sweep": sweep,
                "setting": setting,
                "seed": seed,
                "n_demos": n,
                "method": method,
                "param": param,
                "corners": "/".join(CORNERS[c] for c in task.corners),
                "row": row,
                "curve": curve,
                "restarts": restarts,
                "command": f"{rerun} --job {key}",
            }
            folder.save(key, rec)
        records.append(rec)
    if shard is not None:
        return None
    expected = [k for k in everything if not (_same_data(cfg, k) and folder.done(k) is None)]
    folder.write_progress("table1", expected, rerun)
    if only is not None:
        return {"job": records[0]}
    if not records:
        raise RuntimeError(f"{out} has no finished jobs to assemble")
    summary = write_outputs(cfg, out, records)
    summary["missing_jobs"] = len(jobs) - len(records)
    return summary


def _key(sweep, setting, seed, n, method, param) -> str:
    return f"{sweep}/{setting}/s{seed}/n{n}/{method}/{param}"


def _main_of(key: str) -> str:
    return "main" + key[len("demos") :]


def _same_data(cfg: Table1Config, key: str) -> bool:
    """Whether a data-efficiency job fits the same data as a main-sweep job (and reads that job's record)."""
    sweep, _, seed, n = key.split("/")[:4]
    return sweep == "demos" and int(n[1:]) == cfg.demos and int(seed[1:]) < cfg.seeds


def _expand(records, cfg):
    """Rows per belief parameterisation (belief-free methods repeat under each)."""
    for rec in records:
        params = cfg.belief_params if rec["param"] == "-" else (rec["param"],)
        for p in params:
            yield p, rec


def write_outputs(cfg: Table1Config, out: Path, records: list[dict]) -> dict:
    main = [r for r in records if r["sweep"] == "main"]
    rows, curve_rows, restart_rows, demo_rows = [], [], [], []
    for p, rec in _expand(main, cfg):
        base = {"setting": rec["setting"], "belief_param": p, "method": rec["method"], "seed": rec["seed"]}
        r = dict(rec["row"])
        r["w"] = " ".join(f"{x:.4g}" for x in r["w"])
        rows.append({**base, **r, "corners": rec["corners"], "n_demos": rec["n_demos"]})
        curve_rows += [{**base, **c} for c in rec["curve"]]
        restart_rows += [{**base, **x} for x in rec["restarts"]]
    for p, rec in _expand([r for r in records if r["sweep"] == "demos"], cfg):
        if p != "tied":
            continue
        demo_rows.append(
            {
                "setting": rec["setting"],
                "method": rec["method"],
                "seed": rec["seed"],
                "n_demos": rec["n_demos"],
                **{k: v for k, v in rec["row"].items() if k != "w"},
            }
        )
    write_csv(out / "results.csv", rows, RESULT_COLUMNS)
    write_csv(out / "curves.csv", curve_rows, ["setting", "belief_param", "method", "seed", "iteration"])
    write_csv(out / "restarts.csv", restart_rows, ["setting", "belief_param", "method", "seed", "restart"])
    write_csv(out / "demo_counts.csv", demo_rows, ["setting", "method", "seed", "n_demos"])
    summary = summarise(cfg, rows, restart_rows, demo_rows)
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    atomic_write(out / "table.md", summary["table_md"])
    tasks = {s: make_grid(cfg.size, s, seed=0) for s in cfg.settings}
    priors = {(s, p): prior_metrics(tasks[s], p) for s in cfg.settings for p in cfg.belief_params}
    render_figures(cfg, out, rows, curve_rows, demo_rows, tasks, priors)
    return summary
