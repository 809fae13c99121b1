"""The coffee study on the command line: ``mindgap reproduce coffee`` and ``mindgap gerel --domain coffee``.

``mindgap gerel --domain coffee`` fits one simulated participant (``--robot``,
``--seed``), or every person of a ratings file (``--ratings``; an optional
``participant`` column, optional ``robot``, ``q1``, ``q2`` columns), each on their own
normalised ratings, after the study's sanity check.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import jax
import numpy as np

from .. import rng
from .._io import atomic_write
from ..algorithms.gerel import GeReLConfig
from ..data.demos import RatedDemonstrations
from ..envs.coffee import ACTIONS, N_STATES, ROBOTS, make_coffee
from ..envs.coffee_demos import SANITY
from ..experiments import coffee
from ..experiments._runfolder import write_csv
from ..feedback.ratings_file import ParticipantRatings, read_participant_ratings, write_participant_ratings
from ..teachers.participants import POPULATIONS, QUESTIONS, recruit
from .reproduce import finish


def reproduce(args, shard) -> int:
    """``mindgap reproduce coffee [--fast] [--participants N] ...``."""
    if args.seeds is not None:
        raise ValueError("--seeds belongs to table1; the coffee study takes --participants")
    cfg = coffee.preset("fast" if args.fast else "full")
    if args.participants is not None:
        cfg = replace(cfg, participants=args.participants)
    out = args.out or Path("runs") / ("coffee" + ("-fast" if args.fast else ""))
    only = getattr(args, "job", None)
    summary = coffee.run(
        cfg, out, fresh=args.fresh, progress=not args.quiet, shard=shard, assemble_only=args.assemble, only=only
    )
    return finish(summary, out, args, "ratings, demonstrations and figures", unit="fits")


def _simulated_person(args, study) -> tuple[ParticipantRatings, dict]:
    robot = args.robot or "mobile"
    key = jax.random.fold_in(rng.key(args.seed), ROBOTS.index(robot) + 1)
    attentive = replace(POPULATIONS[robot], inattentive=0.0)  # a person with a belief to recover
    responses = recruit(key, attentive, make_coffee(robot), study.demos, 1, sanity=study.sanity)
    p = responses[-1].participant
    rated = RatedDemonstrations(study.demos, responses[-1].ratings)
    person = ParticipantRatings(p.pid, rated, study.names, {"q1": p.q1, "q2": p.q2}, robot)
    truth = {"spill_true": p.spill, "wet_weight_true": p.wet_weight, "coffee_weight_true": p.coffee_weight}
    return person, truth


def _screen(person: ParticipantRatings) -> str:
    r = np.asarray(person.rated.ratings)
    if np.ptp(r) == 0:
        return "every demonstration got the same rating"
    if SANITY in person.demos:
        i = person.demos.index(SANITY)
        if r[i] > np.delete(r, i).min():
            return "failed the sanity check (the random demonstration is not their lowest rating)"
    return ""


def gerel(args) -> int:
    """``mindgap gerel --domain coffee [--robot R] [--ratings FILE] [--param factored|per-sa|full] [--minus]``."""
    param = args.param or "factored"
    if param not in coffee.PARAMS:
        raise ValueError(f"--param {param} does not apply to coffee: use one of {', '.join(coffee.PARAMS)}")
    if args.robot is not None and args.robot not in ROBOTS:
        raise ValueError(f"unknown robot {args.robot!r}: use one of {', '.join(ROBOTS)}")
    method = "gerel-minus" if args.minus else "gerel"
    cfg = GeReLConfig(estimator=args.estimator)
    if args.max_iter:
        cfg = replace(cfg, max_iter=args.max_iter)
    if args.restarts:
        cfg = replace(cfg, restarts=args.restarts, keep=min(cfg.keep, args.restarts))
    study = coffee.make_study()
    truths: dict[str, dict] = {}
    if args.ratings is None:
        person, truth = _simulated_person(args, study)
        people = [person]
        truths[person.participant] = truth
        print(
            f"simulated {person.robot} participant {person.participant}: Q1={person.answers['q1']} "
            f"Q2={person.answers['q2']}, believes spill {truth['spill_true']:.2f}, "
            f"weights (coffee {truth['coffee_weight_true']:.2f}, wet {truth['wet_weight_true']:.2f})"
        )
        if args.save_ratings:
            write_participant_ratings(args.save_ratings, people, QUESTIONS)
    else:
        people = read_participant_ratings(
            args.ratings,
            n_states=N_STATES,
            n_actions=len(ACTIONS),
            gamma_max=cfg.gamma_max,
            catalogue=study.catalogue,
            questions=QUESTIONS,
            robots=ROBOTS,
        )
    rows = []
    for person in people:
        robot = person.robot or args.robot
        why = "" if args.no_filter else _screen(person)
        if why:
            print(f"participant {person.participant}: dropped, {why} (--no-filter keeps them)")
            continue
        if robot is None and method == "gerel-minus":
            raise ValueError(
                f"participant {person.participant}: GeReL⁻ needs the robot's true dynamics; "
                "add a robot column or pass --robot"
            )
        fitted = coffee.fit_person(
            make_coffee(robot or "mobile"),
            person.rated,
            method,
            param,
            cfg,
            key=coffee.fit_key(args.seed, person.participant),
            normalise=args.normalise,
            progress=not args.quiet,
        )
        truth = truths.get(person.participant, {})
        rows.append(
            {
                "participant": person.participant,
                "robot": robot or "",
                "method": method,
                "spill_learned": fitted["spill_learned"],
                "wet_weight_learned": fitted["wet_weight_learned"],
                "spill_true": truth.get("spill_true", ""),
                "wet_weight_true": truth.get("wet_weight_true", ""),
                "belief_param": param if method == "gerel" else "-",
                "coffee_weight_learned": fitted["coffee_weight_learned"],
                "coffee_weight_true": truth.get("coffee_weight_true", ""),
                **{q: person.answers.get(q, "") for q in QUESTIONS},
                "elbo": fitted["elbo"],
                "iterations": fitted["iterations"],
            }
        )
        print(
            f"{person.participant} ({robot or 'robot unknown'}): spill {fitted['spill_learned']:.2f}, "
            f"weights coffee {fitted['coffee_weight_learned']:.2f}, wet {fitted['wet_weight_learned']:.2f}"
        )
    if not rows:
        raise ValueError("no participant left to fit (all dropped by the sanity check; --no-filter keeps them)")
    if args.out:
        write_csv(args.out / "results.csv", rows, coffee.RESULT_COLUMNS)
        report = {"domain": "coffee", "method": method, "param": param, "normalise": args.normalise, "fits": rows}
        atomic_write(args.out / "posterior.json", json.dumps(report, indent=2))
        print(f"results saved to {args.out}/results.csv and posterior.json")
    return 0
