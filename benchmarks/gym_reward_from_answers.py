"""Check: what each preference learner's reward learns from the person's answers alone, for a sharper or blunter person.

The full run's learners fail to find the reward on the hopper and the cheetah, and "What the
answers carry" (docs/experiments/gym.md) measures why: the person's belief half of a segment's
score (Σ max(log T_H, floor), Eq. 3.5) spreads many times as widely as her reward half (Σ r_H),
and how many times depends on how sharply she expects the robot (``--min-std``, the floor on her
belief's spread; the fit's own is 0.01 of a typical step's change). This check takes the policy,
the query sampler and the schedule out of the question and asks only the reward learning: on
``--steps`` transitions of uniformly random actions (the buffer a learner holds after its first
steps) cut into 10-step windows (a query segment of the full preset), it draws ``--queries``
random pairs from the first 80% of the windows, has the person answer them (the run's
``TeacherConfig``: Bradley–Terry, β = 1) or flips a coin, and fits on all of them at once:

* PrefBias's q(w) q(φ) (:func:`~mindgap.algorithms.prefbias_inference.fit`, the full preset's
  config, its prior centred on an f_ψ trained on the same transitions, as its last feedback
  round fits them);
* PEBBLE's reward ensemble (:func:`~mindgap.models.reward_ensemble.train_reward`, the full preset's).

``--variant 'FIELD=VALUE …'`` (repeatable) fits PrefBias again with those config fields changed,
``--scale-prior-std`` and ``--log-f-floor`` with those, ``--updates`` with more rounds, and ``--oracle``
each of them told the person's belief (f_φ's prior centred on her model, with her floors: at r_w = r_H
its score is hers exactly), which asks whether reaching her belief is all PrefBias lacks.

On the held-out last 20% of the windows it prints, per person and learner, the correlation of the
learned Σ r_w with Σ r_H (did it learn the reward?) and with the belief half Σ max(log T_H, floor)
(did it learn the belief's half instead?), and the share of held-out window pairs r_w orders as
r_H does (0.5: no better than chance). Beside the persons with a belief: one who scores Σ r_H
alone (the most the answers can teach at this many queries) and coin flips (the least). Then, per
person and PrefBias variant, how Σ log f_φ compares with her belief half (at f_ψ and at the posterior
mean; for the rows without a belief, the run's person's half), and how far one draw of f_φ from q
moves a window's Σ log f_φ, at the start of the fit and after it (the likelihood of each answer is
taken under one draw: SPEC's condition that the belief posterior's draws stay well inside what they
must tell apart). Means ± standard deviations over ``--seeds`` (each seed draws fresh pairs, answers
and initialisations; the transitions are shared). Not a run's figures: the learners see the robot's
own steps, not random ones, and pick their queries; what it does show is whether the answers about
random steps carry r_H to each learner at each sharpness.

    python benchmarks/gym_reward_from_answers.py --world hopper-fixed --min-std 0.01 0.1 1
    python benchmarks/gym_reward_from_answers.py --world cheetah --seeds 3 --queries 800
    python benchmarks/gym_reward_from_answers.py --world hopper-fixed --min-std 0.01 --persons belief --oracle
        --variant "init_std=0.001 belief_prior_std=0.001"   (one command)
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.algorithms.prefbias_inference import fit, prefbias_init, scored_log_f
from mindgap.commands.design import prefbias_overrides
from mindgap.data.prefs import prefs_add, prefs_init
from mindgap.data.segments import Segments
from mindgap.experiments import prefbias_gym as gym
from mindgap.models.gaussian_dynamics import dynamics_init, fit_norm, train_dynamics
from mindgap.models.prefbias_nets import draw_per_pair, posterior_reward
from mindgap.models.reward_ensemble import ensemble_reward, reward_init, train_reward
from mindgap.teachers.learned_belief import collect, learned_log_prob, with_learned_belief
from mindgap.teachers.preference import answer

SEGMENT = 10
"""Steps per window: a query segment of the full preset."""
HELD = 0.2
"""Share of the windows (the last ones) kept out of the queries, on which the learned rewards are scored."""


def windows(obs, act, nxt) -> Segments:
    """Consecutive ``SEGMENT``-step windows of the transitions, as segments (every step real)."""
    k = len(obs) // SEGMENT
    cut = lambda x: jnp.asarray(x[: k * SEGMENT].reshape(k, SEGMENT, -1))  # noqa: E731
    return Segments(cut(obs), cut(act), cut(nxt), jnp.ones((k, SEGMENT), bool))


def _corr(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.corrcoef(x, y)[0, 1]) if x.std() > 0 and y.std() > 0 else float("nan")


def _order(x: np.ndarray, y: np.ndarray, rng: np.random.Generator, pairs: int = 20_000) -> float:
    """Share of random pairs of windows whose order by ``x`` is their order by ``y``."""
    i, j = rng.integers(0, len(x), (2, pairs))
    keep = (y[i] != y[j]) & (i != j)
    return float(((x[i] > x[j]) == (y[i] > y[j]))[keep].mean())


def _cells(rows: list) -> list[str]:
    v = np.asarray(rows)
    return [f"{v[:, j].mean():+.2f} ± {v[:, j].std():.2f}" for j in range(v.shape[1])]


def oracle(pcfg, belief, floor: float):
    """PrefBias told the person's belief: f_φ's prior centred on her model (no stay head, as hers has none),
    with her floor on σ and on the log density, so that at r_w = r_H its score is hers exactly."""
    dynamics = dataclasses.replace(pcfg.dynamics, min_std=float(belief.min_std))
    return dataclasses.replace(pcfg, stay_head=False, log_f_floor=floor, dynamics=dynamics)


def learn(
    world, seg: Segments, n_train: int, held: Segments, labels_for, queries: int, seed: int, cfg, dyn, variants: dict
):
    """Both learners' rewards from one seed's answers to pairs of the first ``n_train`` windows (PrefBias once per
    config of ``variants``, by name), scored on ``held`` (the other windows as one run of steps).

    Returns:
        (their window sums on the held-out windows, with PrefBias's Σ log f_φ at its prior's centre and
        posterior mean; per PrefBias variant, :func:`draw_spread` at the start of the fit and after it).
    """
    lcfg = cfg.learners
    key = jax.random.key(seed)
    k_pair, k_ans, k_pb, k_fit, k_pe, k_tr = jax.random.split(key, 6)
    ia, ib = jax.random.randint(k_pair, (2, queries), 0, n_train)
    take = lambda idx: jax.tree.map(lambda x: x[idx], seg)  # noqa: E731
    seg_a, seg_b = take(ia), take(ib)
    label = labels_for(k_ans, seg_a, seg_b)
    d, a = seg.obs.shape[-1], seg.act.shape[-1]
    data = prefs_init(queries, SEGMENT, d, a, absorbing=True)
    data = prefs_add(data, seg_a, seg_b, label, jnp.ones(queries, bool))
    out, noise = {}, {}
    for v, pcfg in variants.items():
        centre = dyn
        if isinstance(pcfg, tuple):  # (config, the person's belief): the oracle prior
            pcfg, centre = pcfg[0], pcfg[1].model
        state = prefbias_init(k_pb, d, a, pcfg, centre, world.obs_units())
        noise[v] = [draw_spread(state, pcfg, held)]
        state, _ = jax.jit(fit, static_argnames="cfg")(state, data, k_fit, cfg=pcfg)
        noise[v].append(draw_spread(state, pcfg, held))
        out[v] = np.asarray(posterior_reward(state.reward.mean, held.obs, held.act, held.next_obs))
        prior_name = "log_f_prior" if centre is dyn else None  # f_ψ's, the same for every variant centred on it
        for name, phi in ((prior_name, state.belief_prior), (f"log_f {v}", state.belief.mean)):
            if name is not None:
                out[name] = np.asarray(scored_log_f(phi, state.norm, held, pcfg, state.log_unit))
    rcfg = lcfg.pebble.reward
    rstate = reward_init(k_pe, d, a, rcfg, absorbing=lcfg.pebble.absorbing_state)
    rstate, _, _ = jax.jit(train_reward, static_argnames="cfg")(rstate, data, k_tr, cfg=rcfg)
    out["pebble"] = np.asarray(ensemble_reward(rstate.params, held.obs, held.act, held.next_obs))
    return {k: v.reshape(-1, SEGMENT).sum(1) for k, v in out.items()}, noise


def draw_spread(state, pcfg, held: Segments, draws: int = 32) -> float:
    """How far one draw of f_φ from q moves a window's Σ log f_φ: the standard deviation over ``draws`` draws,
    averaged over the held-out windows (what the likelihood of one answer sees besides the two segments)."""
    phis = draw_per_pair(state.belief, jax.random.key(7), draws)
    lf = jax.vmap(lambda phi: scored_log_f(phi, state.norm, held, pcfg, state.log_unit))(phis)
    return float(np.asarray(lf).reshape(draws, -1, SEGMENT).sum(-1).std(0).mean())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--world", default="hopper-fixed", help="a noisy host domain: hopper, cheetah, hopper-fixed")
    p.add_argument(
        "--min-std",
        type=float,
        nargs="+",
        default=[0.01, 1.0],
        help="floors on the person's belief's spread, in units of the typical step's change (0.01: the fit's own, "
        "the full run's person)",
    )
    p.add_argument(
        "--scale-prior-std",
        type=float,
        nargs="*",
        default=[],
        help="also fit PrefBias with these priors on f_φ's spread (PrefBiasConfig.scale_prior_std), beside its default",
    )
    p.add_argument(
        "--log-f-floor",
        type=float,
        default=None,
        help="also fit each PrefBias variant with this floor on log f_φ (PrefBiasConfig.log_f_floor; the person's is -20)",
    )
    p.add_argument(
        "--variant",
        action="append",
        default=[],
        help="also fit PrefBias with these PrefBiasConfig fields changed, e.g. 'init_std=0.001 belief_prior_std=0.001' "
        "(repeatable)",
    )
    p.add_argument(
        "--oracle",
        action="store_true",
        help="also fit each PrefBias variant told the person's belief (f_φ's prior centred on it): whether reaching the "
        "belief is what it lacks",
    )
    p.add_argument(
        "--updates", type=int, default=None, help="PrefBias's rounds per fit (default: the full preset's, 300)"
    )
    p.add_argument(
        "--persons",
        nargs="+",
        choices=("reward", "belief", "coin"),
        default=["reward", "belief", "coin"],
        help="whose answers: the reward-only person, the persons of --min-std, coin flips (default: all)",
    )
    p.add_argument("--steps", type=int, default=20_000, help="random-action transitions")
    p.add_argument("--queries", type=int, default=800, help="answered pairs per seed (the full run's largest budget)")
    p.add_argument("--seeds", type=int, default=3)
    args = p.parse_args()
    if args.world not in ("hopper", "cheetah", "hopper-fixed"):
        sys.exit(
            f"gym_reward_from_answers: no noisy host domain {args.world!r}: choose from hopper, cheetah, hopper-fixed"
        )
    if args.steps < 50 * SEGMENT or args.queries < 1 or args.seeds < 1:
        sys.exit(f"gym_reward_from_answers: --steps must be at least {50 * SEGMENT}; --queries and --seeds at least 1")
    if not all(m > 0 for m in [*args.min_std, *args.scale_prior_std]):
        sys.exit("gym_reward_from_answers: --min-std and --scale-prior-std must be positive")
    cfg = gym.preset("full")
    world, _ = gym.load_world(args.world, cfg, progress=True)
    name, belief = next(iter(world.beliefs.items()))
    obs, act, nxt = collect(world, args.steps, 0, progress=True)
    seg = windows(obs, act, nxt)
    n_train = int(seg.obs.shape[0] * (1 - HELD))
    held = jax.tree.map(lambda x: x[n_train:].reshape(-1, *x.shape[2:]), seg)  # scored, never queried: steps [N, ·]
    r_h = np.asarray(
        jax.vmap(lambda o, a, o2: world.env.reward(o, a, o2, world.params))(held.obs, held.act, held.next_obs)
    )
    r_h = r_h.reshape(-1, SEGMENT).sum(1)
    # f_ψ, the centre of PrefBias's belief prior, trained on the same transitions (as its feedback rounds train it)
    dcfg = cfg.learners.prefbias.prefbias.dynamics
    stay = cfg.learners.prefbias.prefbias.stay_head
    o, a_, o2 = (jnp.asarray(x) for x in (obs, act, nxt))
    valid = jnp.ones(len(obs), bool)
    norm = fit_norm(o, a_, o2, valid)
    dyn0 = dynamics_init(jax.random.key(1), o.shape[-1], a_.shape[-1], dcfg, norm, stay=stay)
    dyn, _ = train_dynamics(jax.random.key(2), o, a_, o2, valid, dcfg, init=dyn0)
    base = cfg.learners.prefbias.prefbias
    if args.updates is not None:
        if args.updates < base.check_every or args.updates % base.check_every:
            sys.exit(f"gym_reward_from_answers: --updates must be a positive multiple of {base.check_every}")
        base = dataclasses.replace(base, updates=args.updates)
    variants = {"prefbias": base} | {
        f"prefbias, σ prior {x:g}": dataclasses.replace(base, scale_prior_std=x) for x in args.scale_prior_std
    }
    for text in args.variant:
        try:
            over = prefbias_overrides(text.split())
            variants[f"prefbias, {text}"] = dataclasses.replace(base, **over)
            variants[f"prefbias, {text}"].check()
        except (TypeError, ValueError) as e:
            sys.exit(f"gym_reward_from_answers: --variant {text!r}: {e}")
    if args.log_f_floor is not None:  # each variant again with f_φ's log density floored as the person's is
        variants |= {
            f"{k}, floor {args.log_f_floor:g}": dataclasses.replace(v, log_f_floor=args.log_f_floor)
            for k, v in variants.items()
        }
    tcfg = dataclasses.replace(cfg.learners.prefbias.teacher, use_belief=True)
    rng = np.random.default_rng(0)
    print(
        f"{args.world}: {args.steps} random steps, {seg.obs.shape[0] - n_train} held-out windows, {args.queries} queries"
    )
    print("person | learner | corr(Σ r_w, Σ r_H) | corr(Σ r_w, Σ belief half) | r_H's order kept")
    beliefs, draws = {}, {}
    persons = (
        [("reward only", "true")] * ("reward" in args.persons)
        + [(f"min std {m:g}", m) for m in args.min_std] * ("belief" in args.persons)
        + [("coin flips", None)] * ("coin" in args.persons)
    )
    for label_name, m in persons:
        held_belief = belief if not isinstance(m, float) else belief._replace(min_std=jnp.float32(m))
        person = with_learned_belief(world, name, held_belief)
        log_t = np.asarray(
            jax.jit(lambda o, a, o2: learned_log_prob(o, a, o2, held_belief))(held.obs, held.act, held.next_obs)
        )
        b_half = np.maximum(log_t, tcfg.log_t_floor).reshape(-1, SEGMENT).sum(1)
        if m == "true":  # the person without a belief: Σ r_H alone (what an unbiased teacher teaches)
            labels_for = lambda k, sa, sb, w=person: answer(  # noqa: E731
                k, sa, sb, w.env, w.params, None, dataclasses.replace(tcfg, use_belief=False)
            )[0]
        elif m is None:
            labels_for = lambda k, sa, sb: jax.random.bernoulli(k, 0.5, (sa.obs.shape[0],)).astype(jnp.float32)  # noqa: E731
        else:
            labels_for = lambda k, sa, sb, w=person, bp=held_belief: answer(  # noqa: E731
                k, sa, sb, w.env, w.params, bp, tcfg
            )[0]
        variants_here = dict(variants)
        if args.oracle:  # each variant again, told her belief
            for k, v in variants.items():
                variants_here[f"{k}, prior at her belief"] = (oracle(v, held_belief, tcfg.log_t_floor), held_belief)
        learners = [*variants_here, "pebble"]
        rows = {k: [] for k in [*learners, "log_f_prior", *(f"log_f {v}" for v in variants_here)]}
        for s in range(args.seeds):
            sums, noise = learn(world, seg, n_train, held, labels_for, args.queries, 100 + s, cfg, dyn, variants_here)
            for k, v in noise.items():
                draws.setdefault((label_name, k), []).append(v)
            for k in learners:
                rows[k].append((_corr(sums[k], r_h), _corr(sums[k], b_half), _order(sums[k], r_h, rng)))
            for k in rows.keys() - set(learners):
                rows[k].append((_corr(sums[k], b_half), sums[k].std() / b_half.std(), sums[k].std() / r_h.std()))
        for k in learners:
            print(" | ".join([label_name, k, *_cells(rows[k])]), flush=True)
        beliefs[label_name] = {k: _cells(rows[k]) for k in rows.keys() - set(learners)}
        beliefs[label_name]["ratio"] = b_half.std() / r_h.std()
    print(
        "\nperson | sd Σ belief half / sd Σ r_H | f_φ | PrefBias's Σ log f_φ: corr with the person's belief half"
        " | its sd / the half's | its sd / Σ r_H's"
    )
    for label_name, cells in beliefs.items():
        ratio = cells.pop("ratio")
        for k in sorted(cells):
            where = "the prior's centre (f_ψ)" if k == "log_f_prior" else f"posterior mean, {k[6:]}"
            print(" | ".join([label_name, f"{ratio:.1f}", where, *cells[k]]))
    print(
        f"\nperson | PrefBias | sd over 32 draws of f_φ of a held-out window's Σ log f_φ: at the start | after the fit"
        f" (the windows' sd of Σ r_H: {r_h.std():.1f})"
    )
    for (label_name, k), v in draws.items():
        print(" | ".join([label_name, k, *_cells(v)]))


if __name__ == "__main__":
    main()
