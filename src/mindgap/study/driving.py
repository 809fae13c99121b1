"""The driving study of §4.4.2 with real people: its domain, its fixed items, and what its answers give.

The study had two phases (§4.4.2, Figs. 32–33, Table 5):

* **training** — the importance of four factors on a 5-point scale (Fig. 32: the study's
  questionnaire, ids :data:`~mindgap.envs.driving.FEATURES`), then the *bias-validation
  question*: "on a sleety day, how will the car brake?", two segments from the same start in
  which the car brakes behind the braking front car, once with dry grip and once with the
  sleet's grip (the item ``bias``; 12 of 14 people chose the effective braking), a *sanity
  item* showing a collision (``sanity``, rule ``answer``: the car that brakes in time), and
  the expectation queries that the running learner (``mindgap eps --teacher study:STORE``)
  chooses actively;
* **testing** — new participants rate 1–10 rollouts of the learned policies (protocol
  ``rating``, ``items: {source: file, path: rollouts.json}``, :mod:`mindgap.data.rollouts_file`).

The domain (``domain: {name: driving, sleet: 1.0, traffic: 0, brake_first: 1, brake_last: 4}``)
is :func:`mindgap.envs.driving.make_world` with those arguments; each segment or rollout is
shown as highway-env's animation (:func:`mindgap.envs.driving.highway.segment_frames`).

The two fixed segments are played by the JAX world's :func:`~mindgap.envs.driving.advance`
with the braking factor fixed at the grip's mean (dry road: 0.95; sleet s: the Beta's mean),
not drawn, so the question shows the typical outcome of each grip and is the same for every
participant. The front car starts braking at the first decision; the car brakes (SLOWER)
from the decision after its brake lights show (or, in the sanity item's collision, keeps its
speed).

:func:`training_summary` and :func:`testing_summary` read the exports back: the valid
participants' mean importance answers (``mindgap reproduce driving --importance A,B,C,D``),
the bias count, and each method's mean rating (Table 5's first row).
"""

from __future__ import annotations

import csv
import json
import statistics
from pathlib import Path

import numpy as np

DEFAULTS = {"sleet": 1.0, "traffic": 0, "brake_first": 1, "brake_last": 4}
"""The driving domain's keys and their defaults (:func:`~mindgap.envs.driving.make_world`'s)."""
FIXED = ("bias", "sanity")
"""The fixed items a training-phase study may show before the live queries (``items.fixed``)."""
BIAS_QUESTION = "It is a sleety day. The front car brakes, and so does your car. How will your car brake?"


def check_domain(domain: dict, protocol: str, items: dict, fail) -> None:
    """Check a driving study's ``domain`` and ``items`` keys; ``fail(msg)`` raises the one-line error."""
    unknown = sorted(set(domain) - set(DEFAULTS) - {"name"})
    if unknown:
        fail(f"domain.{unknown[0]} is not a key of the driving domain (keys: {', '.join(DEFAULTS)})")
    sleet = domain.get("sleet", DEFAULTS["sleet"])
    if isinstance(sleet, bool) or not isinstance(sleet, int | float) or not 0.0 <= sleet <= 1.0:
        fail(f"domain.sleet must be a number from 0 (dry) to 1 (full sleet), got {sleet!r}")
    for key in ("traffic", "brake_first", "brake_last"):
        v = domain.get(key, DEFAULTS[key])
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            fail(f"domain.{key} must be a whole number of at least 0, got {v!r}")
    try:
        driving_world(domain)
    except ValueError as e:
        fail(f"domain: {e}")
    if items["source"] == "live":
        if protocol == "rating":
            fail("live driving studies compare segments: protocol preference or expectation")
        fixed = items.get("fixed", [])
        if not isinstance(fixed, list) or any(f not in FIXED for f in fixed) or len(set(fixed)) != len(fixed):
            fail(f"items.fixed must list some of {', '.join(FIXED)} (each once)")
        seg = items.get("segment", 6)
        if isinstance(seg, bool) or not isinstance(seg, int) or not 2 <= seg <= 15:
            fail(f"items.segment must be a whole number of steps from 2 to 15, got {seg!r}")
    elif protocol != "rating":
        fail("driving studies from a rollouts file rate whole episodes: protocol rating")


def world_args(domain: dict) -> dict:
    return {k: domain.get(k, d) for k, d in DEFAULTS.items()}


def driving_world(domain: dict):
    """The driving world a study shows (:func:`~mindgap.envs.driving.make_world` with the domain's keys)."""
    from ..envs.driving import make_world

    a = world_args(domain)
    return make_world(
        sleet=float(a["sleet"]), traffic=a["traffic"], brake_first=a["brake_first"], brake_last=a["brake_last"]
    )


def scripted_segment(params, mu: float, brake: bool, length: int) -> dict:
    """One segment of ``length`` decisions from the start: the front car brakes at the first decision;
    the car brakes from the decision after (``brake``) or keeps its speed; every braking step at factor ``mu``.

    Returns JSON-ready ``obs``, ``act`` ([L, 1]), ``next_obs``, ``mask`` (a collision ends the segment's
    real steps; later steps repeat the final state).
    """
    import jax
    import jax.numpy as jnp

    from ..envs.driving import advance, observe, reset
    from ..envs.driving.params import IDLE, SLOWER

    global _advance
    if _advance is None:
        _advance = jax.jit(advance)
    state = reset(jax.random.key(0), params)
    obs, act, nxt, mask = [], [], [], []
    for t in range(length):
        a = SLOWER if brake and bool(state.braking) else IDLE
        live = not bool(state.done)
        new = _advance(state, jnp.int32(a), jnp.float32(mu), jnp.asarray(t == 0), params) if live else state
        obs.append(np.asarray(observe(state, params)))
        nxt.append(np.asarray(observe(new, params)))
        act.append([float(a)])
        mask.append(live)
        state = new
    return {
        "obs": np.round(np.stack(obs), 5).tolist(),
        "act": act,
        "next_obs": np.round(np.stack(nxt), 5).tolist(),
        "mask": mask,
    }


_advance = None


def fixed_items(study) -> list:
    """The training phase's fixed items named in ``items.fixed`` (module docstring), sides drawn by ``items.seed``."""
    from ..envs.driving.sleet import factor_mean_std
    from .items import Item

    world = driving_world(study.domain)
    p = world.params
    length = int(study.items.get("segment", 6))
    rng = np.random.default_rng(int(study.items.get("seed", 0)))
    dry_mu = float(factor_mean_std(0.0, p.grip)[0])
    sleet_mu = float(factor_mean_std(p.sleet, p.grip)[0])
    out = []
    for name in study.items.get("fixed", []):
        if name == "bias":
            good, other = scripted_segment(p, dry_mu, True, length), scripted_segment(p, sleet_mu, True, length)
            key, question = "effective", BIAS_QUESTION
        else:
            good, other = scripted_segment(p, dry_mu, True, length), scripted_segment(p, dry_mu, False, length)
            key, question = "safe", ""
        side = "a" if rng.random() < 0.5 else "b"
        a, b = (good, other) if side == "a" else (other, good)
        data = {"a": a, "b": b, key: side}
        if question:
            data["question"] = question
        sanity = {"rule": "answer", "value": side} if name == "sanity" else None
        out.append(Item(name, "pair", data, sanity))
    return out


def rollout_items(study) -> list:
    """Rating items from a rollouts file (``items.path``, relative to the study file)."""
    from ..data.rollouts_file import RolloutsFileError, read_rollouts
    from .config import StudyFileError
    from .items import Item

    path = Path(study.items["path"])
    if not path.is_absolute():
        path = Path(study.base_dir) / path
    try:
        doc = read_rollouts(path)
    except RolloutsFileError as e:
        raise StudyFileError(f"items.path: {e}") from None
    dom = doc["domain"]
    if dom.get("name") != "driving" or world_args(dom) != world_args(study.domain):
        raise StudyFileError(
            f"items.path: {path} holds rollouts of {json.dumps(dom)}, the study shows {json.dumps(study.domain)}"
        )
    items = []
    for r in doc["records"]:
        obs = r["obs"]
        seg = {"obs": obs[:-1], "act": r["act"], "next_obs": obs[1:], "mask": r["mask"]}
        meta = {k: r[k] for k in ("method", "seed", "episode") if k in r}
        sanity = {"rule": r["sanity"], "value": None} if r.get("sanity") else None
        items.append(Item(r["item"], "demo", {"segment": seg, **meta}, sanity))
    return items


def frames(study, seg: dict, length: int | None = None) -> list[np.ndarray]:
    """The animation frames of one segment of the study's world, as a participant sees them.

    highway-env draws the segment (:func:`~mindgap.envs.driving.highway.segment_frames`) with the
    camera of :func:`mindgap.plotting.driving.view_config` (cars 70 px long, the road section from
    behind the ego to past the front car); :func:`mindgap.plotting.driving.decorate` crops it to
    the road, draws the sleet and lights each car's brake lights in the decisions where it slows.
    ``length`` pads the clip with its last frame to that many frames (both clips of a pair are
    padded to the longer one's :func:`clip_length`, so that they loop in step).
    """
    from ..envs.driving.highway import segment_frames
    from ..envs.driving.params import SUBSTEPS
    from ..plotting.driving import decorate, view_config

    a = world_args(study.domain)
    window = (a["brake_first"], a["brake_last"])
    config = view_config(int(driving_world(study.domain).params.lanes))
    raw = segment_frames(
        seg["obs"], seg["act"], seg["mask"], sleet=a["sleet"], traffic=a["traffic"], brake_window=window, config=config
    )
    per_decision = braking(seg)
    # frame 0 is the start; frame 1 + 15 t + k is integration step k of decision t
    flags = np.concatenate([np.zeros((1, 2), bool), np.repeat(per_decision, SUBSTEPS, 0)])[: len(raw)]
    out = decorate(raw, flags, a["sleet"])
    if length is not None and length > len(out):
        out += [out[-1]] * (length - len(out))
    return out


def clip_length(seg: dict) -> int:
    """The number of frames highway-env draws for a segment: its start and 15 a real step."""
    from ..envs.driving.params import SUBSTEPS

    return 1 + SUBSTEPS * int(np.asarray(seg["mask"], bool).sum())


def braking(seg: dict) -> np.ndarray:
    """[n, 2] bool: whether the ego and the front car slow down in each of a segment's n real steps."""
    from ..envs.driving.world import EGO_OBS, SPEED_SCALE

    mask = np.asarray(seg["mask"], bool)
    obs, nxt = np.asarray(seg["obs"], float)[mask], np.asarray(seg["next_obs"], float)[mask]
    speeds = lambda o: o[:, [2, EGO_OBS + 2]] * SPEED_SCALE  # noqa: E731  the ego's and the front car's [m/s]
    return (speeds(obs) - speeds(nxt)) > BRAKE_LIGHT_DROP


BRAKE_LIGHT_DROP = 0.05
"""Speed lost over a decision [m/s] above which a car's brake lights are on in that decision."""


# ---------------------------------------------------------------------------------------
# the exports read back


def training_summary(answers_json) -> dict:
    """What the training phase gives, from its ``answers.json`` (``mindgap study export``).

    Valid participants finished the study and did not fail a sanity item (§4.4.2: "one failed the
    sanity check"). Returns the number of valid participants, their mean answer to each importance
    question (in :data:`~mindgap.envs.driving.FEATURES` order) and the reward weights it gives
    (:func:`~mindgap.envs.driving.importance_weights`), and how many chose the effective braking in
    the bias-validation question (12 of 14 in the study).
    """
    from ..envs.driving import FEATURES, importance_weights

    doc = json.loads(Path(answers_json).read_text())
    failed = {a["participant"] for a in doc["answers"] if a["sanity_failed"]}
    valid = [p for p in doc["participants"] if p["completed"] and p["participant"] not in failed]
    missing = [f for f in FEATURES if any(f not in p["questionnaire"] for p in valid)]
    if missing:
        raise ValueError(
            f"{answers_json}: the questionnaire has no answers to {', '.join(missing)} (ids: {', '.join(FEATURES)})"
        )
    if not valid:
        raise ValueError(f"{answers_json}: no participant finished the study and passed the sanity item")
    means = [statistics.fmean(p["questionnaire"][f] for p in valid) for f in FEATURES]
    names = {p["participant"] for p in valid}
    items = {it["id"]: it for it in doc.get("items", [])}
    bias = [a for a in doc["answers"] if a["item"] == "bias" and a["participant"] in names]
    effective = None
    if bias:
        side = (items.get("bias") or {}).get("effective")
        effective = sum(a["choice"] == side for a in bias) if side else None
    return {
        "valid": len(valid),
        "participants": len(doc["participants"]),
        "importance": dict(zip(FEATURES, means)),
        "weights": dict(zip(FEATURES, (float(w) for w in importance_weights(means)))),
        "bias_answered": len(bias),
        "bias_effective": effective,
        "reproduce": "mindgap reproduce driving --importance " + ",".join(f"{m:.3g}" for m in means),
    }


def testing_summary(ratings_csv) -> dict:
    """Table 5's average ratings from the testing phase's ``ratings.csv`` (``mindgap study export``).

    Only valid raters count: those who failed no sanity item (the collision rated lowest).
    Returns, per method, the mean and standard deviation over every valid rating of its
    rollouts, and the number of ratings and raters.
    """
    rows = list(csv.DictReader(Path(ratings_csv).open()))
    need = {"participant", "method", "rating", "sanity_failed"}
    if not rows or not need <= set(rows[0]):
        raise ValueError(f"{ratings_csv}: not a driving ratings file (need the columns {', '.join(sorted(need))})")
    bad = {r["participant"] for r in rows if r["sanity_failed"] == "True"}
    valid = [r for r in rows if r["participant"] not in bad]
    methods = {}
    for m in dict.fromkeys(r["method"] for r in valid):
        if m == "sanity":
            continue
        v = [float(r["rating"]) for r in valid if r["method"] == m]
        methods[m] = {"rating_mean": statistics.fmean(v), "rating_std": statistics.pstdev(v), "ratings": len(v)}
    return {
        "raters": len({r["participant"] for r in valid}),
        "dropped": sorted(bad),
        "methods": methods,
    }
