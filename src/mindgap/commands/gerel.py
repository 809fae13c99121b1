"""``mindgap gerel``: GeReL (chapter 2) fitted to simulated or recorded ratings on the grid or the coffee domain.

On ``grid7`` it fits one simulated person (or a ratings file) and prints the learned reward
and believed action effects; ``--domain coffee`` is the coffee study's (:mod:`~.coffee`).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

DOMAINS = ("grid7", "coffee")


def add_parser(sub) -> None:
    """The ``gerel`` subcommand and its flags."""
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


def run(args) -> int:
    """Run ``mindgap gerel`` (the parsed ``args``)."""
    if args.domain == "coffee":
        from . import coffee

        return coffee.gerel(args)
    import jax
    import numpy as np

    from .. import rng
    from .._io import atomic_write
    from ..algorithms.gerel import GeReLConfig, fit_gerel
    from ..envs.grid import ACTIONS, MOVE_NAMES
    from ..experiments.table1 import belief_space
    from ..feedback.demos import random_demonstrations
    from ..feedback.ratings_file import read_ratings, write_ratings
    from ..metrics import all_metrics
    from ..planning.grid_task import make_grid
    from ..teachers.rating import RatingTeacher

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

    from ..planning import boltzmann_policy
    from ..plotting.heatmaps import save_reward_panels

    feats = np.asarray(task.mdp.features)
    panels = [("learned R, expected actions", feats @ res.mu)]
    policies = [np.asarray(boltzmann_policy(res.transitions, feats @ res.mu, task.mdp.discount))]
    if simulated:
        w = np.asarray(task.true_weights)
        panels.insert(0, ("true R_H, person's actions", feats @ w))
        policies.insert(0, np.asarray(boltzmann_policy(task.human_transitions, feats @ w, task.mdp.discount)))
    save_reward_panels(path, panels, task.size, policies)
