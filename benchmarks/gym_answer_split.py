"""Check: how the simulated person's score of a segment splits between its reward and its belief, per amount of noise.

On the noisy hopper and half-cheetah (:mod:`mindgap.envs.mujoco_noise`) the person believes the
robot reliable (§3.4.2.3: "a small amount of noise to some of the transitions"; the person's T_H is a
model fitted to the reliable env, :mod:`mindgap.teachers.learned_belief`), and scores a segment by
Σ r_H + Σ max(log T_H, floor) (Eq. 3.5 with the teacher's floor). Before any learner runs, this
measures on uniformly random actions (the learners' first steps, and the distribution the belief was
fitted on) how widely each half of that score spreads over 10-step windows (a query segment), for
the domain's noise (``share`` of the steps, ``scale`` of the velocities' perturbation) and for other
amounts: the share of steps the person's model puts at the floor, the spread of Σ r_H and of
Σ max(log T_H, floor), and their ratio; then the same with log T_H taken against the density of the
most expected outcome (the believed mean: log T_H(s' | s, a) − log T_H(μ(s, a) | s, a) =
−½ Σ ((s' − μ)/σ)², the person's surprise with the model's own sharpness, which differs from state
to state with no bias at all, taken out). A ratio far above 1 means the answers say mostly which segment
held more steps the person finds all but impossible, and carry r_H as a small remainder
(docs/experiments/gym.md, "What the answers carry", measures the same on the full run's buffers).
``0:0`` is the reliable env itself: the spread the belief's half has with no bias at all.
``--min-std`` raises the floor on the belief's spread (the fit's is 0.01 of the typical step's
change, as sharp as a model of a deterministic simulator gets): how the split depends on how sharp
the person's expectation is, which the dissertation leaves open.

    python benchmarks/gym_answer_split.py --world cheetah --noise 0:0 0.05:0.1 0.2:0.5
    python benchmarks/gym_answer_split.py --world hopper-fixed --steps 20000

The belief is the full preset's (fitted once and cached, as the runs fit it); the windows are
consecutive steps of episodes restarted when they end (a random hopper that terminates falls after
about twenty steps, so windows cross its episodes' ends; ``hopper-fixed`` is the cleaner measure).
"""

from __future__ import annotations

import argparse
import sys

import jax
import jax.numpy as jnp
import numpy as np

from gym_learned_reward import window_spread
from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.envs.interface import EnvError
from mindgap.experiments import prefbias_gym as gym
from mindgap.experiments.gym_claims import figure_domain
from mindgap.models.gaussian_dynamics import predict
from mindgap.teachers.learned_belief import collect, fit_learned_belief, learned_log_prob
from mindgap.teachers.preference import TeacherConfig

HOSTS = [name for name, d in gym.DOMAINS.items() if d.runtime == "host"]
"""The gym experiment's domains on the host loop (the ones with a learned belief)."""
NOISY = tuple(name for name in HOSTS if figure_domain(name) in ("hopper", "cheetah"))
"""The host domains whose truth is hidden noise (the lander's is a wind)."""
SEGMENT = 10
"""Steps per window: a query segment of the full preset."""


def split(world, belief, steps: int, seed: int) -> dict:
    """The figures of one world (module docstring) over ``steps`` random-action transitions."""
    obs, act, nxt = (jnp.asarray(x) for x in collect(world, steps, seed))
    r = np.asarray(jax.jit(jax.vmap(lambda o, a, o2: world.env.reward(o, a, o2, world.params)))(obs, act, nxt))
    log_prob = jax.jit(lambda o, a, o2: learned_log_prob(o, a, o2, belief))
    log_t = np.asarray(log_prob(obs, act, nxt))
    # the same density taken against its most expected outcome, the believed mean: −½ Σ ((s' − μ)/σ)²
    mode = jax.jit(lambda o, a: predict(belief.model, o, a, belief.min_std)[0])(obs, act)
    log_t_mode = np.asarray(log_prob(obs, act, mode))
    floor = TeacherConfig().log_t_floor
    sd_r = window_spread(r, SEGMENT)
    row = {"sd_r": sd_r}
    for name, lt in (("", log_t), ("_rel", log_t - log_t_mode)):
        scored = np.maximum(lt, floor)
        sd_b = window_spread(scored, SEGMENT)
        row |= {
            f"at_floor{name}": float((lt <= floor).mean()),
            f"mean_log_T{name}": float(scored.mean()),
            f"sd_belief{name}": sd_b,
            f"ratio{name}": sd_b / sd_r if sd_r > 0 else float("inf"),
        }
    return row


def _noise(text: str) -> tuple[float, float]:
    try:
        share, scale = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"noise must be SHARE:SCALE, e.g. 0.2:0.5, got {text!r}") from None
    if not (0.0 <= share <= 1.0 and scale >= 0.0):
        raise argparse.ArgumentTypeError(f"noise needs a share in [0, 1] and a scale ≥ 0, got {text!r}")
    return share, scale


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--world",
        default="cheetah",
        help=f"a host domain of the gym experiment: {', '.join(HOSTS)}",
    )
    p.add_argument(
        "--noise",
        type=_noise,
        nargs="+",
        default=[(0.0, 0.0), (0.05, 0.1), (0.05, 0.5), (0.2, 0.1), (0.2, 0.5)],
        help="SHARE:SCALE amounts of hidden noise to measure (noisy domains only; default: a grid with the domain's 0.2:0.5)",
    )
    p.add_argument(
        "--min-std",
        type=float,
        nargs="+",
        default=None,
        help="floors on the belief's spread, in units of the typical step's change (default: the fit's own, 0.01): "
        "a person who expects the robot only roughly where the reliable one would go",
    )
    p.add_argument("--steps", type=int, default=20_000, help="random-action transitions per amount")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--belief-env",
        default=None,
        help="fit the person's belief to this env spec instead of the domain's (e.g. the reliable hopper whose "
        "episodes do not end: gym:Hopper-v5,exclude_current_positions_from_observation=False,"
        "terminate_when_unhealthy=False)",
    )
    args = p.parse_args()
    if args.world not in gym.DOMAINS or gym.DOMAINS[args.world].runtime != "host":
        sys.exit(f"gym_answer_split: no host domain {args.world!r}: choose from {', '.join(HOSTS)}")
    if args.steps < 10 * SEGMENT:
        sys.exit(f"gym_answer_split: --steps must be at least {10 * SEGMENT}")
    cfg = gym.preset("full")
    if args.belief_env is None:
        world, _ = gym.load_world(args.world, cfg, progress=True)
        belief = next(iter(world.beliefs.values()))
    else:
        try:
            belief_world = gym_world_from_spec(gym._spec(args.belief_env, cfg.horizon))
            world = gym_world_from_spec(gym._spec(gym.domain(args.world).env, cfg.horizon))
            belief, record = fit_learned_belief(belief_world, cfg.belief_fit, true_world=world, progress=True)
        except (EnvError, ValueError) as e:
            sys.exit(f"gym_answer_split: {e}")
        print(f"belief fitted to {record['belief_env']}: held-out log-likelihood {record['held_out_log_lik']:.2f}")
    if args.min_std is not None and not all(m > 0 for m in args.min_std):
        sys.exit("gym_answer_split: --min-std must be positive")
    floors = [None] if args.min_std is None else args.min_std
    d = gym.domain(args.world)
    amounts = args.noise if args.world in NOISY else [None]
    print(
        "world | min std | share | scale | sd Σ r_H | steps at the floor | mean max(log T_H, floor) | sd Σ belief | ratio"
        " | the same against the most expected outcome: at the floor | mean | sd Σ belief | ratio"
    )
    for floor, amount in ((f, a) for f in floors for a in amounts):
        spec = d.env if amount is None else f"{d.env},share={amount[0]},scale={amount[1]}"
        variant = gym_world_from_spec(gym._spec(spec, cfg.horizon))
        held = belief if floor is None else belief._replace(min_std=jnp.float32(floor))
        row = split(variant, held, args.steps, args.seed)
        share, scale = ("–", "–") if amount is None else amount
        cells = [args.world, f"{float(held.min_std):g}", share, scale, f"{row['sd_r']:.2f}"]
        for k in ("", "_rel"):
            cells += [f"{row['at_floor' + k]:.3f}", f"{row['mean_log_T' + k]:.2f}", f"{row['sd_belief' + k]:.2f}"]
            cells.append(f"{row['ratio' + k]:.1f}")
        print(" | ".join(str(c) for c in cells))


if __name__ == "__main__":
    main()
