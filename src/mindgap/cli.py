"""The ``mindgap`` command line.

mindgap reproduce table1 [--fast] [--seeds N] [--out DIR] [--fresh]
mindgap gerel --domain grid7 [--size N] [--belief B] [--seed S] [--out DIR]
mindgap gerel --domain grid7 --ratings FILE [--out DIR]
mindgap reproduce coffee [--fast] [--participants N] [--out DIR]
mindgap reproduce driving [--fast] [--seeds N] [--sleet S] [--traffic N] [--sanity expectation] [--importance A,B,C,D] [--answers-by rollout-behaviour|rollout|expectation|decisions] [--out DIR]
mindgap reproduce nav|priors|sampling|eps|lambda|gym [--fast] [--seeds N] [--worlds W,W | --env SPEC …] [--out DIR]
mindgap gerel --domain coffee [--robot R] [--ratings FILE] [--out DIR]
mindgap worlds list|show|plan …            (terrain worlds; see mindgap.commands.worlds)
mindgap design check WORLD …               (can a world show PrefBias's effect? see mindgap.commands.design)
mindgap sac|pebble|drlhp --world W --out DIR …   (preference-based RL; see mindgap.commands.learn)
mindgap prefbias --world W --out DIR …   (PrefBias, Algorithm 2; see mindgap.commands.prefbias)
mindgap eps --world W --lam L --out DIR …   (EPS, Algorithm 3; see mindgap.commands.eps)
mindgap study serve|check|links|export|examples …  (user studies in the browser; see mindgap.commands.study)
mindgap report RUN_DIR … [--out DIR]       (one page of results beside the dissertation's; see mindgap.commands.report)
mindgap reproduce NAME --backend local|ray [--workers N] [--address ADDR]   (every job on workers, then assembled)
mindgap sweep SPEC.toml [--backend local|ray] …   (experiments and grids on workers or Ray; see mindgap.commands.sweep)
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from ._io import use_compilation_cache
from .experiments.registry import NAMES as EXPERIMENTS
from .experiments.terrain_cli import NAMES as TERRAIN_EXPERIMENTS

DOMAINS = ("grid7", "coffee")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mindgap", description="Learn what a person wants when they misjudge the robot.")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("reproduce", help="run a named experiment of the dissertation")
    r.add_argument("name", help=f"experiment: {', '.join(EXPERIMENTS)}")
    r.add_argument("--fast", action="store_true", help="the quick preset (seconds to minutes)")
    r.add_argument("--seeds", type=int, help="seeds per setting (overrides the preset)")
    r.add_argument("--worlds", help="terrain experiments: a comma-separated subset of the worlds (names or files)")
    r.add_argument(
        "--env",
        action="append",
        metavar="SPEC",
        help="terrain experiments: run on this world instead (repeatable): a named world, a world file, "
        "or path.py:factory[,key=value…] with a belief and an exact log_prob",
    )
    r.add_argument("--participants", type=int, help="coffee: valid participants per robot type (overrides the preset)")
    r.add_argument("--sleet", type=float, help="driving: the road's sleet level, 0 (dry) to 1 (full sleet)")
    r.add_argument("--traffic", type=int, help="driving: other cars on the road (0 to 4 on its three lanes)")
    r.add_argument(
        "--sanity",
        choices=("expectation", "preference"),
        help="driving: recruits answer the sanity item by which clip they prefer (default) or find more expected",
    )
    r.add_argument("--importance", metavar="A,B,C,D", help="driving: the participants' mean importance answers (1-5)")
    r.add_argument(
        "--answers-by",
        choices=("rollout", "rollout-behaviour", "expectation", "decisions"),
        help="driving: participants judge a clip by its decisions played out in the world they believe in "
        "(rollout-behaviour, default; rollout also charges a crash they did not expect), by log T_H + log pi_H "
        "at its states (expectation) or by log pi_H there alone (decisions)",
    )
    r.add_argument("--out", type=Path, help="run folder (default runs/NAME or runs/NAME-fast); reruns resume")
    r.add_argument("--fresh", action="store_true", help="discard finished jobs in the run folder")
    r.add_argument("--quiet", action="store_true", help="no progress bars")
    r.add_argument("--assemble", action="store_true", help="write outputs from the finished jobs only; run nothing")
    r.add_argument("--shard", help="I/N: run only slice I of N (processes sharing --out); rerun without it to assemble")
    r.add_argument(
        "--job", metavar="KEY", help="run only this job (a record's `command` names it) and print its record"
    )

    from .commands import design, eps, learn, prefbias, report, study, sweep, worlds

    sweep.add_backend_flags(r)

    worlds.add_parser(sub)
    design.add_parser(sub)
    learn.add_parsers(sub)
    prefbias.add_parser(sub)
    eps.add_parser(sub)
    study.add_parser(sub)
    report.add_parser(sub)
    sweep.add_parser(sub)

    g = sub.add_parser("gerel", help="fit GeReL to simulated or recorded ratings")
    g.add_argument("--domain", default="grid7", help=f"domain: {', '.join(DOMAINS)}")
    g.add_argument("--size", type=int, default=7, help="grid side")
    g.add_argument(
        "--belief",
        default="reversed",
        help="simulated person's belief: reversed, rotated, true, a permutation like 1,0,3,2, or a .npy tensor",
    )
    g.add_argument(
        "--corners", help="reward,penalty corner ids (0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right)"
    )
    g.add_argument("--seed", type=int, default=0, help="random seed")
    g.add_argument("--demos", type=int, default=2000, help="number of simulated rated demonstrations")
    g.add_argument("--length", type=int, default=10, help="steps per simulated demonstration")
    g.add_argument(
        "--param",
        choices=("tied", "per-sa", "full", "factored"),
        help="belief parameterisation (grid7: tied by default; coffee: factored by default)",
    )
    g.add_argument(
        "--robot", help="coffee: robot type of the simulated person, or of a ratings file without a robot column"
    )
    g.add_argument(
        "--normalise", default="minmax", choices=("minmax", "none"), help="coffee: per-person rating scaling"
    )
    g.add_argument("--no-filter", action="store_true", help="coffee: keep people who fail the sanity check")
    g.add_argument("--estimator", default="pathwise", choices=("pathwise", "score"), help="ELBO gradient estimator")
    g.add_argument("--minus", action="store_true", help="GeReL⁻: freeze the belief at the true dynamics")
    g.add_argument("--max-iter", type=int, help="iteration cap")
    g.add_argument("--restarts", type=int, help="random restarts")
    g.add_argument("--ratings", type=Path, help="fit to this ratings CSV instead of a simulated person")
    g.add_argument("--save-ratings", type=Path, help="also write the simulated ratings in the ratings CSV format")
    g.add_argument("--out", type=Path, help="folder for posterior.npz and posterior.json")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    use_compilation_cache()
    try:
        if args.command == "reproduce":
            return _reproduce(args)
        if args.command == "worlds":
            from .commands import worlds

            return worlds.run(args)
        if args.command == "study":
            from .commands import study

            return study.run(args)
        if args.command == "report":
            from .commands import report

            return report.run(args)
        if args.command == "sweep":
            from .commands import sweep

            return sweep.run(args)
        if args.command == "design":
            from .commands import design

            return design.run(args)
        if args.command in ("sac", "pebble", "drlhp"):
            from .commands import learn

            return learn.run(args)
        if args.command == "prefbias":
            from .commands import prefbias

            return prefbias.run(args)
        if args.command == "eps":
            from .commands import eps

            return eps.run(args)
        return _gerel(args)
    except (ValueError, RuntimeError, FloatingPointError) as e:
        print(f"mindgap: error: {e}", file=sys.stderr)
        return 2


def _reproduce(args) -> int:
    if args.name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {args.name!r}: choose from {', '.join(EXPERIMENTS)}")
    from .experiments import table1

    if args.assemble and (args.fresh or args.shard):
        raise ValueError("--assemble only reads a run folder; it does not combine with --fresh or --shard")
    if args.job and (args.assemble or args.shard):
        raise ValueError("--job runs one job; it does not combine with --assemble or --shard")
    for flag in ("worlds", "env"):
        if getattr(args, flag) and args.name not in TERRAIN_EXPERIMENTS:
            raise ValueError(f"--{flag} belongs to the terrain experiments ({', '.join(TERRAIN_EXPERIMENTS)})")
    for flag in ("sleet", "traffic", "sanity", "importance", "answers_by"):
        if getattr(args, flag) is not None and args.name != "driving":
            raise ValueError(f"--{flag.replace('_', '-')} belongs to the driving study")
    if args.backend:
        from .commands import sweep

        return sweep.reproduce(args)
    for flag in ("workers", "address", "retries", "cpus_per_job", "gpus_per_job"):
        if getattr(args, flag) is not None:
            raise ValueError(f"--{flag.replace('_', '-')} goes with --backend local|ray")
    if args.name == "driving":
        from .experiments import driving_cli

        return driving_cli.reproduce(args)
    if args.name == "coffee":
        from .experiments import coffee_cli

        return coffee_cli.reproduce(args, _shard(args.shard))
    if args.name in TERRAIN_EXPERIMENTS:
        from .experiments import terrain_cli

        return terrain_cli.reproduce(args)
    if args.participants is not None:
        raise ValueError("--participants belongs to the coffee study")
    cfg = table1.preset("fast" if args.fast else "full")
    if args.seeds is not None:
        if args.seeds < 1:
            raise ValueError("--seeds must be at least 1")
        cfg = replace(cfg, seeds=args.seeds, demo_count_seeds=min(cfg.demo_count_seeds, args.seeds))
    out = args.out or Path("runs") / (args.name + ("-fast" if args.fast else ""))
    shard = _shard(args.shard)
    summary = table1.run(
        cfg, out, fresh=args.fresh, progress=not args.quiet, shard=shard, assemble_only=args.assemble, only=args.job
    )
    if args.job:
        from .experiments._runfolder import job_summary

        print(job_summary(summary["job"], out, args.job))
        return 0
    if summary is None:
        print(f"shard {args.shard} done; rerun without --shard to assemble {out}/")
        return 0
    print(summary["table_md"])
    if summary.get("missing_jobs"):
        print(f"{summary['missing_jobs']} jobs not run yet; rerun without --assemble to finish them")
    print(f"results, curves and figures in {out}/")
    return 0


def _shard(spec: str | None) -> tuple[int, int] | None:
    if not spec:
        return None
    try:
        i, n = (int(x) for x in spec.split("/"))
    except ValueError:
        raise ValueError(f"--shard must look like 0/2, got {spec!r}") from None
    if not 0 <= i < n:
        raise ValueError(f"--shard {spec}: need 0 <= I < N")
    return i, n


def _gerel(args) -> int:
    if args.domain == "coffee":
        from .experiments import coffee_cli

        return coffee_cli.gerel(args)
    import jax
    import numpy as np

    from . import rng
    from ._io import atomic_write
    from .algorithms.gerel import GeReLConfig, fit_gerel
    from .envs.grid import ACTIONS, MOVE_NAMES
    from .experiments.table1 import belief_space
    from .feedback.demos import random_demonstrations
    from .feedback.ratings_file import read_ratings, write_ratings
    from .metrics import all_metrics
    from .planning.grid_task import make_grid
    from .teachers.rating import RatingTeacher

    if args.domain not in DOMAINS:
        raise ValueError(f"unknown domain {args.domain!r}: choose from {', '.join(DOMAINS)}")
    args.param = args.param or "tied"
    if args.param == "factored":
        raise ValueError("--param factored needs a factored domain (coffee); grid7 takes tied, per-sa or full")
    corners = None
    if args.corners:
        try:
            corners = tuple(int(c) for c in args.corners.split(","))
        except ValueError:
            raise ValueError(f"--corners must be two integers like 1,3, got {args.corners!r}") from None
    task = make_grid(args.size, args.belief, seed=args.seed, corners=corners)
    cfg = GeReLConfig(estimator=args.estimator, freeze_belief=args.minus)
    if args.max_iter:
        cfg = replace(cfg, max_iter=args.max_iter)
    if args.restarts:
        cfg = replace(cfg, restarts=args.restarts, keep=min(cfg.keep, args.restarts))
    key = rng.key(args.seed)
    k_demo, k_rate, k_fit = jax.random.split(key, 3)
    simulated = args.ratings is None
    if simulated:
        if args.demos < 1 or args.length < 1:
            raise ValueError("--demos and --length must be at least 1")
        teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
        rated = teacher.rate(k_rate, random_demonstrations(k_demo, task.mdp, args.demos, args.length))
        if args.save_ratings:
            write_ratings(args.save_ratings, rated)
    else:
        rated = read_ratings(
            args.ratings, n_states=task.mdp.n_states, n_actions=task.mdp.n_actions, gamma_max=cfg.gamma_max
        )
    space = belief_space(task, args.param)
    res = fit_gerel(task.mdp, rated, space, cfg, key=k_fit, progress=not args.quiet)

    report = {
        "domain": args.domain,
        "size": args.size,
        "param": args.param,
        "estimator": args.estimator,
        "method": "gerel-minus" if args.minus else "gerel",
        "n_demos": int(rated.demos.count),
        "mu": [float(x) for x in res.mu],
        "elbo": float(res.elbo[res.best]),
        "iterations": res.run.iterations,
    }
    weights = ", ".join(f"{x:.3f}" for x in res.mu)
    print(f"learned reward weights μ = [{weights}]  (ELBO {report['elbo']:.1f})")
    if args.param == "tied" and not args.minus:
        theta = res.alpha / res.alpha.sum(-1, keepdims=True)
        print("believed effect of each action (probability of each move):")
        print("          " + " ".join(f"{m:>6}" for m in MOVE_NAMES))
        for a, name in enumerate(ACTIONS):
            print(f"  {name:<7} " + " ".join(f"{p:6.2f}" for p in theta[a]))
    if simulated:
        m = all_metrics(task.mdp, res.mu, res.transitions, task.true_weights, task.human_transitions)
        report.update(
            belief=task.belief,
            corners=list(task.corners),
            true_weights=[float(x) for x in task.true_weights],
            metrics=m,
        )
        print("metrics: " + "  ".join(f"{k}={v:.3f}" for k, v in m.items()))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        import io

        buf = io.BytesIO()
        np.savez(buf, mu=res.mu, alpha=res.alpha, transitions=res.transitions)
        atomic_write(args.out / "posterior.npz", buf.getvalue())
        atomic_write(args.out / "posterior.json", json.dumps(report, indent=2))
        _save_heatmaps(args.out / "posterior.png", task, res, simulated)
        print(f"posterior saved to {args.out}/posterior.npz (plot: posterior.png)")
    return 0


def _save_heatmaps(path: Path, task, res, simulated: bool) -> None:
    """Learned reward with the believed policy's arrows, next to the truth when it is known."""
    import numpy as np

    from .planning import boltzmann_policy
    from .plotting.heatmaps import save_reward_panels

    feats = np.asarray(task.mdp.features)
    panels = [("learned R, expected actions", feats @ res.mu)]
    policies = [np.asarray(boltzmann_policy(res.transitions, feats @ res.mu, task.mdp.discount))]
    if simulated:
        w = np.asarray(task.true_weights)
        panels.insert(0, ("true R_H, person's actions", feats @ w))
        policies.insert(0, np.asarray(boltzmann_policy(task.human_transitions, feats @ w, task.mdp.discount)))
    save_reward_panels(path, panels, task.size, policies)


if __name__ == "__main__":
    sys.exit(main())
