"""Answers out of the store, in the files the fitting commands read.

* ``ratings.csv`` (protocol ``rating``) — the ratings-file format of
  :mod:`mindgap.feedback.ratings_file`: one row per demonstrated step,
  ``participant[,robot],demo,step,state,action,rating[,q…]``, read by
  ``mindgap gerel --domain coffee|grid7 --ratings FILE``. grid7 demonstrations are
  labelled ``participant/item`` so that pooled reading keeps people apart.
* ``preferences.json`` (``preference``, ``expectation``) — see :mod:`.prefs_file`, read
  by ``mindgap pebble|drlhp --preferences FILE``.
* ``answers.csv`` / ``answers.json`` — every answer of every protocol with its time,
  condition and sanity verdict, and the questionnaire (the raw record).

By default only participants who finished the study are exported to the fitting
files (``partial=True`` takes everyone); the raw record always has everyone. A participant
who declined (possibly after answering, from another tab) has withdrawn: their answers and
questionnaire are in no export.
"""

from __future__ import annotations

import csv
import io
import json

from .prefs_file import ANSWERS, preferences_document
from .store import LIVE_PREFIX, Store


def sanity_failures(items: dict[str, dict], answers: list) -> dict[str, list[str]]:
    """``{participant label: [failed sanity item ids]}`` from the items' rules and the answers."""
    by_person: dict[str, dict[str, float | str]] = {}
    for a in answers:
        by_person.setdefault(a["participant"], {})[a["item_id"]] = a["choice"] if a["choice"] else a["value"]
    out: dict[str, list[str]] = {}
    for who, given in by_person.items():
        failed = []
        for item_id, item in items.items():
            rule = item.get("sanity")
            if not rule or item_id not in given:
                continue
            v = given[item_id]
            if rule["rule"] == "lowest":
                bad = any(float(x) < float(v) for k, x in given.items() if k != item_id and k in items)
            elif rule["rule"] == "max":
                bad = float(v) > rule["value"]
            elif rule["rule"] == "min":
                bad = float(v) < rule["value"]
            else:
                bad = v != rule["value"]
            if bad:
                failed.append(item_id)
        out[who] = failed
    return out


def _context(store: Store, partial: bool):
    study = store.study_json()
    items = {it["id"]: it for it in store.items()}
    people = {p["label"]: p for p in store.participants()}
    answers = [
        a
        for a in store.answers()
        if people[a["participant"]]["declined_at"] is None
        and (partial or people[a["participant"]]["completed_at"] is not None)
    ]
    return study, items, people, answers


def _questionnaire(store: Store) -> list:
    """The questionnaire answers of participants who did not decline."""
    declined = {p["id"] for p in store.participants() if p["declined_at"] is not None}
    return [row for row in store.questionnaire() if row["participant_id"] not in declined]


def ratings_csv(store: Store, partial: bool = False) -> str:
    """The ratings file of a rating study (see the module docstring)."""
    study, items, people, answers = _context(store, partial)
    if study["protocol"] != "rating":
        raise ValueError(f"study {study['name']!r} is a {study['protocol']} study: export preferences, not ratings")
    if study["domain"]["name"] == "driving":
        return _driving_ratings(study, items, answers)
    coffee = study["domain"]["name"] == "coffee"
    questions = [q["id"] for q in study["questionnaire"]]
    by_pid: dict[int, dict[str, int]] = {}
    for row in _questionnaire(store):
        by_pid.setdefault(row["participant_id"], {})[row["question"]] = row["value"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["participant"] + (["robot"] if coffee else []) + ["demo", "step", "state", "action", "rating"] + questions
    )
    for a in answers:
        item = items[a["item_id"]]
        p = people[a["participant"]]
        label = item["id"] if coffee else f"{p['label']}/{item['id']}"
        q = by_pid.get(p["id"], {})
        d = item["data"]
        for t, (s, act) in enumerate(zip(d["states"][:-1], d["actions"])):
            head = [p["label"]] + ([p["condition"]] if coffee else [])
            w.writerow(head + [label, t, s, act, f"{a['value']:g}"] + [q.get(x, "") for x in questions])
    return buf.getvalue()


def _driving_ratings(study: dict, items: dict, answers: list) -> str:
    """A driving testing phase's ratings (§4.4.2, Table 5): one row per rated rollout, with the method,
    seed and episode it shows and whether the rater failed a sanity item (``mindgap study driving``)."""
    failed = sanity_failures(items, answers)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["participant", "item", "method", "seed", "episode", "rating", "sanity_failed"])
    for a in answers:
        d = items[a["item_id"]]["data"]
        bad = bool(failed.get(a["participant"]))
        w.writerow([a["participant"], a["item_id"], d.get("method", ""), d.get("seed", ""), d.get("episode", "")]
                   + [f"{a['value']:g}", bad])  # fmt: skip
    return buf.getvalue()


def preferences_json(store: Store, partial: bool = False) -> str:
    """The preferences file of a comparison study (fixed items and live queries alike)."""
    study, items, people, answers = _context(store, partial)
    if study["protocol"] == "rating":
        raise ValueError(f"study {study['name']!r} is a rating study: export ratings, not preferences")
    records = []
    for a in answers:
        if study["items"].get("source") == "live" and a["item_id"] in items:
            continue  # a live study's fixed items (driving's bias question and sanity item) are no training data
        data = _item_data(store, items, a["item_id"])
        if data is None:
            continue
        records.append(
            {
                "participant": a["participant"],
                "item": a["item_id"],
                "answer": a["choice"],
                "label": ANSWERS[a["choice"]],
                "seconds": None if a["seconds"] is None else round(a["seconds"], 3),
                "a": data["a"],
                "b": data["b"],
                **({"truth": data["truth"]} if "truth" in data else {}),
            }
        )
    keep = ("name", "world", "belief", "env", "sleet", "traffic", "brake_first", "brake_last")
    domain = {k: study["domain"][k] for k in keep if k in study["domain"]}
    return json.dumps(preferences_document(study["protocol"], domain, records))


def _item_data(store: Store, items: dict, item_id: str) -> dict | None:
    if item_id in items:
        return items[item_id]["data"]
    if item_id.startswith(LIVE_PREFIX):
        q = store.live_query(int(item_id[len(LIVE_PREFIX) :]))
        return None if q is None else json.loads(q["data"])
    return None


def answers_table(store: Store) -> list[dict]:
    """Every answer with participant, condition, value, choice, seconds, sanity verdict, time."""
    study, items, people, answers = _context(store, True)
    failed = sanity_failures(items, answers)
    return [
        {
            "participant": a["participant"],
            "condition": a["condition"],
            "item": a["item_id"],
            "value": a["value"],
            "choice": a["choice"] or "",
            "seconds": None if a["seconds"] is None else round(a["seconds"], 3),
            "sanity_item": bool(items.get(a["item_id"], {}).get("sanity")),
            "sanity_failed": a["item_id"] in failed.get(a["participant"], []),
            "submission_id": a["submission_id"],
            "created_at": a["created_at"],
        }
        for a in answers
    ]


def answers_csv(store: Store) -> str:
    rows = answers_table(store)
    buf = io.StringIO()
    cols = [
        "participant",
        "condition",
        "item",
        "value",
        "choice",
        "seconds",
        "sanity_item",
        "sanity_failed",
        "submission_id",
        "created_at",
    ]
    w = csv.DictWriter(buf, cols, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def answers_json(store: Store) -> str:
    """The raw record: study, participants (stage times, questionnaire), answers."""
    study = store.study_json()
    quest: dict[int, dict] = {}
    for row in _questionnaire(store):
        quest.setdefault(row["participant_id"], {})[row["question"]] = row["value"]
    people = [
        {
            "participant": p["label"],
            "condition": p["condition"],
            "completed": p["completed_at"] is not None,
            "declined": p["declined_at"] is not None,
            "questionnaire": quest.get(p["id"], {}),
            **{f"{s}_at": p[f"{s}_at"] for s in ("consent", "instructions", "questionnaire", "completed")},
        }
        for p in store.participants()
    ]
    # each fixed item's id, kind, sanity rule and the plain facts of its data (which side is the
    # truth, the rated method, ...): enough to read the answers without the store
    items = [
        {"id": it["id"], "kind": it["kind"], "sanity": it.get("sanity")}
        | {k: v for k, v in it["data"].items() if isinstance(v, str | int | float | bool)}
        for it in store.items()
    ]
    return json.dumps(
        {"study": study, "participants": people, "items": items, "answers": answers_table(store)}, indent=1
    )


def export_all(store: Store, out, partial: bool = False) -> list:
    """Write the fitting file of the study's protocol and the raw record into folder ``out``."""
    from pathlib import Path

    from .._io import atomic_write

    out = Path(out)
    written = []
    study = store.study_json()
    if study["protocol"] == "rating":
        atomic_write(out / "ratings.csv", ratings_csv(store, partial))
        written.append(out / "ratings.csv")
    else:
        atomic_write(out / "preferences.json", preferences_json(store, partial))
        written.append(out / "preferences.json")
    atomic_write(out / "answers.csv", answers_csv(store))
    atomic_write(out / "answers.json", answers_json(store))
    return written + [out / "answers.csv", out / "answers.json"]
