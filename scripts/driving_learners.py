"""Train one driving learner on a finished run's participants, with other query or answer settings.

The participants (their answers to Fig. 32, beliefs and π_H) are the costly part of
``mindgap reproduce driving`` (20 minutes of its 48 on two cores); a learner takes about two.
This trains DRLHP or EPS (5 seeds, the full preset's schedule) on the participants of ``--run``
in a scratch folder, with the query segments drawn from anywhere in the replay buffer or from
episodes' starts (``--queries-from``) and the participants answering by the identifiable
protocol or by log π_H alone (``--answers-by``), each decision scored as is or against the
state's most expected one (``--relative``), and prints the behaviours the experiment
measures (docs/experiments/driving.md, Status). Two controls: ``--mistake 0.5`` flips every
answer with probability one half, so the answers carry nothing (a coin), and
``--entropy-bonus 0`` switches off the learners' state-entropy exploration bonus. With
``--exact PID`` no query is asked: u_H is that one participant's own score, log T_H + log π_H
(EPS's exact surrogate), and ``--road S`` sets the road the learner drives on (0 the dry road
a biased participant believes in; default the run's):

    .venv/bin/python scripts/driving_learners.py --run results/driving --method drlhp \\
        [--queries-from anywhere|start] [--answers-by protocol|decisions] [--segment 5] \\
        [--relative] [--mistake P] [--entropy-bonus B] [--lam L] [--nats-per-unit S] [--exact PID] [--road S] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import tempfile
import time
from pathlib import Path

import jax

from mindgap._io import use_compilation_cache
from mindgap.algorithms import eps as eps_alg
from mindgap.experiments import driving as dr
from mindgap.experiments._runfolder import RunFolder
from mindgap.teachers.expectation import ExpectationTeacher


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, required=True, help="a finished `mindgap reproduce driving` run folder")
    p.add_argument("--method", choices=("drlhp", "eps"), required=True)
    p.add_argument("--queries-from", choices=("anywhere", "start"), default="anywhere")
    p.add_argument("--answers-by", choices=("protocol", "decisions"), default="protocol")
    p.add_argument("--segment", type=int, default=None, help="steps per query segment (default: the preset's 5)")
    p.add_argument(
        "--relative",
        action="store_true",
        help="participants score each decision against the state's most expected one (TeacherConfig.relative)",
    )
    p.add_argument("--mistake", type=float, default=0.0, help="probability that an answer is flipped (0.5: a coin)")
    p.add_argument(
        "--entropy-bonus", type=float, default=None, help="the state-entropy bonus's weight (default the preset's)"
    )
    p.add_argument("--lam", type=float, default=None, help="EPS's λ (default the preset's 2.0)")
    p.add_argument("--nats-per-unit", type=float, default=None, help="EPS's s_H (default the preset's 7)")
    p.add_argument("--exact", metavar="PID", help="u_H is this participant's own score (no queries)")
    p.add_argument("--road", type=float, default=None, help="the sleet of the road driven on (default the run's)")
    p.add_argument("--out", type=Path, default=None, help="scratch run folder (default: a temporary one)")
    args = p.parse_args()
    people = args.run / "jobs" / "driving__people.json"
    if not people.is_file():
        raise SystemExit(f"{args.run} has no finished participants job ({people})")
    use_compilation_cache()
    cfg = dr.preset("full")
    sac = cfg.eps.sac
    if args.entropy_bonus is not None:
        sac = dataclasses.replace(sac, entropy_bonus=args.entropy_bonus)
    eps = dataclasses.replace(
        cfg.eps,
        queries_from=args.queries_from,
        segment=args.segment or cfg.eps.segment,
        sac=sac,
        lam=cfg.eps.lam if args.lam is None else args.lam,
        nats_per_unit=cfg.eps.nats_per_unit if args.nats_per_unit is None else args.nats_per_unit,
    )
    teacher = dataclasses.replace(
        cfg.teacher, use_belief=args.answers_by == "protocol", mistake=args.mistake, relative=args.relative
    )
    traffic = json.loads((args.run / "config.json").read_text()).get("traffic", 0)  # the run's road
    cfg = dataclasses.replace(cfg, eps=eps, teacher=teacher, traffic=traffic)
    if args.road is not None:
        cfg = dataclasses.replace(cfg, sleet=args.road)
    out = args.out or Path(tempfile.mkdtemp(prefix="driving-learner-"))
    for sub, name in (("jobs", "driving__people.json"), ("actors", "people.npz")):
        (out / sub).mkdir(parents=True, exist_ok=True)
        shutil.copy(args.run / sub / name, out / sub / name)
    folder = RunFolder(out, cfg)
    job = next(j for j in dr.jobs(cfg) if j.method == args.method)
    t = time.time()
    if args.exact:
        rec, what = exact(folder, cfg, job, args.exact), f"the exact score of {args.exact}"
    else:
        rec = dr._compute(cfg)(folder, job, cfg.seeds, fresh=True, progress=True)
        what = f"queries from {args.queries_from}, answers by {args.answers_by}, {eps.segment}-step segments, "
        what += f"mistake {args.mistake}" + (", relative scores" if args.relative else "")
    print(f"{args.method} (λ {eps.lam}) on {what}, road sleet {cfg.sleet}, entropy bonus {sac.entropy_bonus}: "
          f"{time.time() - t:.0f} s, {out}")  # fmt: skip
    for k, label in (
        ("return", "return under r_A"),
        ("collided", "collision rate"),
        ("changed", "episodes with a lane change"),
        ("first_change", "first lane change (decisions after the onset)"),
        ("braked_first", "braked before changing lane"),
        ("min_gap", "smallest gap in the front car's lane [m]"),
    ):
        print(f"  {label:48s}", " ".join("   n/a" if x is None else f"{float(x):6.2f}" for x in rec[k]))


def exact(folder: RunFolder, cfg, job, pid: str) -> dict:
    """Train ``job``'s learner with u_H the exact score of participant ``pid``; its behaviours' record."""
    people = folder.done("driving/people")
    world = dr.world_of(cfg, people["engineered_weights"])
    valid, actors = dr.load_people(folder, world, people, cfg)
    pids = [d.pid for d in valid]
    if pid not in pids:
        raise SystemExit(f"no valid participant {pid!r} in the run (valid: {', '.join(pids)})")
    i = pids.index(pid)
    person = ExpectationTeacher(
        dr.belief_params(world, valid[i]), jax.tree.map(lambda a: a[i], actors), world.env, cfg.teacher
    )
    ecfg = dataclasses.replace(job.cfg, surrogate="exact")
    res = eps_alg.train(world, ecfg, person, person_name=pid, seeds=cfg.seeds, out=folder.root / "exact")
    spread = ", ".join(f"{float(v):.2f}" for v in res["carry"].model.u_norm[:, 1])
    print(
        f"u_H's standard deviation over each seed's buffer [nats]: {spread} (the entropies' s_H: {ecfg.nats_per_unit})"
    )
    return dr.learner_record(cfg, world, res["carry"].loop.sac.params.actor, res)


if __name__ == "__main__":
    main()
