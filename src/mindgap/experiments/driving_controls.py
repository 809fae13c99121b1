"""The driving study's learner controls: one learner on a finished run's participants, answers changed.

The participants (their answers to Fig. 32, beliefs and π_H) are the costly part of
``mindgap reproduce driving``; a learner takes a few minutes. A control trains DRLHP or EPS
(the full preset's schedule and seeds) on the participants of a run folder, in a folder of its
own, with one thing changed, and measures the behaviours the experiment measures
(:func:`~.driving_measures.behaviour`; docs/experiments/driving.md, "Gates and controls"):

* ``coin``: every answer a fair coin (Bradley–Terry at β = 0) — what a learner that follows the
  answers must *not* do as it does on the participants' answers (K1);
* ``only=PID``: every query goes to that one participant (K3: a braker's answers, or those of a
  participant who knows about the sleet);
* ``exact=PID``: no query; u_H is that participant's own per-step score (EPS's exact surrogate),
  without learning noise (K2): log T_H + log π_H at the clip's states when the run's participants
  answer by ``expectation``, else log π_H there (a played-out clip's score is no sum over its own
  steps);
* ``answers_by``: how the participants judge a clip (:attr:`~.driving.DrivingConfig.answers_by`);
* ``road``: the sleet of the road the learner drives on; ``lam``: EPS's λ;
  ``survival_entropy``: :attr:`~mindgap.algorithms.sac.SACConfig.survival_entropy`; ``offset`` and
  ``absorbing``: :attr:`~mindgap.algorithms.eps_config.EPSConfig.offset` and ``.absorbing``;
  ``alpha``: DRLHP's SAC entropy coefficient fixed at another value (:attr:`~mindgap.algorithms.sac.SACConfig.alpha`),
  or ``"tuned"`` to a target entropy, instead of the presets' 1/s_H
  (:attr:`~mindgap.algorithms.eps_config.EPSConfig.drlhp_alpha`; EPS's is λ/s_H).

``mindgap design driving --run DIR --learner drlhp|eps [...]`` runs one and prints its record.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import jax
import jax.numpy as jnp

from ..algorithms import eps as eps_alg
from ..teachers.drivers import check_sleet_level
from ..teachers.expectation import ExpectationTeacher
from . import driving as dr
from . import prefbias_common as pc
from ._runfolder import RunFolder
from .driving_measures import learner_record
from .driving_probes import load_participants


@dataclasses.dataclass(frozen=True)
class Control:
    """One learner control (module docstring)."""

    method: str = "drlhp"
    coin: bool = False
    only: str | None = None
    exact: str | None = None
    road: float | None = None
    lam: float | None = None
    survival_entropy: str | None = None
    offset: str | None = None
    absorbing: str | None = None
    seeds: int | None = None
    answers_by: str | None = None
    alpha: float | str | None = None

    def __post_init__(self):
        if self.method not in ("drlhp", "eps"):
            raise ValueError(f"a control trains drlhp or eps, got {self.method!r}")
        if self.exact and (self.coin or self.only):
            raise ValueError("--exact asks no queries: it does not combine with --coin or --only")
        if self.road is not None:
            check_sleet_level(self.road)
        tuned = self.alpha == "tuned"
        if self.alpha is not None and (
            self.method != "drlhp" or not (tuned or isinstance(self.alpha, float) and self.alpha > 0)
        ):
            raise ValueError("--alpha sets DRLHP's entropy coefficient (a positive number or 'tuned'); EPS's is λ/s_H")

    @property
    def name(self) -> str:
        parts = [self.method]
        for field, value in (("coin", self.coin), ("only", self.only), ("exact", self.exact), ("road", self.road),
                             ("lam", self.lam), ("survival", self.survival_entropy), ("offset", self.offset),
                             ("absorbing", self.absorbing), ("seeds", self.seeds),
                             ("answers", self.answers_by), ("alpha", self.alpha)):  # fmt: skip
            if value not in (None, False):
                parts.append(
                    field if value is True else f"{field}-{value:g}" if isinstance(value, float) else f"{field}-{value}"
                )
        return "__".join(parts)


def configure(cfg: dr.DrivingConfig, c: Control) -> dr.DrivingConfig:
    """The run's configuration with the control's changes."""
    eps = cfg.eps
    if c.survival_entropy is not None:
        eps = dataclasses.replace(eps, sac=dataclasses.replace(eps.sac, survival_entropy=c.survival_entropy))
    if c.alpha is not None:
        fixed = None if c.alpha == "tuned" else c.alpha
        eps = dataclasses.replace(eps, drlhp_alpha="sac", sac=dataclasses.replace(eps.sac, alpha=fixed))
    if c.lam is not None:
        eps = dataclasses.replace(eps, lam=c.lam)
    if c.offset is not None:
        eps = dataclasses.replace(eps, offset=c.offset)
    if c.absorbing is not None:
        eps = dataclasses.replace(eps, absorbing=None if c.absorbing == "none" else c.absorbing)
    eps.check()
    out = dataclasses.replace(cfg, eps=eps)
    if c.road is not None:
        out = dataclasses.replace(out, sleet=c.road)
    if c.seeds is not None:
        out = dataclasses.replace(out, seeds=c.seeds)
    return out


def run_control(run: Path, c: Control, out: Path | None = None, progress: bool = True) -> dict:
    """Train the control's learner on ``run``'s participants in ``out`` (default ``run/controls/NAME``);
    return its record (:func:`~.driving_measures.learner_record`) with the control's settings. Resumes."""
    run = Path(run)
    people = load_participants(run, c.answers_by)
    cfg = configure(people.cfg, c)
    out = Path(out) if out is not None else run / "controls" / c.name
    done = out / "record.json"
    if done.is_file():
        return json.loads(done.read_text())
    pids = [d.pid for d in people.drivers]
    for pid in (c.only, c.exact):
        if pid is not None and pid not in pids:
            raise ValueError(f"no valid participant {pid!r} in {run} (valid: {', '.join(pids)})")
    for sub, name in (("jobs", "driving__people.json"), ("actors", "people.npz")):
        (out / sub).mkdir(parents=True, exist_ok=True)
        shutil.copy(run / sub / name, out / sub / name)
    folder = RunFolder(out, cfg)
    job = next(j for j in dr.jobs(cfg) if j.key == f"{dr.WORLD}/{c.method}")
    world = dr.world_of(cfg, people.people["engineered_weights"])
    learner = pc.coin_flips(job.cfg) if c.coin else job.cfg
    kw = dict(seeds=cfg.seeds, out=out / "train", progress=progress)
    if c.exact is not None:
        i = pids.index(c.exact)
        # a per-step score: log T_H + log π_H at the states (answers by expectation), log π_H there alone
        # otherwise — the rollout's score of a clip is not a sum over its own steps
        tcfg = dataclasses.replace(cfg.answer_cfg, use_belief=cfg.answers_by == "expectation")
        person = ExpectationTeacher(dr.belief_params(world, people.drivers[i]), people.actor(i), world.env, tcfg)
        res = eps_alg.train(world, dataclasses.replace(learner, surrogate="exact"), person, person_name=c.exact, **kw)
    else:
        crowd = dr.crowd_teacher(folder, cfg, world, people.people)
        if c.only is not None:
            i = pids.index(c.only)
            crowd = dataclasses.replace(
                crowd,
                beliefs=jax.tree.map(lambda a: a[i : i + 1], crowd.beliefs),
                policies=jax.tree.map(lambda a: a[i : i + 1], crowd.policies),
                attentive=jnp.ones((1,), bool),
            )
        res = eps_alg.train(world, learner, crowd, person_name=c.only or "participants", **kw)
    rec = learner_record(world, res["carry"].loop.sac.params.actor, res, cfg.rollouts)
    rec["control"] = dataclasses.asdict(c)
    rec["answers_by"] = cfg.answers_by
    from .._io import atomic_write

    atomic_write(done, json.dumps(rec))
    return rec


def report(rec: dict) -> str:
    """The control's behaviours, one line per measure with one value per seed."""
    c = rec["control"]
    what = ", ".join(f"{k}={v}" for k, v in c.items() if v not in (None, False) and k != "method")
    lines = [f"{c['method']} ({what or 'the run as it is'}; participants judge by {rec['answers_by']})"]
    for k, label in (
        ("return", "return under r_A"),
        ("collided", "collision rate"),
        ("changed", "episodes with a lane change"),
        ("first_change", "first lane change (decisions after the onset)"),
        ("braked_first", "braked before changing lane"),
        ("min_gap", "smallest gap in line with the front car [m]"),
    ):
        lines.append(f"  {label:48s} " + " ".join("   n/a" if x is None else f"{float(x):6.2f}" for x in rec[k]))
    braking = sum(1 for x in rec["braked_first"] if x is not None and x > 0.5)
    lines.append(f"  seeds braking first (in most episodes): {braking} of {rec['seeds']}")
    return "\n".join(lines)
