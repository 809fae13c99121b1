"""Experiment ``coffee``: the coffee-robot user study of §2.3.2 with simulated participants.

For each robot type (mobile, humanoid) participants are recruited from the type's
:class:`~mindgap.teachers.participants.Population` until ``participants`` pass the
study's filters (sanity check, response time). Each answers Q1/Q2 and rates the nine
demonstrations of :mod:`mindgap.envs.coffee_demos`. Every valid participant is then
fitted on their own, min-max normalised ratings (§2.3.2) by GeReL — with the belief
parameterised per factor (a Beta over the spill probability) and per state-action
pair (the dissertation's Dirichlets) — and by GeReL⁻ (belief frozen to the robot's
true dynamics). Outputs: the Table 2 analogue (questionnaire means with p-values),
the Fig. 12 analogue (learned weights and spill probabilities per method and robot),
``results.csv`` with one row per participant, method and belief parameterisation.

Every fit is a checkpointed job: a killed run resumes where it stopped.
"""

from __future__ import annotations

import json
import time
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from .. import rng
from .._io import atomic_write
from ..algorithms.gerel import GeReLConfig, fit_gerel
from ..data.demos import Demonstrations, RatedDemonstrations
from ..envs.coffee import ACTIONS, N_STATES, ROBOTS, event_probability, factored_layout, make_coffee
from ..envs.coffee_demos import SANITY, Trace, study_traces, to_demonstrations, trace_text
from ..envs.tabular import TabularMDP
from ..feedback.normalise import normalise_ratings
from ..feedback.ratings_file import ParticipantRatings, write_participant_ratings
from ..models.belief import BeliefSpace, factored, per_state_action
from ..teachers.participants import POPULATIONS, QUESTIONS, Population, Response, recruit
from . import registry
from ._runfolder import RunFolder, write_csv
from .coffee_report import write_outputs

METHODS = ("gerel", "gerel-minus")
PARAMS = ("factored", "per-sa", "full")
RESULT_COLUMNS = [
    "participant",
    "robot",
    "method",
    "spill_learned",
    "wet_weight_learned",
    "spill_true",
    "wet_weight_true",
]


@dataclass(frozen=True)
class CoffeeConfig:
    """What ``mindgap reproduce coffee`` runs."""

    participants: int = 12
    """Valid participants per robot type (§2.3.2: 12 of 20 recruits were valid)."""
    populations: tuple[Population, ...] = (POPULATIONS["mobile"], POPULATIONS["humanoid"])
    """One population per robot type."""
    belief_params: tuple[str, ...] = ("factored", "per-sa")
    """GeReL's belief parameterisations (GeReL⁻ needs none)."""
    normalise: str = "minmax"
    """Per-participant rating normalisation before fitting (``minmax`` or ``none``)."""
    fit_sanity: bool = True
    """Fit the sanity-check demonstration's rating too (it is a rating like the others)."""
    min_minutes: float = 3.0
    """Responses faster than this are dropped."""
    max_recruits: int = 500
    """Give up when this many recruits per robot do not yield enough valid ones."""
    sanity_seed: int = 0
    """Seed of the sanity-check demonstration's random actions."""
    seed: int = 0
    """Seed of the recruitment, the ratings and the fits."""
    gerel: GeReLConfig = field(default_factory=GeReLConfig)


def preset(name: str) -> CoffeeConfig:
    """``full`` (the real numbers) or ``fast`` (a minute; used by the tests)."""
    if name == "full":
        return CoffeeConfig()
    if name == "fast":
        # one compiled program per method (no screening), GeReL with the factored belief only
        return CoffeeConfig(
            participants=2,
            belief_params=("factored",),
            gerel=GeReLConfig(restarts=2, keep=2, anneal_iter=50, max_iter=100),
        )
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


class Study(NamedTuple):
    """The demonstrations every participant sees."""

    traces: list[Trace]
    demos: Demonstrations
    names: tuple[str, ...]
    sanity: int

    @property
    def catalogue(self) -> dict[str, tuple[tuple[int, ...], tuple[int, ...]]]:
        """``{demo label: (states, actions)}`` for :func:`read_participant_ratings`."""
        return {t.name: (t.states[:-1], t.actions) for t in self.traces}


def make_study(sanity_seed: int = 0) -> Study:
    traces = study_traces(sanity_seed)
    names = tuple(t.name for t in traces)
    return Study(traces, to_demonstrations(traces), names, names.index(SANITY))


def belief_space(mdp: TabularMDP, param: str) -> BeliefSpace:
    """GeReL's belief for the coffee world: ``factored`` (Beta over the spill probability), ``per-sa`` or ``full``."""
    if param == "factored":
        return factored(*factored_layout(("spill",)))
    if param in ("per-sa", "full"):
        return per_state_action(mdp.transitions, full=param == "full")
    raise ValueError(f"unknown belief parameterisation {param!r} for coffee: use one of {', '.join(PARAMS)}")


def fit_person(
    mdp: TabularMDP,
    rated: RatedDemonstrations,
    method: str,
    param: str,
    gcfg: GeReLConfig,
    *,
    key,
    normalise: str = "minmax",
    progress: bool = False,
) -> dict:
    """Fit one person's ratings with GeReL or GeReL⁻ (§2.3.2); returns the learned quantities.

    Args:
        mdp: the true world of the robot the person saw.
        rated: their demonstrations and raw ratings.
        method: ``gerel`` or ``gerel-minus``.
        param: GeReL's belief parameterisation (ignored by GeReL⁻).
        gcfg: GeReL's hyperparameters (``freeze_belief`` is set from ``method``).
        key: PRNG key.
        normalise: rating normalisation (:func:`~mindgap.feedback.normalise.normalise_ratings`).

    Returns:
        ``spill_learned`` (believed spill probability under the posterior mean; the
        truth for GeReL⁻), ``coffee_weight_learned``, ``wet_weight_learned``, ELBO,
        iterations and seconds.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    t0 = time.perf_counter()
    ratings = normalise_ratings(rated.ratings, normalise, gcfg.gamma_max)
    norm = RatedDemonstrations(rated.demos, jnp.asarray(ratings, jnp.float32))
    cfg = replace(gcfg, freeze_belief=method == "gerel-minus")
    res = fit_gerel(mdp, norm, belief_space(mdp, param), cfg, key=key, progress=progress)
    return {
        "spill_learned": event_probability(res.transitions, "spill"),
        "coffee_weight_learned": float(res.mu[0]),
        "wet_weight_learned": float(res.mu[1]),
        "elbo": float(res.elbo[res.best]),
        "iterations": int(res.run.iterations),
        "seconds": time.perf_counter() - t0,
    }


def fit_key(seed: int, participant: str):
    """The fitting key of one participant (shared by their methods: common random numbers)."""
    return jax.random.fold_in(rng.key(seed), zlib.crc32(participant.encode()) & 0x7FFFFFFF)


def recruit_all(cfg: CoffeeConfig, study: Study) -> dict[str, list[Response]]:
    """Every recruit's response per robot type (deterministic in ``cfg.seed``)."""
    out = {}
    for pop in cfg.populations:
        key = jax.random.fold_in(rng.key(cfg.seed), ROBOTS.index(pop.robot) + 1)
        out[pop.robot] = recruit(
            key,
            pop,
            make_coffee(pop.robot),
            study.demos,
            cfg.participants,
            sanity=study.sanity,
            min_minutes=cfg.min_minutes,
            max_recruits=cfg.max_recruits,
        )
    return out


def _fitted_demos(cfg: CoffeeConfig, study: Study, ratings) -> RatedDemonstrations:
    keep = np.array([cfg.fit_sanity or i != study.sanity for i in range(len(study.names))])
    d = study.demos
    demos = Demonstrations(d.states[keep], d.actions[keep], d.mask[keep])
    return RatedDemonstrations(demos, jnp.asarray(np.asarray(ratings)[keep], jnp.float32))


def _jobs(cfg: CoffeeConfig, responses):
    for pop in cfg.populations:
        for r in responses[pop.robot]:
            if not r.valid:
                continue
            for method in METHODS:
                for param in cfg.belief_params if method == "gerel" else ("-",):
                    yield pop.robot, r, method, param


def _key(robot, resp, method, param) -> str:
    return f"{robot}/{resp.participant.pid}/{method}/{param}"


def job_keys(cfg: CoffeeConfig) -> list[str]:
    """The keys of the study's fits (one per valid simulated participant, method and parameterisation)."""
    return [_key(*job) for job in _jobs(cfg, recruit_all(cfg, make_study(cfg.sanity_seed)))]


def run(
    cfg: CoffeeConfig,
    out: Path,
    *,
    fresh: bool = False,
    progress: bool = True,
    shard=None,
    assemble_only: bool = False,
    only: str | None = None,
) -> dict | None:
    """Run (or resume) the study in ``out``; write CSV/JSON/PNG; return the summary.

    ``shard=(i, n)`` fits only every ``n``-th participant starting at ``i`` (processes
    sharing ``out``); a final call without it assembles the outputs. ``only`` fits the one
    job of that key (its record's ``command`` names it), writes no outputs and returns
    ``{"job": its record}``.
    """
    if cfg.participants < 2:
        raise ValueError("participants must be at least 2 per robot type (the two-sample test needs them)")
    if sorted(p.robot for p in cfg.populations) != sorted(ROBOTS):
        raise ValueError(f"need one population per robot type ({', '.join(ROBOTS)})")
    for p in cfg.belief_params:
        if p not in PARAMS:
            raise ValueError(f"unknown belief parameterisation {p!r}: use one of {', '.join(PARAMS)}")
    out = Path(out)
    folder = RunFolder(out, cfg, fresh=fresh and shard is None)
    study = make_study(cfg.sanity_seed)
    responses = recruit_all(cfg, study)
    jobs = list(_jobs(cfg, responses))
    everything = [_key(*job) for job in jobs]
    if only is not None:
        if only not in everything:
            raise ValueError(f"coffee has no job {only!r}: its jobs are named like {everything[0]}")
        jobs = [job for job in jobs if _key(*job) == only]
    rerun = registry.command("coffee", cfg, out)
    if shard is not None:
        i, n_shards = shard
        people = sorted({j[1].participant.pid for j in jobs})
        mine = {p for k, p in enumerate(people) if k % n_shards == i}
        jobs = [j for j in jobs if j[1].participant.pid in mine]
    mdps = {robot: make_coffee(robot) for robot in ROBOTS}
    records = []
    for robot, resp, method, param in tqdm(jobs, desc="coffee", disable=not progress or assemble_only):
        person = resp.participant
        key = _key(robot, resp, method, param)
        rec = folder.done(key)
        if rec is None and assemble_only:
            continue
        if rec is None:
            rated = _fitted_demos(cfg, study, resp.ratings)
            fitted = fit_person(
                mdps[robot],
                rated,
                method,
                param if param != "-" else "factored",
                cfg.gerel,
                key=fit_key(cfg.seed, person.pid),
                normalise=cfg.normalise,
                progress=progress,
            )
            rec = {"participant": person.pid, "robot": robot, "method": method, "belief_param": param, **fitted}
            rec["command"] = f"{rerun} --job {key}"
            folder.save(key, rec)
        records.append(rec)
    if shard is not None:
        return None
    folder.write_progress("coffee", everything, rerun)
    if only is not None:
        return {"job": records[0]}
    if not records:
        raise RuntimeError(f"{out} has no finished fits to assemble")
    rows = result_rows(cfg, responses, records)
    write_csv(out / "results.csv", rows, RESULT_COLUMNS)
    write_study_files(cfg, out, study, responses)
    summary = write_outputs(cfg, out, study, responses, rows)
    summary["missing_jobs"] = len(jobs) - len(records)
    return summary


def result_rows(cfg: CoffeeConfig, responses, records) -> list[dict]:
    """``results.csv`` rows: the fits joined with each participant's truth and answers."""
    people = {r.participant.pid: r.participant for rs in responses.values() for r in rs}
    rows = []
    for rec in records:
        p = people[rec["participant"]]
        rows.append(
            {
                "participant": p.pid,
                "robot": p.robot,
                "method": rec["method"],
                "spill_learned": rec["spill_learned"],
                "wet_weight_learned": rec["wet_weight_learned"],
                "spill_true": p.spill,
                "wet_weight_true": p.wet_weight,
                "belief_param": rec["belief_param"],
                "coffee_weight_learned": rec["coffee_weight_learned"],
                "coffee_weight_true": p.coffee_weight,
                "q1": p.q1,
                "q2": p.q2,
                "attentive": p.attentive,
                "elbo": rec["elbo"],
                "iterations": rec["iterations"],
                "seconds": rec["seconds"],
            }
        )
    return rows


def write_study_files(cfg: CoffeeConfig, out: Path, study: Study, responses) -> None:
    """``participants.csv`` (every recruit), ``ratings.csv`` (valid ones, the ratings-file format), ``demos.txt``."""
    rows = []
    people = []
    for robot, rs in responses.items():
        for r in rs:
            p = r.participant
            rows.append(
                {
                    "participant": p.pid,
                    "robot": robot,
                    "valid": r.valid,
                    "dropped": r.dropped,
                    "attentive": p.attentive,
                    "q1": p.q1,
                    "q2": p.q2,
                    "spill_true": p.spill,
                    "coffee_weight_true": p.coffee_weight,
                    "wet_weight_true": p.wet_weight,
                    "slider_low": p.slider[0],
                    "slider_high": p.slider[1],
                    "minutes": p.minutes,
                    **{f"rating:{n}": float(x) for n, x in zip(study.names, r.ratings)},
                }
            )
            if r.valid:
                rated = RatedDemonstrations(study.demos, jnp.asarray(r.ratings, jnp.float32))
                answers = {"q1": p.q1, "q2": p.q2}
                people.append(ParticipantRatings(p.pid, rated, study.names, answers, robot))
    write_csv(out / "participants.csv", rows, ["participant", "robot", "valid", "dropped"])
    write_participant_ratings(out / "ratings.csv", people, QUESTIONS)
    text = [f"The robot's actions: {', '.join(ACTIONS)}; {N_STATES} states.", ""]
    text += [trace_text(t) + "\n" for t in study.traces]
    atomic_write(out / "demos.txt", "\n".join(text))
    atomic_write(out / "study.json", json.dumps({"demos": list(study.names), "sanity": study.names[study.sanity]}))
