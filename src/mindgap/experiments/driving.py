"""Experiment ``driving``: EPS vs SAC vs DRLHP on the sleety highway, rated by new simulated participants
(dissertation §4.4.2, Table 5, Figs. 32–36).

The study's two phases with simulated participants (:mod:`~mindgap.teachers.drivers`):

* **training** — recruits answer Fig. 32's importance questions and the bias-validation
  question; a sanity item (a collision) drops the inattentive; r_A is the map of the valid
  participants' average answers; each valid participant's expected policy π_H is discrete SAC
  for their own reward in the world as they believe it (one program vmapped over them).
  EPS (λ = 2.0, Algorithm 3), DRLHP (the learned u_H alone, §4.4.1.1) and SAC (on r_A) train
  on the true, sleety world with discrete SAC (:mod:`~mindgap.algorithms.sac_discrete`);
  EPS and DRLHP ask the participants "which is more expected?" (one participant per query);
* **testing** — *new* participants, recruited the same way, rate 1–10 the greedy rollouts of
  every method's seeds (and the collision of the sanity item, which must come lowest); the
  same episodes are written to ``rollouts.json`` (:mod:`mindgap.data.rollouts_file`) for
  real people to rate in the study app (``mindgap study``, ``driving-testing`` example).

Jobs, in a :class:`~._runfolder.RunFolder` (finished ones are read back, an interrupted
learner resumes from its engine checkpoint): ``driving/people``, ``driving/sac``,
``driving/drlhp``, ``driving/eps`` (each vmaps its seeds), ``driving/testing``.

Measured per method, over seeds, on ``rollouts`` greedy episodes per seed in the sleety
world (:func:`~.driving_measures.behaviour`): return under r_A (Table 5), collision rate, the first lane change
(decisions after the front car starts braking; share of episodes with one), whether the car
braked before it, and the smallest bumper gap to the front car while in line with it.
Outputs: ``results.csv``, ``participants.csv``, ``ratings.csv``, ``curves.csv``,
``table.md``, ``summary.json``, ``frames_METHOD.png`` (Figs. 34–36: three characteristic
moments drawn by the highway-env version) and ``episode_METHOD.gif``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from ..algorithms import eps as eps_alg
from ..algorithms import pbrl
from ..algorithms.eps_config import EPSConfig, eps_config
from ..algorithms.expected_policy import ExpectedPolicyConfig
from ..algorithms.sac import SACConfig
from ..algorithms.sac_loop import agent_init, greedy_policy, loop_init, rollouts, run_chunk
from ..checkpoint import load_pytree, save_pytree
from ..data.rollouts_file import rollout_record, write_rollouts
from ..data.segments import Segments
from ..envs.driving import STUDY_IMPORTANCE, importance_weights, make_world
from ..envs.driving.params import SLOWER
from ..teachers import drivers as dv
from ..teachers.preference import TeacherConfig
from . import prefbias_common as pc
from ._runfolder import RunFolder, to_jsonable, write_csv
from .driving_measures import behaviour, greedy_episodes, learner_record
from .driving_report import COIN, METHODS, WORLD
from .driving_report import write_outputs as report_outputs


@dataclasses.dataclass(frozen=True)
class DrivingConfig:
    """What ``mindgap reproduce driving`` runs."""

    sleet: float = 1.0
    """The sleet level of the road the agents drive on (0 dry … 1 full sleet)."""
    traffic: int = 0
    """Other cars on the road besides the front car (0 … 4; :func:`~mindgap.envs.driving.make_world`)."""
    sanity: str = "preference"
    """How a recruit answers the training phase's sanity item: ``preference`` (which clip they prefer,
    Σ r_H over the same moments, the collision's clip and braking in time both cut to the crash: the
    study's wording, "a collision, which should not be preferred under any situation") or
    ``expectation`` (which clip is more expected, per step, as they answer queries; it drops
    attentive recruits who expect steering, docs/experiments/driving.md)."""
    importance: tuple[float, ...] = STUDY_IMPORTANCE
    """The population's mean importance answers (Fig. 32's averages)."""
    answers_by: str = "rollout-behaviour"
    """How a participant judges which clip is more expected (queries, the sanity item asked as an
    expectation, the testing phase's ratings): ``rollout-behaviour`` (the default: the clip's decisions
    played out in the world they believe in, :mod:`~mindgap.teachers.believed_rollout`;
    docs/domains/driving.md), ``rollout`` (the same, and a crash their rollout does not reproduce
    charged at the floor: braking in lane on sleet then is nobody's expectation, because it crashes
    there; docs/experiments/driving.md), ``expectation``
    (Σ [log T_H + log π_H] at the clip's own states, the identifiable protocol) or ``decisions``
    (log π_H at the clip's own states alone)."""
    seeds: int = 5
    participants: int = 14
    """Valid participants of the training phase (14 in the study)."""
    raters: int = 15
    """Valid participants of the testing phase (15 in the study)."""
    population: dv.DriverPopulation = dv.DriverPopulation()
    teacher: TeacherConfig = TeacherConfig()
    """How a participant answers a query (Bradley–Terry, β = 1)."""
    eps: EPSConfig = dataclasses.field(default_factory=lambda: _eps("full"))
    """EPS's configuration (λ = 2.0; DRLHP is the same with ``method="drlhp"``)."""
    person: ExpectedPolicyConfig = ExpectedPolicyConfig(
        total_steps=20_000, chunk=1000, seeds=5, sac=SACConfig(hidden=(64, 64), learning_starts=2000)
    )
    """How each participant's π_H is trained: discrete SAC in their belief, 5 seeds each, the seed with
    the best greedy r_H kept (one seed left most of them in the local optimum of leaving the lane
    before the front car brakes, below their own reward's braking in lane: docs/experiments/driving.md)."""
    rollouts: int = 20
    """Greedy episodes per seed measured in the sleety world."""
    shown: int = 2
    """Greedy episodes per seed shown to each rater."""

    def __post_init__(self):
        dv.check_sleet_level(self.sleet)
        if self.sanity not in ("expectation", "preference"):
            raise ValueError(f"sanity must be 'expectation' or 'preference', got {self.sanity!r}")
        if self.answers_by not in ANSWERS_BY:
            raise ValueError(f"answers_by must be one of {', '.join(ANSWERS_BY)}, got {self.answers_by!r}")
        if not 0 <= self.traffic <= 4:
            raise ValueError(f"traffic must be in 0 … 4 (two cars in each of the other two lanes), got {self.traffic}")
        importance_weights(self.importance)  # one line for a rating outside [1, 5]
        for name in ("seeds", "participants", "raters", "rollouts", "shown"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.shown > self.rollouts:
            raise ValueError("shown must not exceed rollouts")

    @property
    def answer_cfg(self) -> TeacherConfig:
        """How the participants answer, as the learners' ``teacher`` config: ``decisions`` leaves log T_H out."""
        return dataclasses.replace(self.teacher, use_belief=self.answers_by != "decisions")

    @property
    def judged(self) -> str:
        """What the participants' expectation covers, as EPS reads it (``EPSConfig.judged``): transitions
        when they answer by ``expectation`` (log T_H + log π_H at the clip's states), else decisions."""
        return "transitions" if self.answers_by == "expectation" else "decisions"

    @property
    def rollout(self) -> bool:
        """Whether the participants play a clip's decisions out in their believed world."""
        return self.answers_by in ("rollout", "rollout-behaviour")

    @property
    def crash(self) -> bool:
        """Whether a played-out clip's crash that the participant's rollout does not reproduce is charged."""
        return self.answers_by == "rollout"


ANSWERS_BY = ("rollout", "rollout-behaviour", "expectation", "decisions")
"""The ways a participant judges a clip (:attr:`DrivingConfig.answers_by`)."""


def _eps(preset: str) -> EPSConfig:
    """EPS on the driving world: the preset's schedule with queries of 10 decisions from episodes' starts,
    the response to the front car's braking as the study's hand-picked clips showed it (§4.4.2, Fig. 33),
    and SAC's entropy neutral to survival (``survival_entropy="neutral"``: SAC and DRLHP; EPS's H_π is
    Eq. 4.6's own term, :func:`~mindgap.algorithms.eps_reward.eps_sac_config`) — every episode here
    ends, by a crash or at the horizon, and when it ends is what the study is about
    (docs/experiments/driving.md, "The learners follow the answers"). For the same reason u_H has an
    absorbing state (``absorbing="single"``, :attr:`~mindgap.algorithms.eps_config.EPSConfig.absorbing`):
    what an ended clip is worth comes from the answers, not from the λ-term's constant, which under the
    cost form paid EPS to crash (docs/experiments/driving.md, "Gates and controls")."""
    if preset == "full":
        cfg = eps_config(
            "full", total_steps=30_000, queries=400, per_round=40, segment=10, queries_from="start", lam=2.0
        )
    else:
        cfg = eps_config("fast", segment=10, queries_from="start", lam=2.0)
    return dataclasses.replace(cfg, absorbing="single", sac=dataclasses.replace(cfg.sac, survival_entropy="neutral"))


def preset(name: str) -> DrivingConfig:
    """``full`` (5 seeds, 30 000 steps, 400 queries, 14 + 15 participants) or ``fast`` (1 seed, 1500 steps,
    30 queries, 4 + 4 participants, a tiny π_H: a dry run and the tests' preset, not results)."""
    if name == "full":
        return DrivingConfig()
    if name == "fast":
        return DrivingConfig(
            seeds=1,
            participants=4,
            raters=4,
            eps=_eps("fast"),
            person=ExpectedPolicyConfig(
                total_steps=500, chunk=250, seeds=1, sac=SACConfig(hidden=(16,), batch_size=32, learning_starts=250)
            ),
            rollouts=4,
            shown=1,
        )
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: DrivingConfig) -> list[pc.Job]:
    """The run's jobs. DRLHP's and EPS's configs carry the participants' way of answering
    (``cfg.teacher``): the engine has the crowd answer by its learner's ``teacher`` config."""
    sac = _sac_cfg(cfg)
    out = [pc.Job(f"{WORLD}/people", WORLD, "people", "participants", cfg.population, {})]
    out.append(pc.Job(f"{WORLD}/sac", WORLD, "sac", "SAC", sac, {}))
    learners = {
        m: dataclasses.replace(cfg.eps, method=m, teacher=cfg.answer_cfg, judged=cfg.judged) for m in ("drlhp", "eps")
    }
    out.append(pc.Job(f"{WORLD}/drlhp", WORLD, "drlhp", "DRLHP", learners["drlhp"], {}))
    out.append(pc.Job(f"{WORLD}/eps", WORLD, "eps", "EPS", learners["eps"], {"lam": cfg.eps.lam}))
    coin = pc.coin_flips(learners["drlhp"])
    out.append(pc.Job(COIN, WORLD, "drlhp", "DRLHP (coin-flip answers)", coin, {"person": "coin"}))
    out.append(pc.Job(f"{WORLD}/testing", WORLD, "testing", "testing phase", cfg.raters, {}))
    return out


def job_needs(cfg: DrivingConfig) -> dict[str, tuple[str, ...]]:
    """The jobs each job reads (for workers that run jobs apart): the learners and the testing phase
    read the participants; the testing phase also reads every learner's policy."""
    people = f"{WORLD}/people"
    learners = tuple(j.key for j in jobs(cfg) if j.method in METHODS)
    rated = tuple(f"{WORLD}/{m}" for m in METHODS)
    return {**{k: (people,) for k in learners}, f"{WORLD}/testing": (people, *rated)}


def _sac_cfg(cfg: DrivingConfig) -> pbrl.PbRLConfig:
    names = ("total_steps", "chunk", "eval_every", "eval_episodes", "sac", "seed")
    return pbrl.method_config("sac", **{n: getattr(cfg.eps, n) for n in names})


def run(cfg: DrivingConfig, out: Path, *, fresh=False, progress=True, assemble_only=False, only=None) -> dict:
    """Run (or resume) the experiment in ``out``; write its files; return the summary."""
    from . import registry

    out = Path(out)
    everything = jobs(cfg)
    todo = pc.select_job(everything, only, "driving") if only else everything
    if only and only != f"{WORLD}/people":
        todo = [everything[0]] + [j for j in todo if j.key != f"{WORLD}/people"]
    if only == f"{WORLD}/testing":
        todo = everything
    folder = RunFolder(out, cfg, fresh=fresh)
    rerun = registry.command("driving", cfg, out)
    records = pc.run_jobs(
        folder, todo, cfg.seeds, fresh=fresh, progress=progress, assemble_only=assemble_only,
        compute=_compute(cfg), rerun=rerun,
    )  # fmt: skip
    folder.write_progress("driving", [j.key for j in everything], rerun)
    if only:
        return {"job": records[only]}
    if not any(r["method"] in METHODS for r in records.values()):
        raise RuntimeError(f"{out} has no finished learner jobs to assemble")
    summary = write_outputs(cfg, out, records)
    summary["missing_jobs"] = len(everything) - len(records)
    return summary


# ---------------------------------------------------------------------------------------
# the jobs


def world_of(cfg: DrivingConfig, weights=None):
    """The sleety world, r_A weighted by ``weights`` (the engineered reward) when given."""
    if weights is None:
        return make_world(sleet=cfg.sleet, traffic=cfg.traffic)
    return make_world(sleet=cfg.sleet, traffic=cfg.traffic, weights=tuple(round(float(w), 6) for w in weights))


def _compute(cfg: DrivingConfig):
    def compute(folder: RunFolder, job: pc.Job, seeds: int, *, fresh: bool, progress: bool) -> dict:
        if job.method == "people":
            return people_record(folder, cfg)
        people = folder.done(f"{WORLD}/people")
        world = world_of(cfg, people["engineered_weights"])
        if job.method == "testing":
            return testing_record(folder, cfg, world, people)
        res = train(folder, cfg, world, people, job, seeds, fresh=fresh, progress=progress)
        save_pytree(_actor_path(folder, job.key), res["carry"].loop.sac.params.actor)
        actors = res["carry"].loop.sac.params.actor
        return learner_record(world, actors, res, cfg.rollouts)

    return compute


def train(folder, cfg: DrivingConfig, world, people: dict, job: pc.Job, seeds: int, *, fresh, progress) -> dict:
    """Train one learner's seeds through the engine (the participants answer EPS's and DRLHP's queries)."""
    kw = dict(seeds=seeds, out=pc.job_dir(folder, job), progress=progress, fresh=fresh)
    if job.method == "sac":
        return pbrl.train(world, job.cfg, teacher="true", **kw)
    crowd = crowd_teacher(folder, cfg, world, people)
    return eps_alg.train(world, job.cfg, crowd, person_name="participants", **kw)


def _actor_path(folder: RunFolder, key: str) -> Path:
    return folder.root / "actors" / (key.replace("/", "__") + ".npz")


def recruit(key, cfg: DrivingConfig, world, n_valid: int, prefix: str, judge, max_rounds: int = 20):
    """Recruit (as on MTurk) until ``n_valid`` recruits pass: each round draws as many recruits as are still
    missing (``n_valid`` in the first), trains their π_H in one vmapped program and asks
    ``judge(key, drivers, actors) → [why dropped, "" if valid]``.

    Returns every recruit in order as (driver, why, actor), stopping at the ``n_valid``-th valid one.
    """
    out, ok = [], 0
    for rnd in range(max_rounds):
        k_draw, k_judge = jax.random.split(jax.random.fold_in(key, rnd))
        batch = [
            dv.sample_driver(
                jax.random.fold_in(k_draw, i), _population(cfg), f"{prefix}-{len(out) + i + 1:02d}", cfg.sleet
            )
            for i in range(n_valid - ok)
        ]
        actors = train_expected_policies(world, batch, cfg)
        whys = judge(k_judge, batch, actors)
        for i, (d, why) in enumerate(zip(batch, whys)):
            out.append((d, why, jax.tree.map(lambda a, i=i: a[i], actors)))
            ok += not why
            if ok == n_valid:
                return out
    raise RuntimeError(f"only {ok} of {len(out)} recruits passed the sanity check; need {n_valid}")


def _population(cfg: DrivingConfig) -> dv.DriverPopulation:
    return dataclasses.replace(cfg.population, importance_mean=tuple(cfg.importance))


def sanity_segments(world, length: int):
    """The sanity item: the ego keeps its speed into the braking front car (a collision) against one that
    brakes as soon as the front car does; one episode each on a dry road, front car braking at step 1."""
    params = world.params.with_sleet(0.0)._replace(brake_first=jnp.int32(1), brake_last=jnp.int32(1))
    env = world.env
    idle = lambda actor, obs: jnp.ones((1,), jnp.float32)  # noqa: E731
    brake = lambda actor, obs: jnp.where(obs[7] > 0.5, float(SLOWER), 1.0)[None]  # noqa: E731
    segs = []
    for policy in (idle, brake):
        obs, _, alive = rollouts(rng.key(50_000), env, params, policy, None, 1, world.horizon)
        acts = jax.vmap(jax.vmap(lambda o: policy(None, o)))(obs[:, :-1])
        segs.append((obs[0], acts[0], alive[0]))
    return segs


def _segment(obs, act, alive, length: int):
    """The first ``length`` steps of an episode as one query segment ``[1, L, ·]``."""
    return Segments(obs[None, :length], act[None, :length], obs[None, 1 : length + 1], alive[None, :length])


def people_record(folder: RunFolder, cfg: DrivingConfig) -> dict:
    """The training phase's participants: recruits, the sanity item, the bias question, r_A, everyone's π_H."""
    probe = world_of(cfg)
    (c_obs, c_act, c_alive), (s_obs, s_act, s_alive) = sanity_segments(probe, probe.horizon)
    items = [_segment(c_obs, c_act, c_alive, probe.horizon), _segment(s_obs, s_act, s_alive, probe.horizon)]
    crash = int(np.asarray(c_alive).sum())  # the preference item shows both up to the crash
    same_moments = [_segment(c_obs, c_act, c_alive, crash), _segment(s_obs, s_act, s_alive, crash)]

    def judge(key, batch, actors):
        whys = []
        for i, d in enumerate(batch):
            if cfg.sanity == "preference":
                reward = dv.RewardH(jnp.asarray(d.weights), probe.params.with_sleet(0.0))
                sc = [float(dv.reward_sums(s, reward)[0]) for s in same_moments]
            else:
                actor = jax.tree.map(lambda a: a[i], actors)
                sc = [float(clip_per_step(cfg, s, actor, belief_params(probe, d), probe.env)[0]) for s in items]
            fails = dv.sanity_fails(jax.random.fold_in(key, i), sc[0], sc[1], d.attentive, cfg.teacher)
            chose = "preferred" if cfg.sanity == "preference" else "more expected"
            whys.append(f"failed the sanity check (the collision {chose})" if fails else "")
        return whys

    key = rng.key(60_000 + cfg.eps.seed)
    recruits = recruit(key, cfg, probe, cfg.participants, "train", judge)
    valid = [(d, a) for d, why, a in recruits if not why]
    stacked = jax.tree.map(lambda *xs: jnp.stack(xs), *[a for _, a in valid])
    save_pytree(folder.root / "actors" / "people.npz", stacked)
    valid = [d for d, _ in valid]
    bias = [
        dv.bias_answer(jax.random.fold_in(key, 90_000 + i), d.believed_sleet, d.attentive, probe.params)
        for i, d in enumerate(valid)
    ]
    expects = expected_behaviour(probe, valid, stacked)
    rows = []
    for d, why, _ in recruits:
        row = {"pid": d.pid, "attentive": d.attentive, "believed_sleet": d.believed_sleet, "dropped": why}
        row.update({f"importance_{i}": v for i, v in enumerate(d.importance)})
        if not why:
            j = valid.index(d)
            row.update(bias_effective_braking=bias[j], **{k: v[j] for k, v in expects.items()})
        rows.append(row)
    weights = dv.engineered_weights(valid)
    return {
        "done": f"{len(valid)} valid of {len(recruits)}; {sum(bias)} chose effective braking",
        "participants": rows,
        "engineered_weights": [float(w) for w in weights],
        "bias_effective": int(sum(bias)),
        "valid": len(valid),
        "recruits": len(recruits),
    }


def belief_params(world, d: dv.Driver):
    """The world as driver ``d`` believes it (their sleet level)."""
    return world.params.with_sleet(d.believed_sleet)


def train_expected_policies(world, drivers: list[dv.Driver], cfg: DrivingConfig):
    """Every driver's π_H: discrete SAC on their reward r_H in the world as they believe it,
    ``cfg.person.seeds`` seeds per driver in one program vmapped over drivers and seeds, keeping the
    seed whose greedy episodes earn the most r_H in that world (as
    :func:`~mindgap.algorithms.expected_policy.train_expected_policy` keeps the best seed). Actors
    with a leading driver axis."""
    p = cfg.person
    p.check()
    n, k = len(drivers), p.seeds
    beliefs = jax.tree.map(lambda *xs: jnp.stack(xs), *[belief_params(world, d) for d in drivers])
    rewards = dv.RewardH(jnp.asarray(np.stack([d.weights for d in drivers])), beliefs)
    env = world.env
    keys = jax.random.split(rng.key(p.seed + 70_000), n * k).reshape(n, k)  # one seed: the former keys
    init = jax.vmap(jax.vmap(lambda key, b: loop_init(key, env, b, p.sac, p.total_steps), (0, None)))
    loop = init(keys, beliefs)
    for start in range(0, p.total_steps, p.chunk):
        phase = "random" if start < p.sac.learning_starts else "train"

        def chunk(ls, b, r, phase=phase):
            return run_chunk(ls, env, b, r, n_steps=p.chunk, cfg=p.sac, phase=phase, reward_fn=dv.participant_reward)

        loop = jax.vmap(jax.vmap(chunk, (0, None, None)))(loop, beliefs, rewards)
    actors = loop.sac.params.actor
    if k == 1:
        return jax.tree.map(lambda a: a[:, 0], actors)
    eval_keys = jax.random.split(rng.key(p.seed + 71_000), n)

    def score(key, actor, belief, reward):
        return _greedy_return_h(key, actor, belief, reward, p.eval_episodes, world)

    returns = np.asarray(jax.jit(jax.vmap(jax.vmap(score, (None, 0, None, None))))(eval_keys, actors, beliefs, rewards))
    best = jnp.asarray(np.argmax(returns, axis=1))
    return jax.tree.map(lambda a: a[jnp.arange(n), best], actors)


def _greedy_return_h(key, actor, belief, reward: dv.RewardH, episodes: int, world):
    """Mean r_H of ``episodes`` greedy episodes of ``actor`` in the world ``belief``."""
    env = world.env
    obs, _, alive = rollouts(key, env, belief, greedy_policy(env), actor, episodes, world.horizon)
    return dv.reward_sums(Segments(None, None, obs[:, 1:], alive), reward).mean()


def load_people(folder: RunFolder, world, people: dict, cfg: DrivingConfig):
    """The valid participants (as :class:`~mindgap.teachers.drivers.Driver`) and their stacked π_H actors."""
    valid = [_driver(r) for r in people["participants"] if not r["dropped"]]
    template = jax.vmap(lambda k: agent_init(k, world.env, cfg.person.sac).params.actor)(
        jax.random.split(rng.key(0), len(valid))
    )
    return valid, load_pytree(folder.root / "actors" / "people.npz", template)[0]


def _driver(row: dict) -> dv.Driver:
    imp = tuple(int(row[f"importance_{i}"]) for i in range(4))
    return dv.Driver(row["pid"], bool(row["attentive"]), imp, float(row["believed_sleet"]))


def crowd_teacher(folder: RunFolder, cfg: DrivingConfig, world, people: dict) -> dv.CrowdTeacher:
    valid, actors = load_people(folder, world, people, cfg)
    beliefs = jax.tree.map(lambda *xs: jnp.stack(xs), *[belief_params(world, d) for d in valid])
    attentive = jnp.asarray([d.attentive for d in valid])
    return dv.CrowdTeacher(beliefs, actors, attentive, world.env, cfg.answer_cfg, rollout=cfg.rollout, crash=cfg.crash)


def clip_per_step(cfg: DrivingConfig, seg: Segments, actor, belief, env) -> jax.Array:
    """How expected each clip looks per decision to one participant, as ``cfg.answers_by`` has them judge: [K]."""
    if cfg.rollout:
        return dv.believed_per_step(seg, actor, belief, cfg.answer_cfg, cfg.crash)
    return dv.per_step_scores(seg, dv.ExpectationTeacher(belief, actor, env), cfg.answer_cfg)


def expected_behaviour(world, drivers, actors) -> dict[str, list]:
    """What each driver expects of the car in the scenario (π_H's greedy episodes in their own belief):
    the share of episodes in which the expected car changes lane and in which it brakes first."""
    out = {"expects_lane_change": [], "expects_braking_first": []}
    for i, d in enumerate(drivers):
        actor = jax.tree.map(lambda a, i=i: a[i], actors)
        obs, _, alive = rollouts(
            rng.key(80_000 + i), world.env, belief_params(world, d), greedy_policy(world.env), actor, 20, world.horizon
        )
        acts = jax.vmap(jax.vmap(lambda o: greedy_policy(world.env)(actor, o)))(obs[:, :-1])
        b = behaviour(np.asarray(obs), np.asarray(acts), np.asarray(alive), world)
        out["expects_lane_change"].append(float(np.mean(b["changed"])))
        out["expects_braking_first"].append(float(np.mean(b["braked_first"])))
    return out


# ---------------------------------------------------------------------------------------
# the testing phase


def testing_record(folder: RunFolder, cfg: DrivingConfig, world, people: dict) -> dict:
    """New participants rate every method's greedy rollouts (and the sanity collision) 1–10."""
    shown, index, records = [], [], []
    for m in METHODS:
        rec = folder.done(f"{WORLD}/{m}")
        actors = _load_actors(folder, f"{WORLD}/{m}", world, cfg, rec["seeds"])
        for s in range(rec["seeds"]):
            actor = jax.tree.map(lambda a, s=s: a[s], actors)
            obs, act, alive, rew = greedy_episodes(world, actor, rng.key(20_000 + s), cfg.shown)
            shown.append((obs, act, alive))
            index += [(m, s, e) for e in range(cfg.shown)]
            records += [
                rollout_record(f"{m}-s{s}-e{e}", m, s, e, obs[e], act[e], alive[e], float(np.asarray(rew[e]).sum()))
                for e in range(cfg.shown)
            ]
    (c_obs, c_act, c_alive), _ = sanity_segments(world, world.horizon)
    shown.append((c_obs[None], c_act[None], c_alive[None]))
    index.append(("sanity", -1, 0))
    records.append(rollout_record("sanity", "sanity", -1, 0, c_obs, c_act, c_alive, sanity="lowest"))
    # the same episodes for people to rate (mindgap study, items: {source: file, path: rollouts.json})
    write_rollouts(folder.root / "rollouts.json", {"name": "driving", "sleet": cfg.sleet}, records)
    obs, act, alive = (jnp.concatenate(x) for x in zip(*shown))
    sanity = len(index) - 1
    ratings = {}

    def judge(key, batch, actors):
        whys = []
        for i, d in enumerate(batch):
            actor = jax.tree.map(lambda a: a[i], actors)
            belief = belief_params(world, d) if cfg.rollout else None
            r = dv.rate_rollouts(
                jax.random.fold_in(key, i), actor, d.attentive, obs, act, alive, cfg.population.rating_noise,
                belief=belief, cfg=cfg.answer_cfg, crash=cfg.crash,
            )  # fmt: skip
            ratings[d.pid] = r
            whys.append(dv.rating_fails(r, sanity))
        return whys

    raters = [(d, why) for d, why, _ in recruit(rng.key(61_000 + cfg.eps.seed), cfg, world, cfg.raters, "test", judge)]
    rows = []
    for d, why in raters:
        for (m, s, e), r in zip(index, ratings[d.pid]):
            rows.append({"rater": d.pid, "valid": not why, "method": m, "seed": s, "episode": e, "rating": float(r)})
    valid = [d for d, why in raters if not why]
    return {
        "done": f"{len(valid)} valid raters of {len(raters)}",
        "ratings": rows,
        "raters": [
            {"pid": d.pid, "attentive": d.attentive, "believed_sleet": d.believed_sleet, "dropped": why}
            for d, why in raters
        ],
    }


def _load_actors(folder: RunFolder, key: str, world, cfg: DrivingConfig, seeds: int):
    path = _actor_path(folder, key)
    if not path.exists():
        raise RuntimeError(f"{key}'s policies are missing from {folder.root}; rerun with --fresh")
    sac = cfg.eps.agent_sac() if not key.endswith("/sac") else _sac_cfg(cfg).sac
    template = jax.vmap(lambda k: agent_init(k, world.env, sac).params.actor)(jax.random.split(rng.key(0), seeds))
    return load_pytree(path, template)[0]


# ---------------------------------------------------------------------------------------
# outputs


def write_outputs(cfg: DrivingConfig, out: Path, records: dict) -> dict:
    """The experiment's files from its job records (:mod:`~.driving_report`)."""
    return report_outputs(cfg, out, records, world_of=world_of, load_actors=_load_actors)


__all__ = ["DrivingConfig", "preset", "jobs", "run", "to_jsonable", "write_csv"]
