"""Ratings files: the CSV format every rating-based learner reads.

One row per demonstrated step, long format::

    demo,step,state,action,rating
    0,0,12,3,6.5
    0,1,13,0,6.5
    1,0,40,2,1.0

- ``demo``: any label identifying the demonstration (rows of one demonstration need
  not be adjacent);
- ``step``: position within the demonstration (integers, unique per demonstration;
  rows are ordered by it);
- ``state``, ``action``: integer ids of the domain (grid: ``row * size + col``;
  actions 0 Up, 1 Down, 2 Left, 3 Right);
- ``rating``: the person's rating of the whole demonstration, in ``[0, γ_max]``,
  repeated on each of its rows.

:func:`read_ratings` ignores any other column and pools all rows. For studies with
many people, :func:`read_participant_ratings` reads the same format with optional
columns:

- ``participant``: who rated (every row needs one when the column exists; without it
  the file is one person);
- ``robot``: the condition the person saw (e.g. ``mobile``/``humanoid``), one per person;
- questionnaire answers such as ``q1``, ``q2``: Likert integers, one per person
  (repeated on that person's rows; an empty cell is an unanswered question).

With a catalogue of the study's demonstrations it also checks that every ``demo`` is
one of them and that its steps are the ones shown.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._io import atomic_write
from ..data.demos import RatedDemonstrations, make_demonstrations
from ._errors import RatingsFileError

REQUIRED = ("demo", "step", "state", "action", "rating")


def read_ratings(path, *, n_states: int, n_actions: int, gamma_max: float = 10.0) -> RatedDemonstrations:
    """Read and validate a ratings file.

    Raises:
        RatingsFileError: a missing file or column, a non-numeric value, a rating out
            of range or differing within a demonstration, a repeated step, or an
            unknown state or action id — the message names the line.
    """
    path = Path(path)
    demos: dict[str, dict] = {}
    for line, row, step, state, action, rating in _rows(path, n_states, n_actions, gamma_max):
        _add_step(path, line, demos, row["demo"], step, state, action, rating)
    if not demos:
        raise RatingsFileError(f"{path}: no rows")
    return _pack(demos, n_states, n_actions)


def _rows(path: Path, n_states: int, n_actions: int, gamma_max: float, check=None):
    """Yield ``(line, row, step, state, action, rating)`` for each validated row.

    ``check(line, row)`` runs first on every row (to name problems of extra columns
    before the generic ones).
    """
    if not path.is_file():
        raise RatingsFileError(f"ratings file {path} does not exist")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            raise RatingsFileError(f"{path}: missing column(s) {', '.join(missing)}; need {', '.join(REQUIRED)}")
        for line, raw in enumerate(reader, start=2):
            row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
            if check is not None:
                check(line, row)
            try:
                step, state, action = int(row["step"]), int(row["state"]), int(row["action"])
                rating = float(row["rating"])
            except ValueError:
                raise RatingsFileError(
                    f"{path}, line {line}: step, state and action must be integers and rating a number"
                ) from None
            if not np.isfinite(rating) or not 0.0 <= rating <= gamma_max:
                raise RatingsFileError(f"{path}, line {line}: rating {rating} is outside [0, {gamma_max}]")
            if not 0 <= state < n_states:
                raise RatingsFileError(f"{path}, line {line}: unknown state id {state} (valid: 0..{n_states - 1})")
            if not 0 <= action < n_actions:
                raise RatingsFileError(f"{path}, line {line}: unknown action id {action} (valid: 0..{n_actions - 1})")
            yield line, row, step, state, action, rating


def _add_step(path, line, demos: dict, label: str, step: int, state: int, action: int, rating: float, who: str = ""):
    d = demos.setdefault(label, {"rating": rating, "steps": {}, "line": line})
    if d["rating"] != rating:
        raise RatingsFileError(
            f"{path}, line {line}: {who}demonstration {label!r} has two ratings ({d['rating']} and {rating})"
        )
    if step in d["steps"]:
        raise RatingsFileError(f"{path}, line {line}: {who}demonstration {label!r} repeats step {step}")
    d["steps"][step] = (state, action)


def _pack(demos: dict, n_states: int, n_actions: int) -> RatedDemonstrations:
    length = max(len(d["steps"]) for d in demos.values())
    n = len(demos)
    states = np.zeros((n, length), np.int32)
    actions = np.zeros((n, length), np.int32)
    mask = np.zeros((n, length), bool)
    ratings = np.zeros(n, np.float32)
    for i, d in enumerate(demos.values()):
        steps = [d["steps"][k] for k in sorted(d["steps"])]
        states[i, : len(steps)] = [s for s, _ in steps]
        actions[i, : len(steps)] = [a for _, a in steps]
        mask[i, : len(steps)] = True
        ratings[i] = d["rating"]
    demo_batch = make_demonstrations(states, actions, mask, n_states=n_states, n_actions=n_actions)
    return RatedDemonstrations(demo_batch, jnp.asarray(ratings))


def write_ratings(path, rated: RatedDemonstrations) -> None:
    """Write rated demonstrations in the format :func:`read_ratings` reads (atomically)."""
    states = np.asarray(rated.demos.states)
    actions = np.asarray(rated.demos.actions)
    mask = np.asarray(rated.demos.mask)
    ratings = np.asarray(rated.ratings)
    lines = [",".join(REQUIRED)]
    for i in range(len(ratings)):
        for t in np.flatnonzero(mask[i]):
            lines.append(f"{i},{t},{states[i, t]},{actions[i, t]},{ratings[i]:.4f}")
    atomic_write(Path(path), "\n".join(lines) + "\n")


@dataclass(frozen=True)
class ParticipantRatings:
    """One person's rated demonstrations, with their questionnaire answers and condition.

    Attributes:
        participant: the person's id (the file's name stem when it has no participant column).
        rated: their demonstrations (in order of first appearance) and ratings.
        demos: the ``demo`` label of each demonstration.
        answers: questionnaire answers given, e.g. ``{"q1": 4, "q2": 2}`` (unanswered left out).
        robot: the ``robot`` column's value, or ``None``.
    """

    participant: str
    rated: RatedDemonstrations
    demos: tuple[str, ...]
    answers: dict[str, int] = field(default_factory=dict)
    robot: str | None = None


def read_participant_ratings(
    path,
    *,
    n_states: int,
    n_actions: int,
    gamma_max: float = 10.0,
    catalogue: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] | None = None,
    questions: tuple[str, ...] = ("q1", "q2"),
    likert: tuple[int, int] = (1, 5),
    robots: tuple[str, ...] | None = None,
) -> list[ParticipantRatings]:
    """Read a ratings file of one or many people (an optional ``participant`` column).

    Args:
        path: the CSV file.
        n_states, n_actions: the domain's sizes.
        gamma_max: top of the rating scale.
        catalogue: ``{demo label: (states, actions)}`` of the study's demonstrations;
            when given, every row's ``demo`` must be one of them, with exactly its steps.
        questions: optional questionnaire columns, Likert integers in ``likert``.
        robots: allowed values of an optional ``robot`` column.

    Returns:
        One :class:`ParticipantRatings` per person, in order of first appearance.

    Raises:
        RatingsFileError: everything :func:`read_ratings` refuses, and a row without a
            participant, an unknown demonstration or one whose steps differ from the
            study's, a questionnaire answer that is not a Likert integer in range or
            differs between a person's rows, an unknown or changing robot.
    """
    path = Path(path)
    people: dict[str, dict] = {}

    def check(line, row):
        if "participant" in row and not row["participant"]:
            raise RatingsFileError(f"{path}, line {line}: missing participant (the participant column is empty)")
        if catalogue is not None and row["demo"] not in catalogue:
            known = ", ".join(catalogue)
            raise RatingsFileError(f"{path}, line {line}: unknown demonstration {row['demo']!r} (the study's: {known})")
        who = row.get("participant") or path.stem
        person = people.setdefault(who, {"demos": {}, "answers": {}, "robot": None})
        for q in questions:
            if q in row and row[q]:
                try:
                    value = int(row[q])
                except ValueError:
                    value = None
                if value is None or not likert[0] <= value <= likert[1]:
                    raise RatingsFileError(
                        f"{path}, line {line}: answer {q}={row[q]!r} is not an integer in {likert[0]}..{likert[1]}"
                    )
                if person["answers"].setdefault(q, value) != value:
                    raise RatingsFileError(
                        f"{path}, line {line}: participant {who!r} has two answers to {q} "
                        f"({person['answers'][q]} and {value})"
                    )
        if row.get("robot"):
            robot = row["robot"]
            if robots is not None and robot not in robots:
                raise RatingsFileError(f"{path}, line {line}: unknown robot {robot!r} (use one of {', '.join(robots)})")
            if person["robot"] is not None and person["robot"] != robot:
                raise RatingsFileError(
                    f"{path}, line {line}: participant {who!r} saw two robots ({person['robot']} and {robot})"
                )
            person["robot"] = robot

    for line, row, step, state, action, rating in _rows(path, n_states, n_actions, gamma_max, check):
        who = row.get("participant") or path.stem
        _add_step(path, line, people[who]["demos"], row["demo"], step, state, action, rating, f"participant {who!r}: ")
    if not people:
        raise RatingsFileError(f"{path}: no rows")
    out = []
    for who, person in people.items():
        if catalogue is not None:
            for label, d in person["demos"].items():
                _check_steps(path, who, label, d, catalogue[label])
        rated = _pack(person["demos"], n_states, n_actions)
        out.append(ParticipantRatings(who, rated, tuple(person["demos"]), dict(person["answers"]), person["robot"]))
    return out


def _check_steps(path, who: str, label: str, d: dict, shown) -> None:
    steps = [d["steps"][k] for k in sorted(d["steps"])]
    expected = list(zip(*shown))
    if len(steps) != len(expected):
        raise RatingsFileError(
            f"{path}: participant {who!r}, demonstration {label!r} has {len(steps)} steps; the study's has {len(expected)}"
        )
    for k, (got, want) in enumerate(zip(steps, expected)):
        if tuple(got) != tuple(want):
            raise RatingsFileError(
                f"{path}: participant {who!r}, demonstration {label!r}, step {k}: (state, action) {tuple(got)} "
                f"differs from the study's {tuple(want)}"
            )


def write_participant_ratings(path, people: list[ParticipantRatings], questions: tuple[str, ...] = ("q1", "q2")):
    """Write many people's ratings in the format :func:`read_participant_ratings` reads (atomically).

    Columns ``participant``, then ``robot`` when any person has one, the required
    columns, then the questionnaire columns any person answered.
    """
    has_robot = any(p.robot is not None for p in people)
    asked = [q for q in questions if any(q in p.answers for p in people)]
    cols = ["participant"] + (["robot"] if has_robot else []) + list(REQUIRED) + asked
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(cols)
    for p in people:
        states = np.asarray(p.rated.demos.states)
        actions = np.asarray(p.rated.demos.actions)
        mask = np.asarray(p.rated.demos.mask)
        ratings = np.asarray(p.rated.ratings)
        for i, label in enumerate(p.demos):
            for t in np.flatnonzero(mask[i]):
                cells = [p.participant] + ([p.robot or ""] if has_robot else [])
                cells += [label, int(t), int(states[i, t]), int(actions[i, t]), f"{float(ratings[i]):.6g}"]
                writer.writerow(cells + [p.answers.get(q, "") for q in asked])
    atomic_write(Path(path), buf.getvalue())
