"""``mindgap design check`` and ``mindgap design recovery``: is a world (and its simulated person) a valid
test of PrefBias, and does PrefBias's inference recover the belief there?

mindgap design check NAME|FILE [NAME|FILE …] [--belief B] [--budget N] [--segment L] [--beta B] [--fit]
                     [--precision EPS] [--oracle RUN] [--out DIR]

Prints, for each world, the exact finite-horizon plans under r_H, under what an unaware
learner learns and under an unbiased person, the per-step bias by terrain, each belief
parameter's standard error at the budget, the identifiability conditions, and the verdict
(:mod:`~mindgap.design.design_check`). With ``--fit``, also a maximum-likelihood fit of the
belief and a state-form reward to the budget's simulated answers (:mod:`~mindgap.design.belief_fit`):
each estimate and its standard error beside the Fisher one, and the first biased parameter's
profile log-likelihood; ``--precision`` makes the fit's learner predict the move mean with a
smooth error of that RMS (cells), the precision a learned dynamics model reaches. ``--oracle RUN``
says whether every SAC oracle seed of a run folder beats the random policy. With ``--out``:
``WORLD.txt`` (the same text) and ``WORLD.json``. The exit status is 0 when every world is valid,
1 when one is not (the fit does not change it).

mindgap design recovery NAME|FILE [NAME|FILE …] [--belief B] [--budget N] [--updates U]
                        [--person biased|unbiased] [--set FIELD=VALUE …] [--no-tabular] [--out DIR]

Fits PrefBias's inference alone to simulated answers and reports, by terrain, the learned belief
against the person's on held-out true transitions (:mod:`~mindgap.experiments.belief_recovery`).

mindgap design reward-plan --run DIR --job KEY [--rollouts N] [--out DIR]

For each seed of a finished PrefBias or PEBBLE job of a nav, priors or sampling run (its
checkpoint in ``DIR/train``): the optimum of its learned reward under the true dynamics, run in
the world, and what the reward says of the optimal and the person's expected plan
(:mod:`~mindgap.experiments.reward_optimum`).

mindgap design driving --run DIR [--episodes N] [--answers-by rollout|rollout-behaviour|expectation|decisions] [--seed S]
mindgap design driving --run DIR --learner drlhp|eps [--coin] [--only PID] [--exact PID] [--road S] [--lam L]
                       [--survival-entropy paid|neutral] [--alpha A|tuned] [--offset cost|centred|none]
                       [--absorbing single|terminal|none] [--seeds N]

The driving study's participant gates on a run's participants, before any learner
(:mod:`~mindgap.experiments.driving_probes`): which scripted response each participant wants and
finds most expected, how their π_H meets the front car's braking, the bias and sanity counts and
where the sanity collision ranks. Writes ``DIR/gates.json`` (``gates-WAY.json`` with
``--answers-by``); the exit status is 0 when every gate holds, 1 when one fails. With ``--learner``,
a control instead: that learner trained on the run's participants with one thing changed
(:mod:`~mindgap.experiments.driving_controls`), in ``DIR/controls/NAME`` (resumable), its
behaviours printed per seed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from .learn import beta_value


def add_parser(sub) -> None:
    d = sub.add_parser("design", help="check that a world can show PrefBias's effect before running a study")
    dsub = d.add_subparsers(dest="design_command", required=True)
    c = dsub.add_parser("check", help="plan, compare and measure identifiability (docs/experiments/identifiability.md)")
    c.add_argument("worlds", nargs="+", help="named terrain worlds or world files")
    c.add_argument("--belief", help="the person's belief (default: each world's first)")
    c.add_argument("--budget", type=int, default=800, help="answered queries (default 800)")
    c.add_argument("--segment", type=int, default=10, help="steps per segment (default 10)")
    c.add_argument(
        "--beta", type=beta_value, default=1.0, help="the person's rationality (default 1; inf: deterministic)"
    )
    c.add_argument("--resolution", type=int, default=4, help="sub-cells per cell side (default 4)")
    c.add_argument("--seed", type=int, default=0, help="random seed of the Monte Carlo parts")
    c.add_argument("--fit", action="store_true", help="also fit the belief by maximum likelihood to simulated answers")
    c.add_argument(
        "--precision", type=float, default=0.0, metavar="EPS",
        help="the fit's learner predicts the move mean with a smooth error of RMS EPS cells (default 0: exactly)",
    )  # fmt: skip
    c.add_argument(
        "--oracle", type=Path, metavar="RUN",
        help="a run folder of nav/priors/sampling: say whether every SAC oracle seed there beats the random policy",
    )  # fmt: skip
    c.add_argument("--out", type=Path, help="folder for WORLD.txt and WORLD.json")
    r = dsub.add_parser(
        "recovery",
        help="does PrefBias's inference recover the belief from the answers? (docs/experiments/identifiability.md)",
    )
    r.add_argument("worlds", nargs="+", help="named terrain worlds or world files")
    r.add_argument("--belief", help="the person's belief (default: each world's first)")
    r.add_argument("--budget", type=int, default=800, help="answered queries to learn from (default 800)")
    r.add_argument("--segment", type=int, default=10, help="steps per segment (default 10)")
    r.add_argument("--updates", type=int, default=3000, help="rounds of the inference (default 3000)")
    r.add_argument("--rounds", type=int, default=1,
                   help="fit as the loop does: R fits of UPDATES/R rounds on growing shares of the answers (default 1)")  # fmt: skip
    r.add_argument("--person", choices=("biased", "unbiased"), default="biased", help="who answers (default biased)")
    r.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                   help="a PrefBiasConfig field of the inference, e.g. belief_prior_std=0.1 (repeatable)")  # fmt: skip
    r.add_argument("--no-tabular", action="store_true", help="skip the tabular maximum-likelihood reference")
    r.add_argument("--seed", type=int, default=0, help="random seed")
    r.add_argument("--out", type=Path, help="folder for WORLD-recovery.txt, .json and .png (the stay maps)")
    rp = dsub.add_parser(
        "reward-plan",
        help="plan on a finished preference learner's reward: is a missed route the reward's or the policy's? "
        "(docs/experiments/identifiability.md)",
    )
    rp.add_argument("--run", type=Path, required=True, help="a nav, priors or sampling run folder with checkpoints")
    rp.add_argument("--job", required=True, help="a finished PrefBias or PEBBLE job of it, e.g. nav2/prefbias-q800")
    rp.add_argument("--rollouts", type=int, default=20, help="rollouts of the reward's optimal plan per seed (default 20)")
    rp.add_argument("--out", type=Path, help="folder for JOB-reward-plan.txt and .json")
    v = dsub.add_parser(
        "driving", help="the driving study's participant gates, before any learner (docs/experiments/driving.md)"
    )
    v.add_argument("--run", type=Path, required=True, help="a driving run folder with a finished driving/people job")
    v.add_argument("--episodes", type=int, default=200, help="episodes per scripted policy and road (default 200)")
    v.add_argument(
        "--answers-by", choices=("rollout", "rollout-behaviour", "expectation", "decisions"),
        help="how the participants judge a clip (default: as the run has them)",
    )  # fmt: skip
    v.add_argument("--seed", type=int, default=0, help="random seed of the episodes")
    v.add_argument(
        "--learner", choices=("drlhp", "eps"),
        help="instead of the gates, train this learner on the run's participants as a control (below)",
    )  # fmt: skip
    v.add_argument("--coin", action="store_true", help="control: every answer a fair coin")
    v.add_argument("--only", metavar="PID", help="control: every query goes to this one participant")
    v.add_argument("--exact", metavar="PID", help="control: u_H is this participant's own per-step score (no queries)")
    v.add_argument("--road", type=float, help="control: the sleet of the road driven on (default the run's)")
    v.add_argument("--lam", type=float, help="control: EPS's λ (default the preset's)")
    v.add_argument("--survival-entropy", choices=("paid", "neutral"), help="control: SAC's survival_entropy")
    v.add_argument(
        "--alpha", type=_alpha, help="control: DRLHP's SAC entropy coefficient, fixed, or 'tuned' (default: 1/s_H)"
    )
    v.add_argument(
        "--offset",
        choices=("cost", "centred", "none"),
        help="control: the constant of EPS's λ-term (default the preset's)",
    )
    v.add_argument(
        "--absorbing",
        choices=("single", "terminal", "none"),
        help="control: u_H's absorbing states (default the preset's)",
    )
    v.add_argument("--seeds", type=int, help="control: seeds (default the preset's)")


def _alpha(text: str) -> float | str:
    """``--alpha``: a positive number, or ``tuned``."""
    if text == "tuned":
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a positive number or 'tuned', got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"a positive number or 'tuned', got {text!r}")
    return value


def run(args: argparse.Namespace) -> int:
    if args.design_command == "recovery":
        return _recovery(args)
    if args.design_command == "driving":
        return _driving(args)
    if args.design_command == "reward-plan":
        return _reward_plan(args)
    from ..design.design_check import DesignConfig, design_check, plan_policies, report
    from ..teachers.preference import TeacherConfig

    if args.budget < 1 or args.segment < 1 or args.resolution < 1:
        raise ValueError("--budget, --segment and --resolution must be at least 1")
    if not args.precision >= 0:
        raise ValueError(f"--precision must be at least 0 (cells), got {args.precision}")
    if args.oracle is not None and not (args.oracle / "jobs").is_dir():
        raise ValueError(f"--oracle {args.oracle}: not a run folder (no jobs/ in it)")
    worlds = _terrain_worlds(args.worlds, args.belief)
    cfg = DesignConfig(
        n=args.resolution,
        budget=args.budget,
        segment=args.segment,
        teacher=dataclasses.replace(TeacherConfig(), beta=args.beta),
        seed=args.seed,
    )
    valid = True
    for world in worlds:
        planned = plan_policies(world, world.belief(args.belief), cfg)  # planned once for the check and the fit
        chk = design_check(world, args.belief, cfg, planned)
        text, record = report(chk), chk.as_dict()
        if args.oracle is not None:
            line, record["oracle"] = oracle_line(args.oracle, world.name)
            text += line
        if args.fit:
            fit_text, fit = _fit(world, args.belief, cfg, chk.parameters, planned, args.precision)
            record["fit"] = json.loads(json.dumps(fit), parse_constant=lambda _: None)  # ±inf, NaN as null
            text += "\n" + fit_text
        print(text)
        valid &= chk.valid
        if args.out is not None:
            from .._io import atomic_write

            args.out.mkdir(parents=True, exist_ok=True)
            atomic_write(args.out / f"{world.name}.txt", text)
            atomic_write(args.out / f"{world.name}.json", json.dumps(record, indent=2))
    return 0 if valid else 1


def _driving(args) -> int:
    """Print the participant gates of a driving run and write them to its ``gates.json``; 1 when one fails."""
    from .._io import atomic_write
    from ..experiments import driving_probes as probes

    if args.episodes < 1:
        raise ValueError("--episodes must be at least 1")
    control_flags = (
        "coin",
        "only",
        "exact",
        "road",
        "lam",
        "survival_entropy",
        "offset",
        "absorbing",
        "seeds",
        "alpha",
    )
    if args.learner is not None:
        from ..experiments import driving_controls as dc

        if args.seeds is not None and args.seeds < 1:
            raise ValueError("--seeds must be at least 1")
        c = dc.Control(args.learner, answers_by=args.answers_by, **{k: getattr(args, k) for k in control_flags})
        print(dc.report(dc.run_control(args.run, c)))
        return 0
    for flag in control_flags:
        if getattr(args, flag) not in (None, False):
            raise ValueError(f"--{flag.replace('_', '-')} goes with --learner")
    people = probes.load_participants(args.run, args.answers_by)
    g = probes.gates(people, args.episodes, args.seed)
    print(probes.report(g))
    name = "gates.json" if args.answers_by is None else f"gates-{args.answers_by}.json"
    atomic_write(args.run / name, json.dumps(g, indent=2))
    return 0 if all(v["holds"] for v in g["gates"].values()) else 1


def _terrain_worlds(specs, belief):
    """Every world loaded and checked before anything is computed (one line on the first that fails)."""
    from ..envs.resolve import resolve_env
    from ..envs.terrain import TerrainWorld

    worlds = []
    for spec in specs:
        world = resolve_env(spec)
        if not isinstance(world, TerrainWorld):
            raise ValueError(f"the design tools plan on a terrain world's map; {spec} is not a terrain world")
        if not world.beliefs:
            raise ValueError(f"{spec} declares no belief to check")
        if belief is not None:
            world.belief(belief)  # one line naming the beliefs it has
        worlds.append(world)
    return worlds


def prefbias_overrides(items: list[str]) -> dict:
    """``FIELD=VALUE`` items as PrefBiasConfig fields (VALUE a Python literal, a bare word a string, a switch
    true or false)."""
    import ast

    from ..algorithms.prefbias_inference import PrefBiasConfig

    defaults = {f.name: f.default for f in dataclasses.fields(PrefBiasConfig)}
    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not eq or name not in defaults:
            raise ValueError(f"--set {item!r}: expected FIELD=VALUE with FIELD one of {', '.join(sorted(defaults))}")
        if isinstance(defaults[name], bool):  # a switch: `false` must not become the (true) string "false"
            if value.lower() not in ("true", "false"):
                raise ValueError(f"--set {item!r}: {name} is true or false")
            out[name] = value.lower() == "true"
            continue
        try:
            out[name] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            out[name] = value
    return out


def _recovery(args) -> int:
    from .._io import atomic_write
    from ..algorithms.prefbias_inference import PrefBiasConfig
    from ..experiments.belief_recovery import RecoveryConfig, belief_recovery, report, save_figure

    cfg = RecoveryConfig(budget=args.budget, segment=args.segment, updates=args.updates, rounds=args.rounds,
                         person=args.person, tabular=not args.no_tabular, seed=args.seed)  # fmt: skip
    cfg.check()
    try:
        pcfg = PrefBiasConfig(**prefbias_overrides(args.set))
    except TypeError as e:
        raise ValueError(f"--set: {e}") from None
    pcfg.check()
    cfg.check(pcfg)  # the fits' own inference too, before any answer is simulated
    for world in _terrain_worlds(args.worlds, args.belief):
        rec = belief_recovery(
            world, pcfg, cfg, args.belief, progress=lambda m, w=world.name: print(f"{w}: {m} …", flush=True)
        )
        text = report(rec)
        print(text)
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            atomic_write(args.out / f"{world.name}-recovery.txt", text)
            atomic_write(args.out / f"{world.name}-recovery.json", json.dumps(rec.as_dict(), indent=2))
            save_figure(rec, world, args.out / f"{world.name}-recovery.png")
    return 0


def _reward_plan(args) -> int:
    from .._io import atomic_write
    from ..experiments.reward_optimum import report, reward_plan

    if args.rollouts < 1:
        raise ValueError("--rollouts must be at least 1")
    rec = reward_plan(args.run, args.job, args.rollouts)
    text = report(rec)
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        stem = args.job.replace("/", "__")
        atomic_write(args.out / f"{stem}-reward-plan.txt", text + "\n")
        atomic_write(args.out / f"{stem}-reward-plan.json", json.dumps(rec, indent=2))
    return 0


def oracle_line(run: Path, world: str) -> tuple[str, dict | None]:
    """Whether every SAC oracle seed of a run folder beats the uniformly random policy on ``world``:
    a normalised score divides by the oracle, so one failed oracle seed makes it meaningless."""
    jobs = run / "jobs"
    sac, ref = jobs / f"{world}__sac.json", jobs / f"{world}__reference.json"
    if not (sac.is_file() and ref.is_file()):
        return f"the oracle: {run} has no finished SAC and reference jobs for {world}\n", None
    from ..experiments.prefbias_common import seed_returns

    rand = float(json.loads(ref.read_text())["random_return"])
    means = seed_returns(json.loads(sac.read_text())).tolist()
    above = sum(m > rand for m in means)
    ok = above == len(means)
    text = (
        f"the oracle ({run}): {above} of {len(means)} SAC seeds above the random policy's {rand:.1f}"
        f" (lowest {min(means):.1f}): {'reliable' if ok else 'NOT reliable: a score normalised by it means little'}\n"
    )
    return text, {"seeds": len(means), "above_random": above, "random": rand, "lowest": min(means), "reliable": ok}


def _fit(world, belief, cfg, fisher, planned, precision: float = 0.0) -> tuple[str, dict | None]:
    """The maximum-likelihood fit as text and as a plain record (None where it cannot run)."""
    from ..design.belief_fit import FLAT_NATS, NO_SCALE, Z_MARGIN, fit_world, verdict

    if cfg.teacher.beta is None:
        return f"maximum-likelihood fit: not run: {NO_SCALE}\n", None
    fit = fit_world(world, belief, cfg, planned=planned, precision=precision)
    se = {p.name: p.stderr for p in fisher}
    learner = (
        "a learner that predicts the move mean exactly (--precision 0)" if precision == 0
        else f"a learner whose predicted move mean errs by a smooth field of RMS {precision:g} cells"
    )  # fmt: skip
    lines = [
        f"maximum-likelihood fit to {cfg.budget} simulated answers (β = {cfg.teacher.beta:g}), started at the truth,"
        f" by {learner}:",
        "  parameter     truth → belief    estimate ± SE      Fisher SE   verdict",
    ]
    for e in fit.parameters:
        lines.append(
            f"  {e.name:<12} {e.truth:6.3f} → {e.belief:6.3f}   {e.estimate:7.3f} ± {e.stderr:<9.3g}"
            f" {se.get(e.name, float('nan')):9.3g}   {verdict(fit, e.name)}"
        )
    held = fit.rewards[0]
    lines.append(
        f"  reward by terrain, then its distance coefficient (truth → estimate ± SE; {held.name} held at {held.truth:g}):"
    )
    lines += [f"    {e.name:<8} {e.truth:6.2f} → {e.estimate:6.2f} ± {e.stderr:.2g}" for e in fit.rewards[1:]]
    if fit.profile is not None:
        p = fit.profile
        lines.append(f"  profile log-likelihood of {p.name} (nats from the maximum; flat below {FLAT_NATS:g}):")
        lines.append("    " + "  ".join(f"{g:.2f}: {v:+.1f}" for g, v in zip(p.grid, p.loglik)))
    lines.append(
        f"  (recovered: within {Z_MARGIN:g} SE of the belief and at least {Z_MARGIN:g} SE from the truth, "
        "on the fit's logit or log scale)"
    )
    record = {
        "precision": precision,
        "parameters": [{**e._asdict(), "verdict": verdict(fit, e.name)} for e in fit.parameters],
        "rewards": [e._asdict() for e in fit.rewards],
        "loglik": fit.loglik,
        "profile": None if fit.profile is None else {
            "name": fit.profile.name, "grid": fit.profile.grid.tolist(), "loglik": fit.profile.loglik.tolist()
        },
    }  # fmt: skip
    return "\n".join(lines) + "\n", record
