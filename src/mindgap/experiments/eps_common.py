"""What the EPS experiments ``eps`` and ``lambda`` share (dissertation §4.4).

* **Learners** on one schedule: EPS (Algorithm 3, :mod:`~mindgap.algorithms.eps`), DRLHP on
  the same expectation preferences (``method="drlhp"``), SAC on the task reward r_A (the
  engine's ``sac``, the same steps, chunks, evaluation and SAC settings), and Policy
  Shaping — the normalised product of the SAC and DRLHP policies of the same seed
  (:mod:`~mindgap.algorithms.policy_shaping`), which trains nothing of its own.
* **The simulated person** of each world (:func:`~mindgap.algorithms.expected_policy.expectation_teacher`):
  the world's belief and an expected policy π_H trained in it, cached on disk. Its job,
  ``WORLD/person``, records the routes the person expects (π_H's greedy rollouts in the
  world as they imagine it: Fig. 27's left column), what obeying them would earn in the
  real world, and the planning check's optimal route (the yardstick of a detour).
* **Jobs** in a :class:`~._runfolder.RunFolder`, run in order (Policy Shaping reads the
  SAC and DRLHP actors its predecessors stored); each learner vmaps its seeds in one call
  and resumes from its engine checkpoint.
* **Evaluation** of every policy, per seed: ``rollouts`` stochastic episodes in the true
  world give the mean return (Table 3) and the explicability score −KL(p_A ‖ p_A^H) against
  the person's exact T_H and π_H (Eq. 4.4, Table 4) — the same episodes for both, since a
  deterministic policy has no finite explicability; greedy rollouts give the routes drawn
  and judged (:func:`required_route`).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..algorithms import eps as eps_alg
from ..algorithms import pbrl
from ..algorithms.eps_config import EPSConfig, eps_config
from ..algorithms.eps_maps import surrogate_maps
from ..algorithms.expected_policy import ExpectedPolicyConfig, expectation_teacher
from ..algorithms.explicability import explicability, explicability_scores
from ..algorithms.policy_shaping import ShapedPolicy, shaped_dist, shaped_greedy
from ..algorithms.sac import sac_init
from ..algorithms.sac_loop import dims, evaluate, rollouts
from ..checkpoint import load_pytree, save_pytree
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import RunFolder

PERSONS = ("biased", "unbiased")


@dataclasses.dataclass(frozen=True)
class EPSLearners:
    """The learners of an EPS experiment and how their policies are measured."""

    eps: EPSConfig
    """EPS's configuration (λ is set per job; DRLHP is the same with ``method="drlhp"``)."""
    sac: pbrl.PbRLConfig
    """SAC on the task reward, on EPS's schedule."""
    person: ExpectedPolicyConfig = ExpectedPolicyConfig()
    """How the simulated person's π_H is trained (once per world and belief; cached)."""
    rollouts: int = 100
    """Stochastic episodes per seed for the return and explicability score (Tables 3–4)."""
    paths: int = 10
    """Greedy rollouts per seed drawn on the maps (and used to judge routes)."""
    plan_resolution: int = 4
    """Sub-cells per cell side of the planning check that gives the optimal route."""


def learners(preset: str) -> EPSLearners:
    """``full``: EPS's defaults (60 000 steps, 800 queries, 80 a round, λ 2) and a π_H of 60 000
    steps; ``fast``: :func:`~mindgap.algorithms.eps_config.eps_config` ``("fast")``, a tiny π_H and 10 rollouts."""
    if preset == "full":
        e, person, roll, paths, res = eps_config("full"), ExpectedPolicyConfig(), 100, 10, 4
    elif preset == "fast":
        e, person, roll, paths, res = eps_config("fast"), ExpectedPolicyConfig.fast(), 10, 3, 2
    else:
        raise ValueError(f"unknown preset {preset!r}: use 'fast' or 'full'")
    names = ("total_steps", "chunk", "eval_every", "eval_episodes", "sac", "seed")
    sac = pbrl.method_config("sac", **{n: getattr(e, n) for n in names})
    return EPSLearners(e, sac, person, roll, paths, res)


# ---------------------------------------------------------------------------------------
# jobs


def person_job(world: str, learn: EPSLearners, person: str = "biased") -> pc.Job:
    cfg = (learn.person, learn.rollouts, learn.paths, learn.plan_resolution)
    return pc.Job(f"{world}/person-{person}", world, "person", f"person ({person})", cfg, {"person": person})


def sac_job(world: str, learn: EPSLearners) -> pc.Job:
    return pc.Job(f"{world}/sac", world, "sac", "SAC", learn.sac, {"person": "biased"})


def eps_job(world: str, learn: EPSLearners, lam: float, person: str = "biased") -> pc.Job:
    """EPS with reconciliation factor ``lam`` learning from a ``person``: biased, unbiased, or ``coin``
    (the biased person at β = 0, :func:`~.prefbias_common.coin_flips`: every answer a fair coin)."""
    name = f"eps-lam{lam:g}" + ("" if person == "biased" else f"-{person}")
    label = {"biased": "EPS", "coin": "EPS (coin-flip answers)"}.get(person, f"EPS ({person} person)")
    cfg = dataclasses.replace(learn.eps, method="eps", lam=float(lam))
    if person == "coin":
        cfg = pc.coin_flips(cfg)
    return pc.Job(f"{world}/{name}", world, "eps", label, cfg, {"lam": float(lam), "person": person})


def drlhp_job(world: str, learn: EPSLearners) -> pc.Job:
    cfg = dataclasses.replace(learn.eps, method="drlhp")
    return pc.Job(f"{world}/drlhp", world, "drlhp", "DRLHP", cfg, {"person": "biased"})


def shaping_job(world: str, learn: EPSLearners) -> pc.Job:
    """Policy Shaping of the ``sac`` and ``drlhp`` jobs' policies (both must come before it)."""
    sources = (f"{world}/sac", f"{world}/drlhp")
    return pc.Job(f"{world}/shaping", world, "shaping", "Policy Shaping", sources, {"person": "biased"})


def _person(world, learn: EPSLearners, name: str):
    return expectation_teacher(world, unbiased=name == "unbiased", policy_cfg=learn.person)


def compute(learn: EPSLearners):
    """The ``compute`` of :func:`~.prefbias_common.run_jobs` for these experiments."""

    def run(folder: RunFolder, job: pc.Job, seeds: int, *, fresh: bool, progress: bool) -> dict:
        world = wm.experiment_world(job.world, "this experiment")
        person = _person(world, learn, job.tags["person"])
        if job.method == "person":
            return _person_record(world, person, learn)
        if job.method == "shaping":
            return _shaping_record(folder, world, person, learn, job, seeds)
        res = train(world, job, seeds, pc.job_dir(folder, job), person, fresh=fresh, progress=progress)
        save_pytree(_actor_path(folder, job.key), res["actor"])
        return learned_record(world, person, learn, res, seed=job.cfg.seed)

    return run


def run_experiment(cfg, out, jobs: list[pc.Job], write_outputs, **kw) -> dict:
    """:func:`~.prefbias_common.run_experiment` with these experiments' jobs (``cfg.learners``'s)."""
    return pc.run_experiment(cfg, out, jobs, write_outputs, compute=compute(cfg.learners), references=("person",), **kw)


def train(world, job: pc.Job, seeds: int, out, person, *, fresh: bool, progress: bool) -> dict:
    """Train one learner's seeds; its results as :func:`learned_record` reads them.

    Returns:
        dict: ``curve``, ``final_returns`` [seeds, episodes], ``paths`` (greedy, per seed),
        ``actor`` (SAC actors, a leading seed axis) and ``u_map`` (EPS/DRLHP: the learned
        u_H per position, mean over seeds; else None).
    """
    kw = dict(seeds=seeds, out=out, progress=progress, fresh=fresh)
    if job.method == "sac":
        res = pbrl.train(world, job.cfg, teacher="true", **kw)
        u_map = None
    else:
        res = eps_alg.train(world, job.cfg, person, person_name=job.tags["person"], **kw)
        c = res["carry"]
        u_map = np.asarray(surrogate_maps(c, world.params, person, job.cfg)).mean(0) if wm.has_map(world) else None
    return {
        **{k: res[k] for k in ("curve", "final_returns", "paths")},
        "actor": res["carry"].loop.sac.params.actor,
        "u_map": u_map,
    }


def learned_record(world, person, learn: EPSLearners, res: dict, seed: int = 0) -> dict:
    """A learner's record: curve, greedy returns and routes, and per seed the stochastic
    rollouts' return and explicability score."""
    final = np.asarray(res["final_returns"], np.float64)
    if not np.all(np.isfinite(final)):
        raise FloatingPointError("non-finite returns: the run diverged")
    scores = explicability_scores(rng.key(20_000 + seed), world, person, res["actor"], learn.rollouts)
    rec = {
        "seeds": int(final.shape[0]),
        "curve": [[int(s), int(t), float(r), int(q)] for s, t, r, q in res["curve"]],
        "final": [float(x) for x in final.mean(1)],
        **_paths_and_routes(world, res["paths"]),
        **_scores(scores),
    }
    if res.get("u_map") is not None:
        rec["u_map"] = pc.nan_to_none(res["u_map"])
    return rec


def _scores(scores: list[dict]) -> dict:
    """Per-seed lists of :func:`~mindgap.algorithms.explicability.explicability_scores`' fields."""
    return {
        "explicability": [s["score"] for s in scores],
        "explicability_stderr": [s["stderr"] for s in scores],
        "dynamics_part": [s["dynamics_part"] for s in scores],
        "policy_part": [s["policy_part"] for s in scores],
        "return": [s["stochastic_return"] for s in scores],
    }


def _paths_and_routes(world, paths) -> dict:
    return {
        "paths": [[np.round(np.asarray(p, np.float64), 4).tolist() for p in seed] for seed in paths],
        "routes": [wm.route_of(world, seed) for seed in paths],
    }


def _actor_path(folder: RunFolder, key: str):
    return folder.root / "actors" / (key.replace("/", "__") + ".npz")


def load_actors(folder: RunFolder, key: str, env, sac_cfg, seeds: int):
    """The SAC actors a finished job stored (a leading seed axis) for ``env``'s spaces."""
    path = _actor_path(folder, key)
    if not path.exists():
        raise RuntimeError(f"{key}'s policies are missing from {folder.root}; rerun with --fresh")
    d, a = dims(env)
    template = jax.vmap(lambda k: sac_init(k, d, a, sac_cfg).params.actor)(jax.random.split(rng.key(0), seeds))
    return load_pytree(path, template)[0]


def _shaping_record(folder: RunFolder, world, person, learn: EPSLearners, job: pc.Job, seeds: int) -> dict:
    """Policy Shaping: the product of each seed's SAC and DRLHP policies, measured like a learner."""
    env_key, fb_key = job.cfg
    ones = jnp.ones(seeds, jnp.float32)  # the plain product, one weight per seed (every leaf has the seed axis)
    policy = ShapedPolicy(
        load_actors(folder, env_key, world.env, learn.sac.sac, seeds),
        load_actors(folder, fb_key, world.env, learn.eps.sac, seeds),
        ones,
        ones,
    )
    final, paths = [], []
    for s, k in enumerate(jax.random.split(rng.key(30_000 + learn.sac.seed), seeds)):
        one = jax.tree.map(lambda a: a[s], policy)
        obs, rew, alive = rollouts(k, world.env, world.params, shaped_greedy, one, max(learn.paths, 20), world.horizon)
        final.append(float(np.asarray(rew).sum(-1).mean()))
        paths.append(_cut(world.trace(obs), alive, learn.paths))
    scores = explicability_scores(
        rng.key(20_000 + learn.sac.seed), world, person, policy, learn.rollouts, agent_dist=shaped_dist
    )
    return {"seeds": seeds, "curve": [], "final": final, **_paths_and_routes(world, paths), **_scores(scores)}


def _cut(pos, alive, count: int) -> list[np.ndarray]:
    """The first ``count`` rollouts, each up to the step it ended."""
    pos, alive = np.asarray(pos), np.asarray(alive)
    return [pos[e, : int(alive[e].sum()) + 1] for e in range(min(count, pos.shape[0]))]


def _person_record(world, person, learn: EPSLearners) -> dict:
    """The routes the person expects, what obeying them earns, and the optimal route."""
    k_exp, k_true, k_score = jax.random.split(rng.key(40_000), 3)
    _, obs, alive = evaluate(k_exp, world.env, person.policy, person.belief, max(learn.paths, 20), world.horizon)
    pos = world.trace(obs)
    in_truth, _, _ = evaluate(k_true, world.env, person.policy, world.params, 20, world.horizon)
    own = explicability(k_score, world, person.belief, person.policy, person.policy, learn.rollouts)
    plan = wm.plan_record(world, learn.plan_resolution, 100)
    return {
        "done": f"π_H return in truth {float(np.mean(in_truth)):.1f}",
        "expected_paths": [np.round(p, 4).tolist() for p in _cut(pos, alive, learn.paths)],
        "obey_return": float(np.mean(in_truth)),
        "obey_stochastic_return": float(jnp.mean(own.returns)),
        "obey_explicability": float(own.score),
        **{k: plan[k] for k in ("optimal", "expected", "plan_return")},
    }


# ---------------------------------------------------------------------------------------
# metrics


def required_route(world, route: dict, person_rec: dict | None) -> bool | None:
    """Whether one seed's greedy routes are the ones the world's ``eps_route`` asks of EPS.

    * ``ice`` / ``sand`` (d3 / d4): most rollouts reach the goal, with more steps on that
      terrain than on the other;
    * ``detour`` (d1, d2): most rollouts reach the goal and their mean distance to the pit
      is nearer that of the route the person expects than that of the optimal route (both
      from the planning check): at least halfway from the optimal berth to the person's — a
      detour the optimal agent does not take, though not necessarily the person's own;
    * None where the world names no ``eps_route`` (or no person record gives the optimal route).
    """
    want = wm.expect(world).get("eps_route")
    if want is None or route["goal"] is None:
        return None
    if route["goal"] < 0.5:
        return False
    if want in ("ice", "sand"):
        return bool(route[want] > route["sand" if want == "ice" else "ice"])
    if person_rec is None or person_rec.get("expected") is None or route["pit_mean"] is None:
        return None
    halfway = 0.5 * (person_rec["optimal"]["pit_mean"] + person_rec["expected"]["pit_mean"])
    return bool(route["pit_mean"] >= halfway)


def route_share(world, rec: dict, person_rec: dict | None) -> float:
    """Fraction of a learner's seeds on the required route (NaN where it is not defined)."""
    flags = [required_route(world, r, person_rec) for r in rec["routes"]]
    flags = [f for f in flags if f is not None]
    return float(np.mean(flags)) if flags else float("nan")


def result_row(world, rec: dict, person_rec: dict | None) -> dict:
    """One learner's row: return and explicability (mean, std over seeds), routes, and how many seeds
    are held still short of the goal (:func:`~.world_measures.held_still_seeds`)."""

    def ms(name):
        v = np.asarray(rec[name], np.float64)
        return float(v.mean()), float(v.std())

    row = {"method": rec["method"], "world": rec["world"], **rec["tags"], "label": rec["label"], "seeds": rec["seeds"]}
    row["return_mean"], row["return_std"] = ms("return")
    row["explicability_mean"], row["explicability_std"] = ms("explicability")
    row["greedy_return_mean"], row["greedy_return_std"] = ms("final")
    row["dynamics_part_mean"], _ = ms("dynamics_part")
    row["policy_part_mean"], _ = ms("policy_part")
    row.update(
        required_route=route_share(world, rec, person_rec),
        held_still=wm.held_still_seeds(world, rec["paths"]),
        **wm.route_means(rec["routes"]),
    )
    return row


def monotone_within_noise(means, stds, seeds: int, rising: bool) -> tuple[bool, float]:
    """Whether a sequence rises (or falls) within seed noise, and its worst reversal.

    Within noise: no later value is below an earlier one (above, for ``rising=False``) by
    more than twice the standard error of their difference, sqrt(se_i² + se_j²) with
    se = std / √seeds. Returns (held, the largest reversal in units of that error; ≤ 2 holds).
    """
    m = np.asarray(means, np.float64) * (1 if rising else -1)
    se = np.asarray(stds, np.float64) / np.sqrt(max(seeds, 1))
    worst = 0.0
    for i in range(len(m)):
        for j in range(i + 1, len(m)):
            drop = m[i] - m[j]
            if drop > 0:
                worst = max(worst, drop / max(np.hypot(se[i], se[j]), 1e-9))
    return worst <= 2.0, worst


def persons(records: dict) -> dict[tuple[str, str], dict]:
    """The person records by (world, person)."""
    return {(r["world"], r["tags"]["person"]): r for r in records.values() if r["method"] == "person"}
