"""``mindgap eps``: explicable policy search (Algorithm 3) or its expectation-DRLHP baseline on a world.

mindgap eps --world d3 --lam 2 --queries 800 --steps 60000 --seeds 5 --out runs/eps-d3

Writes the outputs of ``mindgap sac`` (curve.csv, curve.png, trajectories.png, summary.json)
plus ``explicability.json`` (Eq. 4.4 per seed over stochastic rollouts, against the
simulated person's exact T_H and π_H) and ``surrogate.png``: the learned u_H per cell
(Fig. 28) beside the person's expected routes.

On a gym world the person's belief is learned from ``--belief-env`` (an unbiased person's from
the env itself), π_H is trained there on the host, and the explicability score reads a model
of the true env learned the same way (:mod:`~mindgap.algorithms.explicability_host`).
"""

from __future__ import annotations

import argparse

from ..algorithms.eps_config import eps_config
from ..feedback.queries import sampler_names
from .config_flags import add_config_flags, with_flags
from .learn import (
    RUN_FIELDS,
    add_belief_env_flag,
    add_env_flag,
    add_person_flags,
    add_queries_from_flag,
    add_run_flags,
    with_belief_env,
)


def add_parser(sub) -> None:
    p = sub.add_parser("eps", help="EPS: reconcile the task reward with what a person expects the robot to do")
    add_env_flag(p)
    p.add_argument("--lam", type=float, default=2.0, help="λ, the reconciliation factor of Eq. 4.6 (default 2)")
    p.add_argument("--method", default="eps", help="eps (default) or drlhp (u_H alone, the §4.4.1.1 baseline)")
    p.add_argument(
        "--person", default="biased", help="biased: the world's belief; unbiased: the person knows the dynamics"
    )
    p.add_argument("--belief", help="belief of a biased person (default: the world's first)")
    add_belief_env_flag(p)
    p.add_argument(
        "--teacher",
        help="study:STORE: people answer 'which is more expected?' live through the study app "
        "(mindgap study serve --db STORE; §4.4.2's training phase); default: the simulated --person",
    )
    p.add_argument(
        "--answer-timeout", type=float, default=600.0, help="study teacher: seconds to wait per round (default 600)"
    )
    p.add_argument("--queries", type=int, help="query budget (default 800)")
    p.add_argument("--per-round", type=int, help="queries per feedback round (default 80)")
    p.add_argument(
        "--sampler", default="disagreement", help=f"{', '.join(sampler_names(belief=False))} (default disagreement)"
    )
    add_queries_from_flag(p)
    add_person_flags(p)
    p.add_argument(
        "--nats-per-unit",
        type=float,
        help="s_H: nats of the person's per-step log-likelihood per unit of the standardised u_H; "
        "the policy entropy is weighted λ/s_H (default 7)",
    )
    p.add_argument(
        "--offset",
        default="cost",
        help="the λ-term's constant per step: cost (default: ≤ 0 on every step of the buffer, as the −KL it "
        "stands for), centred (u_H and H_T centred over the buffer: a bonus above average), none (u_H centred)",
    )
    p.add_argument(
        "--judged",
        choices=("transitions", "decisions"),
        default="transitions",
        help="what the person's expectation covers: transitions (log T_H + log π_H, default) or decisions "
        "(log π_H alone: H_T leaves the objective)",
    )
    p.add_argument(
        "--absorbing",
        choices=("single", "terminal"),
        help="u_H with absorbing states: an ended episode's λ-term goes on at what u_H learns the rest of "
        "an ended clip is worth (default: none)",
    )
    p.add_argument(
        "--surrogate",
        default="learned",
        help="learned: u_H from the person's answers (default); exact: the person's own log T_H + log π_H, "
        "no queries (an oracle ablation)",
    )
    p.add_argument("--rollouts", type=int, default=100, help="rollouts per seed for the explicability score")
    p.add_argument("--cache", help="where the person's expected policy π_H is cached (default ~/.cache/mindgap)")
    p.add_argument(
        "--fast", action="store_true", help="the quick preset (tiny networks, 1500 steps, a tiny π_H; for dry runs)"
    )
    add_run_flags(p)
    p.set_defaults(steps=None, hidden=None, learning_starts=None, batch=None)  # the preset's unless given
    hand = ("lam", "sampler", "queries_from", "offset", "absorbing", "judged", "surrogate", "queries", "per_round")
    add_config_flags(p, eps_config("full"), skip=RUN_FIELDS + hand + ("nats_per_unit",))


def run(args: argparse.Namespace) -> int:
    import json

    import numpy as np

    from .. import rng
    from .._io import atomic_write
    from ..algorithms.eps import train
    from ..algorithms.eps_maps import surrogate_maps
    from ..algorithms.expected_policy import ExpectedPolicyConfig, expectation_teacher
    from ..algorithms.explicability import explicability_scores
    from ..algorithms.explicability_host import explicability_scores_host
    from ..envs.gym_world import GymWorld
    from ..envs.resolve import resolve_env
    from ..envs.terrain import TerrainWorld
    from ..plotting.terrain import save_fields
    from ..teachers.learned_belief import BeliefFitConfig, fit_learned_belief
    from ..teachers.preference import TeacherConfig
    from .learn import fill_from_preset, sac_config, write_outputs

    if args.person not in ("biased", "unbiased"):
        raise ValueError(f"--person must be biased or unbiased, got {args.person!r}")
    if args.rollouts < 1:
        raise ValueError("--rollouts must be at least 1")
    world = resolve_env(args.env)
    gym = isinstance(world, GymWorld)
    if gym and args.person == "unbiased":
        if args.belief_env is not None:
            raise ValueError("an unbiased person believes the true env: drop --belief-env")
        args.belief_env = world.name  # a learned model of the env itself
    world = with_belief_env(world, args)
    preset = "fast" if args.fast else "full"
    base = eps_config(preset)
    fill_from_preset(args, base)
    over = dict(
        method=args.method,
        lam=args.lam,
        total_steps=args.steps,
        seed=args.seed,
        sac=sac_config(args),
        sampler=args.sampler,
        queries_from=args.queries_from,
        offset=args.offset,
        absorbing=args.absorbing,
        judged=args.judged,
        surrogate=args.surrogate,
        teacher=TeacherConfig(beta=args.beta, mistake=args.mistake),
    )
    for name in ("queries", "per_round", "nats_per_unit"):
        if getattr(args, name) is not None:
            over[name] = getattr(args, name)
    cfg = with_flags(eps_config(preset, **over), args)
    cfg.check()
    if args.teacher is not None:
        return _run_with_people(args, world, cfg, train, write_outputs)
    policy_cfg = ExpectedPolicyConfig.fast() if args.fast else ExpectedPolicyConfig()
    unbiased = args.person == "unbiased" and not gym  # on a gym world the unbiased person's belief is learned above
    person = expectation_teacher(
        world, args.belief, unbiased=unbiased, policy_cfg=policy_cfg, cache_dir=args.cache, progress=not args.quiet
    )
    res = train(
        world,
        cfg,
        person,
        seeds=args.seeds,
        out=args.out,
        progress=not args.quiet,
        fresh=args.fresh,
        person_name=args.person,
    )
    carry = res["carry"]
    if gym:  # T_A too is a learned model there: of the true env, fitted as the person's belief is
        fit = BeliefFitConfig.fast() if args.fast else BeliefFitConfig()
        truth, _ = fit_learned_belief(world, fit, cache_dir=args.cache)
        actors = carry.loop.sac.params.actor
        scores = explicability_scores_host(
            world, person, truth, actors, args.rollouts, seed=20_000 + args.seed, progress=not args.quiet
        )
    else:
        scores = explicability_scores(
            rng.key(20_000 + args.seed), world, person, carry.loop.sac.params.actor, args.rollouts
        )
    atomic_write(args.out / "explicability.json", json.dumps(scores, indent=2))
    label = f"{cfg.method} (λ {cfg.lam:g}, {args.person} person)" if cfg.method == "eps" else "drlhp (expectations)"
    expl = np.array([s["score"] for s in scores])
    summary = write_outputs(
        args.out,
        world,
        res,
        label,
        queries=0 if cfg.surrogate == "exact" else None,
        method=cfg.method,
        lam=cfg.lam,
        person=args.person,
        explicability_mean=float(expl.mean()),
        explicability_std=float(expl.std()),
        explicability_per_seed=expl.tolist(),
    )
    written = "curve.csv, trajectories.png, explicability.json"
    if isinstance(world, TerrainWorld):  # u_H drawn on the map (Fig. 28)
        u = surrogate_maps(carry, world.params, person, cfg)
        what = "learned u_H" if cfg.surrogate == "learned" else "the person's log T_H + log π_H"
        save_fields(
            args.out / "surrogate.png",
            world.params,
            [(f"{what} (standardised, {args.seeds} seed(s))", np.asarray(u).mean(0))],
            label="u_H",
            vmin=None,
            cmap="viridis",
        )
        written += ", surrogate.png"
    print(
        f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
        f"{summary['final_return_std']:.1f}, explicability {expl.mean():.1f} ± {expl.std():.1f} over "
        f"{args.seeds} seed(s), {summary['queries']} queries asked; {written} in {args.out}/"
    )
    return 0


def _run_with_people(args, world, cfg, train, write_outputs) -> int:
    """EPS asking people through a running study (``--teacher study:STORE``): the engine's host teacher.

    No simulated person is built, so there is no explicability score (Eq. 4.4 needs the person's
    own T_H and π_H, which people do not hand over); the answers are in the run's query dataset and
    in the study's export (``preferences.json``, protocol expectation).
    """
    from ..study.live import StudyTeacher

    if not args.teacher.startswith("study:"):
        raise ValueError(f"--teacher must be study:STORE, got {args.teacher!r}")
    if cfg.surrogate == "exact":
        raise ValueError("--surrogate exact reads a simulated person's models: drop --teacher study:STORE")
    host = StudyTeacher(args.teacher[len("study:") :], world, timeout=args.answer_timeout, progress=not args.quiet)
    res = train(world, cfg, host, seeds=args.seeds, out=args.out, progress=not args.quiet, fresh=args.fresh)
    label = f"{cfg.method} (λ {cfg.lam:g}, people through {host.name})" if cfg.method == "eps" else "drlhp (people)"
    summary = write_outputs(args.out, world, res, label, method=cfg.method, lam=cfg.lam, person=host.name)
    print(
        f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
        f"{summary['final_return_std']:.1f} over {args.seeds} seed(s), {summary['queries']} queries answered "
        f"in {len(host.batches)} round(s); curve.csv, trajectories.png in {args.out}/"
    )
    return 0
