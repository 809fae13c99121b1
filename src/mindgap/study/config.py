"""Study files: the YAML a researcher writes to declare a study (dissertation Figs. 9–11, 32–33).

A study file names the protocol, the domain and where its items come from, the texts
a participant reads, the Likert questionnaire, the sanity-check items, the minimum
time per item and the number of participant links to create::

    name: coffee-rating
    protocol: rating                 # rating | preference | expectation
    participants: 24
    min_seconds: 5
    domain: {name: coffee, robots: [mobile, humanoid]}
    items: {source: coffee-demos}
    consent: "..."
    instructions: "..."
    questionnaire:
      - {id: q1, text: "...", scale: [1, 5], anchors: [not at all, very much]}
    sanity:
      - {item: sanity-random, rule: lowest}

Parsing is hand-written (not a schema library) so that every problem is reported as
one sentence naming the key, e.g. ``study.yaml: questionnaire[0].scale must be two
integers like [1, 5]``. See ``docs/study.md`` and the example files in
``mindgap/study/examples``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from pathlib import Path

PROTOCOLS = ("rating", "preference", "expectation")
DOMAINS = ("coffee", "grid7", "terrain", "gym", "driving")
SOURCES = {
    "coffee": ("coffee-demos",),
    "grid7": ("random",),
    "terrain": ("random-pairs", "belief-pairs", "file", "live"),
    "gym": ("live",),
    "driving": ("live", "file"),
}
RULES = ("lowest", "max", "min", "answer")
_NAME = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")


class StudyFileError(ValueError):
    """A study file that cannot be run; the message names the file and the key."""


@dataclasses.dataclass(frozen=True)
class Question:
    """One Likert item of the questionnaire."""

    id: str
    text: str
    scale: tuple[int, int] = (1, 5)
    anchors: tuple[str, str] = ("", "")


@dataclasses.dataclass(frozen=True)
class Sanity:
    """A sanity check on one item.

    ``lowest``: the item's rating is the participant's lowest (ties allowed);
    ``max`` / ``min``: the rating is at most / at least ``value``;
    ``answer``: a comparison answered ``value`` (``a`` or ``b``).
    """

    item: str
    rule: str
    value: float | str | None = None


@dataclasses.dataclass(frozen=True)
class Study:
    """A parsed study file. ``domain`` and ``items`` stay plain dicts (their keys depend on the domain)."""

    name: str
    protocol: str
    domain: dict
    items: dict
    title: str = ""
    participants: int = 10
    min_seconds: float = 0.0
    shuffle: bool = True
    consent: str = ""
    instructions: str = ""
    question: str = ""
    questionnaire: tuple[Question, ...] = ()
    sanity: tuple[Sanity, ...] = ()
    rating_scale: tuple[float, float, float] = (0.0, 10.0, 1.0)
    base_dir: str = "."
    waiting: str = ""
    min_live_answers: int = 0

    @property
    def comparison(self) -> bool:
        return self.protocol in ("preference", "expectation")

    @property
    def live(self) -> bool:
        return self.items.get("source") == "live"

    @property
    def waiting_text(self) -> str:
        """What the waiting page of a live study says: the study's ``waiting`` text or its domain's."""
        return self.waiting or WAITING.get(self.domain["name"], WAITING["terrain"])

    def conditions(self) -> tuple[str, ...]:
        """The between-participant conditions (coffee: the robot types); one empty condition otherwise."""
        if self.domain["name"] == "coffee":
            return tuple(self.domain.get("robots", ("mobile",)))
        return ("",)

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    def fingerprint(self) -> str:
        """Hash of everything that defines the study (not its base folder).

        Keys added since stores were first written count only when set, so a store made
        before them still opens with its study file.
        """
        d = dataclasses.asdict(self)
        d.pop("base_dir")
        for key in _ADDED:
            if d[key] == _ADDED[key]:
                d.pop(key)
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


DEFAULT_QUESTION = {
    "rating": "How well did the robot do? Rate the demonstration from 0 (worst) to 10 (best).",
    "preference": "Which of the two behaviours do you prefer?",
    "expectation": "Which of the two behaviours did you expect the robot to show?",
}

WAITING = {
    "terrain": "The robot is still learning; a new pair of its behaviours will appear here in a moment.",
    "gym": "The robot is still learning; a new pair of clips of it will appear here in a moment.",
    "driving": "The next pair of clips of your car will appear here in a moment.",
}
"""The waiting page's default text in a live study, by domain (a study file's ``waiting`` replaces it)."""
_ADDED = {"waiting": "", "min_live_answers": 0}


def load_study(path) -> Study:
    """Read and check a study file (YAML).

    Raises:
        StudyFileError: a missing file, invalid YAML, or a missing, unknown or
            ill-typed key — the message names it.
    """
    import yaml

    path = Path(path)
    if not path.is_file():
        raise StudyFileError(f"study file {path} does not exist")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        raise StudyFileError(f"{path}: not valid YAML ({e})") from None
    return parse_study(raw, source=str(path), base_dir=str(path.parent.resolve()))


def parse_study(raw, source: str = "study", base_dir: str = ".") -> Study:
    """Build a :class:`Study` from the parsed YAML mapping ``raw``."""

    def fail(msg: str):
        raise StudyFileError(f"{source}: {msg}")

    if not isinstance(raw, dict):
        fail("the file must be a mapping of keys (name, protocol, domain, items, ...)")
    known = {f.name for f in dataclasses.fields(Study)} - {"base_dir", "rating_scale"} | {"rating"}
    unknown = sorted(set(raw) - known)
    if unknown:
        fail(f"unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    for key in ("name", "protocol", "domain", "items"):
        if key not in raw:
            fail(f"missing key {key!r}")
    name = raw["name"]
    if not isinstance(name, str) or not _NAME.match(name):
        fail(f"name {name!r} must be lower-case letters, digits, '-' or '_' (at most 64)")
    protocol = raw["protocol"]
    if protocol not in PROTOCOLS:
        fail(f"protocol {protocol!r} is not one of {', '.join(PROTOCOLS)}")
    domain = raw["domain"]
    if isinstance(domain, str):
        domain = {"name": domain}
    if not isinstance(domain, dict) or domain.get("name") not in DOMAINS:
        fail(f"domain.name must be one of {', '.join(DOMAINS)}")
    domain = dict(domain)
    items = raw["items"]
    if not isinstance(items, dict) or "source" not in items:
        fail("items must be a mapping with a source, e.g. {source: coffee-demos}")
    items = dict(items)
    if items["source"] not in SOURCES[domain["name"]]:
        fail(
            f"items.source {items['source']!r} does not fit domain {domain['name']}: use {', '.join(SOURCES[domain['name']])}"
        )
    if domain["name"] == "terrain":
        if protocol == "rating":
            fail("terrain studies compare segments: protocol preference or expectation")
        if not isinstance(domain.get("world"), str):
            fail("domain.world must name a terrain world (nav1, nav2, d1–d4) or a world file")
    elif domain["name"] == "gym":
        if protocol == "rating":
            fail("gym studies compare segments: protocol preference or expectation")
        if not isinstance(domain.get("env"), str) or not domain["env"].startswith("gym:"):
            fail("domain.env must name a gymnasium env as gym:ID[,key=value...], e.g. gym:mindgap/NoisyHopper-v0")
    elif domain["name"] == "driving":  # §4.4.2: live queries (training phase) or rollouts to rate (testing)
        from .driving import check_domain

        check_domain(domain, protocol, items, fail)
    elif protocol != "rating":
        fail(f"domain {domain['name']} shows demonstrations to rate: protocol rating")
    if domain["name"] == "coffee":
        robots = domain.get("robots", ["mobile"])
        if isinstance(robots, str):
            robots = [robots]
        if not robots or any(r not in ("mobile", "humanoid") for r in robots):
            fail("domain.robots must list mobile and/or humanoid")
        domain["robots"] = list(robots)
    if items["source"] == "file":
        if not isinstance(items.get("path"), str):
            what = "a rollouts file" if domain["name"] == "driving" else "a preferences file"
            fail(f"items.path must name {what} for source: file")

    participants = _int(raw.get("participants", 10), "participants", fail, lo=0)
    min_seconds = _num(raw.get("min_seconds", 0), "min_seconds", fail)
    if min_seconds < 0:
        fail("min_seconds must be at least 0")
    questionnaire = tuple(_question(q, i, fail) for i, q in enumerate(raw.get("questionnaire") or []))
    ids = [q.id for q in questionnaire]
    if len(set(ids)) != len(ids):
        fail("questionnaire ids must be unique")
    sanity = tuple(_sanity(s, i, protocol, fail) for i, s in enumerate(raw.get("sanity") or []))
    scale = (0.0, 10.0, 1.0)
    if "rating" in raw:
        r = raw["rating"]
        if protocol != "rating" or not isinstance(r, dict):
            fail("rating: {min, max, step} belongs to protocol rating")
        scale = tuple(_num(r.get(k, d), f"rating.{k}", fail) for k, d in zip(("min", "max", "step"), scale))
        if not scale[0] < scale[1] or scale[2] <= 0:
            fail("rating needs min < max and step > 0")
    texts = {}
    min_live = _int(raw.get("min_live_answers", 0), "min_live_answers", fail, lo=0)
    if min_live and items["source"] != "live":
        fail("min_live_answers belongs to a live study (items: {source: live})")
    for key in ("title", "consent", "instructions", "question", "waiting"):
        v = raw.get(key, "")
        if not isinstance(v, str):
            fail(f"{key} must be text")
        texts[key] = v.strip()
    if texts["waiting"] and items["source"] != "live":
        fail("waiting belongs to a live study (items: {source: live}): it is the text shown while no query waits")
    shuffle = raw.get("shuffle", True)
    if not isinstance(shuffle, bool):
        fail("shuffle must be true or false")
    return Study(
        name=name,
        protocol=protocol,
        domain=domain,
        items=items,
        title=texts["title"] or name,
        participants=participants,
        min_seconds=float(min_seconds),
        shuffle=shuffle,
        consent=texts["consent"],
        instructions=texts["instructions"],
        question=texts["question"] or DEFAULT_QUESTION[protocol],
        questionnaire=questionnaire,
        sanity=sanity,
        rating_scale=scale,
        base_dir=base_dir,
        waiting=texts["waiting"],
        min_live_answers=min_live,
    )


def _int(v, key, fail, lo=None) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        fail(f"{key} must be an integer, got {v!r}")
    if lo is not None and v < lo:
        fail(f"{key} must be at least {lo}")
    return v


def _num(v, key, fail) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        fail(f"{key} must be a number, got {v!r}")
    return float(v)


def _question(q, i, fail) -> Question:
    where = f"questionnaire[{i}]"
    if not isinstance(q, dict) or not isinstance(q.get("id"), str) or not isinstance(q.get("text"), str):
        fail(f"{where} needs an id and a text")
    if not _NAME.match(q["id"]):
        fail(f"{where}.id {q['id']!r} must be lower-case letters, digits, '-' or '_'")
    scale = q.get("scale", [1, 5])
    if (
        not isinstance(scale, list | tuple)
        or len(scale) != 2
        or not all(isinstance(x, int) and not isinstance(x, bool) for x in scale)
        or scale[0] >= scale[1]
        or scale[1] - scale[0] > 20
    ):
        fail(f"{where}.scale must be two integers like [1, 5]")
    anchors = q.get("anchors", ["", ""])
    if not isinstance(anchors, list | tuple) or len(anchors) != 2 or not all(isinstance(a, str) for a in anchors):
        fail(f"{where}.anchors must be two texts (lowest, highest)")
    return Question(q["id"], q["text"].strip(), (scale[0], scale[1]), (anchors[0], anchors[1]))


def _sanity(s, i, protocol, fail) -> Sanity:
    where = f"sanity[{i}]"
    if not isinstance(s, dict) or not isinstance(s.get("item"), str) or s.get("rule") not in RULES:
        fail(f"{where} needs an item and a rule ({', '.join(RULES)})")
    rule, value = s["rule"], s.get("value")
    if protocol == "rating":
        if rule == "answer":
            fail(f"{where}: rule answer is for comparisons; ratings use lowest, max or min")
        if rule in ("max", "min"):
            value = _num(value, f"{where}.value", fail)
    else:
        if rule != "answer" or value not in ("a", "b"):
            fail(f"{where}: comparisons use rule answer with value a or b")
    return Sanity(s["item"], rule, value)
