"""``mindgap prefbias``: PrefBias (Algorithm 2) on a terrain world; the outputs of ``mindgap pebble`` plus the belief.

mindgap prefbias --world nav1 --teacher biased --queries 800 --seeds 5 --out runs/prefbias-nav1

Writes curve.csv, curve.png, trajectories.png, summary.json and belief.png: the noise the
learned belief f_φ predicts at each cell (mean over seeds) beside the agent's dynamics
model f_ψ and the simulated person's own table.
"""

from __future__ import annotations

import argparse

from ..algorithms.prefbias import PrefBiasLoopConfig
from ..algorithms.prefbias_inference import PrefBiasConfig
from ..algorithms.prefbias_queries import SAMPLERS
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


def _on(flag: bool) -> str:
    return "on" if flag else "off"


def add_parser(sub) -> None:
    p = sub.add_parser(
        "prefbias", help="PrefBias: learn the reward and the person's belief about the dynamics together"
    )
    add_env_flag(p)
    p.add_argument(
        "--teacher",
        default="biased",
        help="biased: r_H + log T_H under the belief; unbiased: r_H + log T (the same person, no bias); "
        "true: r_H alone (the ordinary B-Pref teacher); "
        "study:STORE: people answering live through the study app (mindgap study serve --db STORE)",
    )
    p.add_argument("--answer-timeout", type=float, default=600.0, help="study teacher: seconds to wait per round")
    p.add_argument("--belief", help="belief of a biased teacher (default: the world's first)")
    add_belief_env_flag(p)
    p.add_argument("--queries", type=int, help="query budget (default 800)")
    p.add_argument("--per-round", type=int, help="queries per feedback round (default 50)")
    p.add_argument(
        "--sampler", default="preference_disagreement", help=f"{', '.join(SAMPLERS)} (default preference_disagreement)"
    )
    add_queries_from_flag(p)
    p.add_argument("--prior", default="dynamics", help="centre of the belief prior: dynamics (f_ψ, default) or random")
    p.add_argument("--explore-steps", type=int, help="state-entropy pre-training steps (default 4000, as PEBBLE)")
    p.add_argument(
        "--absorbing",
        action=argparse.BooleanOptionalAction,
        default=PrefBiasConfig.absorbing,
        help="absorbing states for the learned reward (Kostrikov et al. 2019): segments keep the steps after a "
        f"goal or pit and r_w learns what each terminal state is worth (default: {_on(PrefBiasConfig.absorbing)})",
    )
    p.add_argument(
        "--absorbing-state",
        choices=("terminal", "single"),
        default=PrefBiasConfig.absorbing_state,
        help="with --absorbing: one absorbing state per terminal state (default; worlds of at most 3 "
        "observation dimensions) or one for all (single: any world, e.g. a gym env)",
    )
    p.add_argument(
        "--stay-head",
        action=argparse.BooleanOptionalAction,
        default=PrefBiasConfig.stay_head,
        help="f_ψ and f_φ also predict the probability of not moving at all (stuck or bumped), a point mass "
        f"instead of a far tail of the Gaussian (default: {_on(PrefBiasConfig.stay_head)})",
    )
    add_person_flags(p)
    p.add_argument(
        "--fast", action="store_true", help="the quick preset (tiny networks, 1500 steps, 30 queries; for dry runs)"
    )
    add_run_flags(p, steps=PrefBiasLoopConfig.total_steps)
    p.set_defaults(steps=None, hidden=None, learning_starts=None, batch=None)  # the preset's unless given
    hand = ("queries", "per_round", "sampler", "queries_from", "explore_steps") + tuple(
        "prefbias." + f for f in ("belief_prior", "absorbing", "absorbing_state", "stay_head")
    )
    add_config_flags(p, PrefBiasLoopConfig(), skip=RUN_FIELDS + hand)


def run(args: argparse.Namespace) -> int:
    import dataclasses

    import numpy as np

    from ..algorithms.prefbias import prefbias_config, train
    from ..envs.resolve import resolve_env
    from ..envs.terrain import TerrainWorld
    from ..planning.terrain_maps import noise_maps, table_noise_map
    from ..plotting.terrain import save_fields
    from ..teachers.preference import TeacherConfig
    from .learn import fill_from_preset, sac_config, write_outputs

    world = resolve_env(args.env)
    world = with_belief_env(world, args)
    preset = "fast" if args.fast else "full"
    base = prefbias_config(preset) if args.fast else PrefBiasLoopConfig()
    fill_from_preset(args, base)
    sac = sac_config(args)
    over = dict(
        total_steps=args.steps,
        seed=args.seed,
        sac=sac,
        sampler=args.sampler,
        queries_from=args.queries_from,
        prefbias=dataclasses.replace(
            base.prefbias,
            belief_prior=args.prior,
            absorbing=args.absorbing,
            absorbing_state=args.absorbing_state,
            stay_head=args.stay_head,
        ),
        teacher=TeacherConfig(beta=args.beta, mistake=args.mistake),
    )
    for name, flag in (("queries", "queries"), ("per_round", "per_round"), ("explore_steps", "explore_steps")):
        if getattr(args, flag) is not None:
            over[name] = getattr(args, flag)
    cfg = with_flags(prefbias_config(preset, **over), args)
    cfg.check()
    teacher, host = args.teacher, None
    if teacher.startswith("study:"):
        from ..study.live import StudyTeacher

        host = StudyTeacher(teacher[len("study:") :], world, timeout=args.answer_timeout, progress=not args.quiet)
    elif teacher not in ("biased", "unbiased", "true"):
        raise ValueError(f"--teacher must be biased, unbiased, true or study:STORE, got {teacher!r}")
    res = train(
        world,
        cfg,
        seeds=args.seeds,
        teacher=host or teacher,
        belief=args.belief,
        out=args.out,
        progress=not args.quiet,
        fresh=args.fresh,
    )
    label = f"prefbias ({teacher} teacher)"
    if not isinstance(world, TerrainWorld):  # no map to draw the belief on
        summary = write_outputs(args.out, world, res, label, method="prefbias", teacher=teacher, sampler=cfg.sampler)
        print(
            f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
            f"{summary['final_return_std']:.1f} over {args.seeds} seed(s), {summary['queries']} queries; "
            f"curve.csv, curve.png, trajectories.png in {args.out}/"
        )
        return 0
    belief_noise, dynamics_noise = (
        np.asarray(m) for m in noise_maps(res["carry"], world.params, cfg.prefbias.dynamics.min_std)
    )
    learned = belief_noise.mean(0)  # NaN on walls
    person = world.belief(args.belief) if teacher == "biased" else world.params
    target = np.asarray(table_noise_map(person))
    rms = float(np.sqrt(np.nanmean((belief_noise - target) ** 2, axis=(1, 2))).mean())
    summary = write_outputs(
        args.out,
        world,
        res,
        label,
        method="prefbias",
        teacher=teacher,
        sampler=cfg.sampler,
        prior=cfg.prefbias.belief_prior,
        belief_noise_rms_error=rms,
    )
    save_fields(
        args.out / "belief.png",
        world.params,
        [
            ("agent's dynamics model f_ψ", dynamics_noise.mean(0)),
            (f"learned belief f_φ ({args.seeds} seed(s))", learned),
            ("the person's belief" if teacher == "biased" else "true dynamics", target),
        ],
        label="noise σ (cells)",
    )
    print(
        f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
        f"{summary['final_return_std']:.1f} over {args.seeds} seed(s), {summary['queries']} queries; "
        f"belief noise RMS error {rms:.3f} cells; curve.csv, curve.png, trajectories.png, belief.png in {args.out}/"
    )
    return 0
