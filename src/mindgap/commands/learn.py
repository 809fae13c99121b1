"""``mindgap sac|pebble|drlhp``: train on a world, write the learning curve and routes.

mindgap pebble --env nav1 --teacher biased --queries 800 --steps 40000 --seeds 5 --out runs/pebble-nav1
mindgap pebble --env examples/point_mass.py:make_world --fast --out runs/pebble-point-mass
"""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path

from ..algorithms.engine import QUERIES_FROM, Schedule
from ..algorithms.pbrl import ABSORBING_DEFAULT, METHODS, method_config
from ..algorithms.sac import SACConfig
from ..feedback.queries import sampler_names
from ..sweeps.grid import SAC_FIELDS
from ..teachers.preference import TeacherConfig
from .config_flags import add_config_flags, with_flags

RUN_FIELDS = ("method", "total_steps", "seed", "teacher.beta", "teacher.mistake") + tuple(
    "sac." + f
    for f in (
        "hidden",
        "learning_starts",
        "utd",
        "batch_size",
        "n_step",
        "reward_scale",
        "noise_color",
        "entropy_bonus",
    )
)
"""The config fields that :func:`add_run_flags` and :func:`add_person_flags` set (``--steps``, ``--batch``, ``--beta``…):
the derived flags (:mod:`~.config_flags`) leave them out."""

FEEDBACK_FIELDS = ("queries", "per_round", "sampler", "queries_from", "absorbing", "absorbing_state")
"""The fields PEBBLE's and DRLHP's hand-made flags set."""


def add_parsers(sub) -> None:
    for method in METHODS:
        helps = {
            "sac": "SAC on the true reward (the oracle)",
            "pebble": "PEBBLE: state-entropy pre-training, then preferences with relabelling",
            "drlhp": "DRLHP: reward ensemble from preferences, SAC as the policy optimiser",
        }
        p = sub.add_parser(method, help=helps[method])
        add_env_flag(p)
        if method != "sac":
            p.add_argument(
                "--teacher",
                default="biased",
                help="biased: r_H + log T_H under the belief; unbiased: r_H + log T (the same person, no bias); "
                "true: r_H alone (the ordinary B-Pref teacher); "
                "study:STORE: people answering live through the study app (mindgap study serve --db STORE)",
            )
            p.add_argument(
                "--answer-timeout", type=float, default=600.0, help="study teacher: seconds to wait per round"
            )
            p.add_argument(
                "--preferences",
                type=Path,
                help="learn the reward offline from a preferences file (mindgap study export)",
            )
            p.add_argument("--belief", help="belief of a biased teacher (default: the world's first)")
            add_belief_env_flag(p)
            p.add_argument("--queries", type=int, help="query budget (default 800)")
            p.add_argument("--per-round", type=int, help="queries per feedback round (default 50)")
            p.add_argument("--sampler", default="disagreement", help=", ".join(sampler_names(belief=False)))
            add_queries_from_flag(p)
            add_person_flags(p)
            p.add_argument(
                "--absorbing",
                action=argparse.BooleanOptionalAction,
                default=None,
                help="absorbing-state treatment of goals and pits for the learned reward (Kostrikov et al. 2019): "
                "segments keep the steps after a terminal, the reward learns their value "
                f"(default: {'on' if ABSORBING_DEFAULT[method] else 'off'})",
            )
            p.add_argument(
                "--absorbing-state",
                choices=("terminal", "single"),
                help="with --absorbing: one absorbing state per terminal state (default: terminal) "
                "or the single one of Kostrikov et al. (single)",
            )
        p.add_argument(
            "--fast", action="store_true", help="the quick preset (tiny networks, 1500 steps, 30 queries; for dry runs)"
        )
        add_run_flags(p)
        p.set_defaults(steps=None, hidden=None, learning_starts=None, batch=None)  # the preset's unless given
        only = SAC_FIELDS if method == "sac" else ()  # the oracle asks nobody: no feedback settings
        add_config_flags(p, method_config(method), skip=RUN_FIELDS + FEEDBACK_FIELDS, only=only)


ENV_HELP = (
    "the world: a named terrain world (nav1, nav2, d1–d4), a world file, or a world of your own as "
    "path/to/file.py:factory or package.module:factory (keyword arguments after a comma: "
    "examples/point_mass.py:make_world,drift=0.1)"
)


def add_env_flag(p) -> None:
    """``--env`` (``--world`` is the same flag): see :mod:`~mindgap.envs.resolve`."""
    p.add_argument("--env", "--world", dest="env", required=True, metavar="ENV", help=ENV_HELP)


def add_belief_env_flag(p) -> None:
    """``--belief-env``: a gym world's person believes a learned model of another variant of the env."""
    p.add_argument(
        "--belief-env",
        metavar="SPEC",
        help="gym worlds: the env as the person imagines it (gym:ID,key=value, same spaces as --env); the "
        "person's believed dynamics are a Gaussian model fitted to its transitions (cached), or a saved model (.npz)",
    )


def with_belief_env(world, args: argparse.Namespace):
    """``world`` with the learned belief of ``--belief-env`` (unchanged without it); writes
    ``belief_model.json`` (the fit's record) into the run folder and prints its quality in one line."""
    spec = getattr(args, "belief_env", None)
    if spec is None:
        return world
    from .._io import atomic_write
    from ..envs.gym_world import GymWorld, gym_world_from_spec
    from ..teachers.learned_belief import BeliefFitConfig, fit_learned_belief, load_learned_belief, with_learned_belief

    if not isinstance(world, GymWorld):
        raise ValueError(f"--belief-env is for gym worlds; {world.name} states its beliefs itself (--belief)")
    if spec.endswith(".npz"):
        belief, record = load_learned_belief(spec)
    elif not spec.startswith("gym:"):
        raise ValueError(f"--belief-env takes gym:ID,key=value or a saved model (.npz), got {spec!r}")
    else:
        cfg = BeliefFitConfig.fast() if args.fast else BeliefFitConfig()
        belief, record = fit_learned_belief(
            gym_world_from_spec(spec),
            cfg,
            true_world=world,
            cache_dir=getattr(args, "cache", None),
            progress=not args.quiet,
        )
    if record["obs_dim"] != world.env.observation_space.dim or record["act_dim"] != len(world.act_low):
        raise ValueError(f"--belief-env {spec}: its model's observations or actions differ in size from {world.name}'s")
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out / "belief_model.json", json.dumps(record, indent=2))
    true_ll = ""
    if "true_log_lik" in record:
        true_ll = f", {record['true_log_lik']:.2f} on the true env's ({record['true_below_floor']:.0%} below the floor)"
    print(
        f"the person's believed dynamics: a model of {record['belief_env']} ({record['transitions']} transitions), "
        f"held-out log-likelihood {record['held_out_log_lik']:.2f} a transition{true_ll}; {record['path']}"
    )
    return with_learned_belief(world, record["belief_env"], belief)


def beta_value(text: str) -> float | None:
    """``--beta``: a positive rationality, or ``inf`` for deterministic answers (B-Pref's oracle)."""
    if text.strip().lower() in ("inf", "infinity", "deterministic"):
        return None
    try:
        beta = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number or inf, got {text!r}") from None
    if not beta > 0:
        raise argparse.ArgumentTypeError(f"beta must be positive (or inf), got {text!r}")
    return beta


def add_queries_from_flag(p) -> None:
    """``--queries-from``: where query segments start (:attr:`~mindgap.algorithms.engine.Schedule.queries_from`)."""
    p.add_argument(
        "--queries-from",
        choices=QUERIES_FROM,
        default="anywhere",
        help="where query segments start: anywhere in the replay buffer (default), or at an episode's start, "
        "so both segments of a pair show a behaviour from the world's starting situation",
    )


def add_person_flags(p) -> None:
    """How the simulated person answers: Bradley–Terry rationality β (Eq. 3.4) and B-Pref's mistakes."""
    beta = TeacherConfig().beta
    p.add_argument(
        "--beta",
        type=beta_value,
        default=beta,
        help=f"the person's Bradley–Terry rationality (default {beta}; inf: deterministic answers, "
        "under which the scale of the score, hence the belief, is not identified)",
    )
    p.add_argument("--mistake", type=float, default=0.0, help="the person's probability of a flipped answer")


def add_run_flags(p, steps: int = 40_000) -> None:
    """Flags every learning command shares: steps, seeds, the SAC settings, the run folder.

    The SAC defaults are the engine's (:attr:`~mindgap.algorithms.engine.Schedule.sac`, which
    explores with :data:`~mindgap.algorithms.engine.EXPLORATION`).
    """
    p.add_argument("--steps", type=int, default=steps, help=f"environment steps per seed (default {steps})")
    p.add_argument("--seeds", type=int, default=1, help="seeds, vmapped in one program (default 1)")
    p.add_argument("--seed", type=int, default=0, help="base seed")
    d = Schedule.sac
    hidden = ",".join(str(h) for h in d.hidden)
    p.add_argument("--hidden", default=hidden, help=f"hidden widths of actor and critics (default {hidden})")
    p.add_argument("--learning-starts", type=int, default=d.learning_starts, help="random steps before SAC updates")
    p.add_argument("--utd", type=int, default=d.utd, help=f"SAC updates per environment step (default {d.utd})")
    p.add_argument("--batch", type=int, default=d.batch_size, help=f"SAC batch size (default {d.batch_size})")
    p.add_argument(
        "--n-step", type=int, default=d.n_step, help=f"steps summed into each critic target (default {d.n_step})"
    )
    p.add_argument(
        "--reward-scale",
        type=float,
        default=d.reward_scale,
        help=f"factor on rewards in the critic target (default {d.reward_scale})",
    )
    p.add_argument(
        "--noise-color",
        type=float,
        default=d.noise_color,
        help="exponent β of the exploration noise's 1/f^β spectrum: 0 white (plain SAC), 1 pink, 2 red "
        f"(default {d.noise_color:g})",
    )
    p.add_argument(
        "--entropy-bonus",
        type=float,
        default=d.entropy_bonus,
        help="weight of a state-entropy bonus on the reward in training, halving every "
        f"{d.entropy_bonus_halflife} steps (default {d.entropy_bonus:g}{': off' if not d.entropy_bonus else ''})",
    )
    p.add_argument("--out", type=Path, required=True, help="run folder (reruns resume from its checkpoint)")
    p.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def fill_from_preset(args: argparse.Namespace, base) -> None:
    """Give the run flags left unset (None) the values of a preset config ``base`` (steps, SAC widths, …)."""
    defaults = dict(
        steps=base.total_steps,
        hidden=",".join(str(h) for h in base.sac.hidden),
        learning_starts=base.sac.learning_starts,
        batch=base.sac.batch_size,
    )
    for name, value in defaults.items():
        if getattr(args, name) is None:
            setattr(args, name, value)


def sac_config(args: argparse.Namespace) -> SACConfig:
    """The SAC settings of the command line."""
    try:
        hidden = tuple(int(x) for x in args.hidden.split(","))
    except ValueError:
        raise ValueError(f"--hidden must look like 128,128, got {args.hidden!r}") from None
    return SACConfig(
        hidden=hidden,
        learning_starts=args.learning_starts,
        utd=args.utd,
        batch_size=args.batch,
        reward_scale=args.reward_scale,
        n_step=args.n_step,
        noise_color=args.noise_color,
        entropy_bonus=args.entropy_bonus,
    )


def run(args: argparse.Namespace) -> int:
    from ..algorithms.pbrl import fast_config, method_config, train
    from ..envs.resolve import resolve_env

    if getattr(args, "preferences", None):
        from ..study.offline import run_offline

        return run_offline(args)
    world = resolve_env(args.env)
    if args.command != "sac":
        world = with_belief_env(world, args)
    preset = fast_config if args.fast else method_config
    base = preset(args.command)
    fill_from_preset(args, base)
    over = dict(total_steps=args.steps, seed=args.seed, sac=sac_config(args))
    teacher = "true"
    if args.command != "sac":
        over.update(
            queries=base.queries if args.queries is None else args.queries,
            per_round=base.per_round if args.per_round is None else args.per_round,
            sampler=args.sampler,
            queries_from=args.queries_from,
            teacher=TeacherConfig(beta=args.beta, mistake=args.mistake),
        )
        if args.absorbing is not None:
            over["absorbing"] = args.absorbing
        if args.absorbing_state is not None:
            over["absorbing_state"] = args.absorbing_state
        teacher = args.teacher
    host = None
    if teacher.startswith("study:"):
        from ..study.live import StudyTeacher

        host = StudyTeacher(teacher[len("study:") :], world, timeout=args.answer_timeout, progress=not args.quiet)
    elif teacher not in ("biased", "unbiased", "true"):
        raise ValueError(f"--teacher must be biased, unbiased, true or study:STORE, got {teacher!r}")
    cfg = with_flags(preset(args.command, **over), args)
    cfg.check()
    res = train(
        world,
        cfg,
        seeds=args.seeds,
        teacher=host or teacher,
        belief=getattr(args, "belief", None),
        out=args.out,
        progress=not args.quiet,
        fresh=args.fresh,
    )
    label = args.command if args.command == "sac" else f"{args.command} ({teacher} teacher)"
    summary = write_outputs(args.out, world, res, label, method=args.command, teacher=teacher)
    print(
        f"{label} on {world.name}: final return {summary['final_return_mean']:.1f} ± "
        f"{summary['final_return_std']:.1f} over {args.seeds} seed(s), {summary['queries']} queries; "
        f"curve.csv, curve.png, trajectories.png in {args.out}/"
    )
    return 0


def _save_rollout(out: Path, world, res: dict) -> None:
    """``rollout.gif`` of a gym world's run (see :func:`write_outputs`); an env that cannot draw itself gets a line."""
    import sys

    import jax

    from ..envs.gym_world import GymWorld

    if not isinstance(world, GymWorld):
        return
    from ..plotting.animation import rollout_frames, save_gif

    actor = jax.tree.map(lambda x: x[0], res["carry"].loop.sac.params.actor)
    try:
        frames, _ = rollout_frames(world, actor, seed=0)
        save_gif(out / "rollout.gif", frames)
    except Exception as e:  # the run's results stand without a picture
        print(f"no rollout.gif: {world.name} could not draw itself ({type(e).__name__}: {e})", file=sys.stderr)


def write_outputs(out: Path, world, res: dict, label: str, queries: int | None = None, **record) -> dict:
    """curve.csv, curve.png, trajectories.png and summary.json of a finished run; returns the summary.

    On a gym world also ``rollout.gif``: one greedy episode of seed 0's policy, drawn by the env
    (:mod:`~mindgap.plotting.animation`).

    ``queries`` overrides the count of queries shown that the curve ends on (the exact-surrogate
    EPS ablation asks none, while its rounds count their budget)."""
    from .._io import atomic_write
    from ..envs.terrain import TerrainWorld
    from ..plotting.learning import curve_stats, save_learning_curves
    from ..plotting.paths import save_paths
    from ..plotting.terrain import save_world

    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["seed", "env_steps", "return", "queries"])
    for seed, step, ret, q in res["curve"]:
        w.writerow([int(seed), int(step), f"{ret:.4f}", int(q)])
    atomic_write(out / "curve.csv", buf.getvalue())
    save_learning_curves(out / "curve.png", {label: res["curve"]}, title=f"{world.name}")
    paths = [p for seed_paths in res["paths"] for p in seed_paths]
    if isinstance(world, TerrainWorld):
        save_world(out / "trajectories.png", world.params, {label: paths}, title=f"{world.name}: {label}")
    else:
        save_paths(out / "trajectories.png", {label: paths}, title=f"{world.name}: {label}")
    _save_rollout(out, world, res)
    final = res["final_returns"]
    summary = {
        **record,
        "world": world.name,
        "final_return_mean": float(final.mean()),
        "final_return_std": float(final.mean(1).std()),
        "final_return_per_seed": [float(x) for x in final.mean(1)],
        "queries": int(curve_stats(res["curve"])[3][-1]) if queries is None else queries,
    }
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    return summary
