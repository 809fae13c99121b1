"""``mindgap design check``: is a world (and its simulated person) a valid test of PrefBias?

mindgap design check NAME|FILE [NAME|FILE …] [--belief B] [--budget N] [--segment L] [--beta B] [--fit] [--out DIR]

Prints, for each world, the exact finite-horizon plans under r_H, under what an unaware
learner learns and under an unbiased person, the per-step bias by terrain, each belief
parameter's standard error at the budget, the identifiability conditions, and the verdict
(:mod:`~mindgap.planning.design_check`). With ``--fit``, also a maximum-likelihood fit of the
belief and a state-form reward to the budget's simulated answers (:mod:`~mindgap.planning.belief_fit`):
each estimate and its standard error beside the Fisher one, and the first biased parameter's
profile log-likelihood. With ``--out``: ``WORLD.txt`` (the same text) and ``WORLD.json``. The
exit status is 0 when every world is valid, 1 when one is not (the fit does not change it).
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
    c.add_argument("--out", type=Path, help="folder for WORLD.txt and WORLD.json")


def run(args: argparse.Namespace) -> int:
    from ..envs.resolve import resolve_env
    from ..envs.terrain import TerrainWorld
    from ..planning.design_check import DesignConfig, design_check, plan_policies, report
    from ..teachers.preference import TeacherConfig

    if args.budget < 1 or args.segment < 1 or args.resolution < 1:
        raise ValueError("--budget, --segment and --resolution must be at least 1")
    worlds = []
    for spec in args.worlds:  # every world loaded and checked before anything is computed
        world = resolve_env(spec)
        if not isinstance(world, TerrainWorld):
            raise ValueError(f"the design check plans on a terrain world's map; {spec} is not a terrain world")
        if not world.beliefs:
            raise ValueError(f"{spec} declares no belief to check")
        if args.belief is not None:
            world.belief(args.belief)  # one line naming the beliefs it has
        worlds.append(world)
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
        if args.fit:
            fit_text, fit = _fit(world, args.belief, cfg, chk.parameters, planned)
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


def _fit(world, belief, cfg, fisher, planned) -> tuple[str, dict | None]:
    """The maximum-likelihood fit as text and as a plain record (None where it cannot run)."""
    from ..planning.belief_fit import FLAT_NATS, NO_SCALE, Z_MARGIN, fit_world, verdict

    if cfg.teacher.beta is None:
        return f"maximum-likelihood fit: not run: {NO_SCALE}\n", None
    fit = fit_world(world, belief, cfg, planned=planned)
    se = {p.name: p.stderr for p in fisher}
    lines = [
        f"maximum-likelihood fit to {cfg.budget} simulated answers (β = {cfg.teacher.beta:g}), started at the truth:",
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
        "parameters": [{**e._asdict(), "verdict": verdict(fit, e.name)} for e in fit.parameters],
        "rewards": [e._asdict() for e in fit.rewards],
        "loglik": fit.loglik,
        "profile": None if fit.profile is None else {
            "name": fit.profile.name, "grid": fit.profile.grid.tolist(), "loglik": fit.profile.loglik.tolist()
        },
    }  # fmt: skip
    return "\n".join(lines) + "\n", record
