"""The gym experiment's reference job (:mod:`~.prefbias_gym`): a random policy's return and the
identifiability conditions of docs/experiments/identifiability.md, measured on a control domain.

The gym and MJX worlds have no terrain map, so :mod:`~.world_measures`' planning, routes and
expected-reward grid do not apply; what applies is measured here on random-action transitions.
``cfg`` is the experiment's :class:`~.prefbias_gym.GymConfig` (its ``reference`` and
``learners`` fields).
"""

from __future__ import annotations

import jax
import numpy as np

from ..envs.gym_world import GymWorld
from ..teachers.learned_belief import collect
from . import world_measures as wm
from .prefbias_common import markdown


def random_host(world: GymWorld, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Returns and lengths of ``episodes`` episodes of a uniformly random policy on a gym world (the env's own reward)."""
    rng = np.random.default_rng(seed)
    rets, lens = [], []
    for e in range(episodes):
        env, _ = world.make(seed + 7919 * e)
        try:
            ret, t, done = 0.0, 0, False
            while not done and t < world.horizon:
                _, r, term, trunc, _ = env.step(world.to_env(rng.uniform(-1.0, 1.0, len(world.act_low))))
                ret, t, done = ret + float(r), t + 1, term or trunc
        finally:
            env.close()
        rets.append(ret)
        lens.append(t)
    return np.asarray(rets), np.asarray(lens)


def random_mjx(world, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`random_host` on a pure-JAX world (:func:`~.world_measures.random_transitions`)."""
    from .. import rng

    tr = wm.random_transitions(rng.key(seed), world.env, world.params, episodes, world.horizon, draws=1)
    return np.asarray(tr["reward"]).sum(1), np.asarray(tr["alive"]).sum(1)


def transitions(world, cfg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random-action transitions of the true world (obs, act, next_obs): where rewards are compared."""
    n, seed = cfg.reference.transitions, cfg.reference.seed + 17
    if isinstance(world, GymWorld):
        return collect(world, n, seed)
    from .. import rng

    episodes = max(1, -(-n // world.horizon))
    tr = wm.random_transitions(rng.key(seed), world.env, world.params, episodes, world.horizon, draws=1)
    alive = np.asarray(tr["alive"]).reshape(-1)
    flat = [np.asarray(tr[k]).reshape(alive.size, -1)[alive][:n] for k in ("obs", "act", "next_obs")]
    return tuple(flat)


def reward_error(world, cfg, fn, params) -> np.ndarray:
    """Per seed, the z-scored RMS error of a learned reward against the person's r_H on random-action transitions.

    As :func:`~.world_measures.reward_error` (0 the truth up to offset and scale, √2 unrelated,
    2 reversed), on the realised transitions of :func:`transitions`: r_H of a gym domain is a
    function of the observed transition (docs/domains/gym.md), so no expectation over next
    states is needed.
    """
    obs, act, nxt = transitions(world, cfg)
    truth = np.asarray(jax.vmap(lambda o, a, n: world.env.reward(o, a, n, world.params))(obs, act, nxt))
    return wm.reward_error_on(obs, act, nxt, truth.astype(np.float64), fn, params)


def reference_record(world, name: str, cfg, belief: dict | None) -> dict:
    """The random policy's return, the share of its episodes that end early, and the conditions."""
    r = cfg.reference
    fn = random_host if isinstance(world, GymWorld) else random_mjx
    rets, lens = fn(world, r.random_episodes, r.seed)
    early = float(np.mean(lens < world.horizon))
    conds = conditions(world, cfg, early, belief)
    return {
        "done": f"random {rets.mean():.1f}",
        "random_return": float(rets.mean()),
        "random_return_std": float(rets.std()),
        "random_length": float(lens.mean()),
        "ended_early": early,
        "plan_return": None,
        "conditions": conds,
        "world_name": world.name,
        "belief_model": None if belief is None else {k: v for k, v in belief.items() if k != "config"},
    }


def check_person(name: str, belief: dict | None, ref: dict | None) -> None:
    """Refuse to train on ``name`` with a person other than the one its reference job recorded.

    A job's person is the learned belief fitted (or read from the cache) on the machine that runs it.
    The fit is not bit for bit the same on every number of CPU cores (XLA splits its sums by thread):
    the noisy hopper's fitted on one core scores 34.048 on its held-out transitions, on two 33.943,
    and its answers differ accordingly (docs/experiments/gym.md, "The person's fit and the machine").
    A run's seeds are one sample only with one person, so a job whose belief's figures differ from the
    reference record's is refused before it trains (nothing to check without a reference record or a
    learned belief).

    Raises:
        ValueError: the figures differ (one line: both held-out figures and the cache file to replace).
    """
    ran = (ref or {}).get("belief_model")
    if belief is None or not ran:
        return
    ours = {k: v for k, v in belief.items() if k not in ("config", "path")}
    theirs = {k: v for k, v in ran.items() if k != "path"}
    if ours != theirs:
        raise ValueError(
            f"{name}: the person's belief here is not the one the run's reference recorded (held-out log-likelihood "
            f"{ours.get('held_out_log_lik')} against {theirs.get('held_out_log_lik')}; a fit on another number of "
            f"CPU cores rounds differently): replace {belief.get('path')} with the file the run was fitted in"
        )


def belief_line(ref: dict | None) -> str | None:
    """The person's learned believed dynamics as the reference job measured them, in one line: the
    mean log-likelihood per held-out transition of the belief env, the share of those below the
    preference teacher's floor on log T_H, and the same on the true env's transitions (what the
    person finds surprising in what actually happens). None for a domain whose belief is exact (MJX).
    """
    b = (ref or {}).get("belief_model")
    if not b:
        return None
    line = (
        f"the person's believed dynamics (a Gaussian model fitted to {b['transitions']} transitions of "
        f"{b['belief_env']}): held-out log-likelihood {b['held_out_log_lik']:.1f} a transition "
        f"({100 * b['held_out_below_floor']:.1f}% below the floor on log T_H)"
    )
    if b.get("true_log_lik") is not None:
        line += f"; on the true env's transitions {b['true_log_lik']:.1f} ({100 * b['true_below_floor']:.1f}% below)"
    return line


def job_costs(records: dict) -> tuple[list[dict], str]:
    """What each finished job of the run cost, from its record: the seconds its process ran (summed
    over its seed slices: one core each, so core-seconds) and their CPU time where every slice kept
    it (slices stopped for a while ran longer than they computed). Rows, and a markdown table with
    the total so far."""
    rows = [
        {
            "job": key,
            "seeds": r.get("seeds"),
            "seconds": float(r.get("seconds", 0.0)),
            "cpu_seconds": r.get("cpu_seconds"),
        }
        for key, r in sorted(records.items())
    ]

    def cell(seconds):
        return "–" if seconds is None else f"{seconds / 3600:.2f}"

    table = [[r["job"], str(r["seeds"] or "–"), cell(r["seconds"]), cell(r["cpu_seconds"])] for r in rows]
    spent = sum(r["cpu_seconds"] if r["cpu_seconds"] is not None else r["seconds"] for r in rows)
    md = (
        markdown(["job", "seeds", "process hours", "CPU hours"], table)
        + f"\n{len(rows)} jobs finished: {spent / 3600:.1f} core-hours (CPU time where every slice kept it, "
        "else the processes' running time)\n"
    )
    return rows, md


def conditions(world, cfg, ended_early: float, belief: dict | None) -> list[dict]:
    """The conditions of docs/experiments/identifiability.md for this domain and person, as measured.

    1. β finite — the learners' teacher configuration;
    2. r_H depends on (s, a) only — whether ∂r_H/∂s' is nonzero on any random-action transition;
    3. equal segments — whether random episodes end before the horizon (share ``ended_early``);
    4. the truth has more than one outcome where the belief is biased — on MJX, whether
       ``outcomes`` fresh steps from the same (state, action) differ; a gymnasium env's state
       cannot be restored, so on the host loop it is not measured (``met`` None);
    5. the belief lies in f_φ's family — a learned belief is a Gaussian dynamics model like f_ψ,
       met when its hidden layers are PrefBias's f_ψ's; an MJX world's ``reliable`` belief is a
       point mass on the physics' next state, outside any Gaussian family.

    Returns:
        ``[{"text", "met" (True, False or None), "why"}]``.
    """
    import jax.numpy as jnp

    beta = cfg.learners.prefbias.teacher.beta
    obs, act, nxt = (jnp.asarray(x) for x in transitions(world, cfg))
    grad = jax.vmap(jax.grad(lambda o, a, n: world.env.reward(o, a, n, world.params), argnums=2))(obs, act, nxt)
    s_prime = float(jnp.mean(jnp.any(jnp.abs(grad) > 1e-6, -1)))
    out = [
        dict(
            text="the person answers by Bradley–Terry with a finite β (Eq. 3.4)",
            met=beta is not None,
            why=f"β = {beta}" if beta is not None else "deterministic answers fix no scale of the score",
        ),
        dict(
            text="r_H depends on (s, a) only, as the learner's r_w does",
            met=s_prime == 0.0,
            why=f"r_H varies with the next observation on {s_prime:.0%} of random-action transitions",
        ),
        dict(
            text="segments have equal length (a fixed horizon)",
            met=ended_early == 0.0,
            why=f"{ended_early:.0%} of random episodes end before the horizon",
        ),
    ]
    if isinstance(world, GymWorld):
        out.append(
            dict(
                text="the truth has more than one outcome wherever the belief is biased",
                met=None,
                why="not measured: a gymnasium env's state cannot be restored to draw a second outcome",
            )
        )
        pb_hidden = list(cfg.learners.prefbias.prefbias.dynamics.hidden)
        fit_hidden = list(belief["config"]["dynamics"]["hidden"]) if belief else []
        out.append(
            dict(
                text="the person's belief lies in f_φ's family",
                met=fit_hidden == pb_hidden,
                why=f"a learned Gaussian dynamics model with hidden layers {fit_hidden} (f_ψ's: {pb_hidden})",
            )
        )
    else:
        share = _stochastic_share(world, cfg, obs.shape[0])
        out.append(
            dict(
                text="the truth has more than one outcome wherever the belief is biased",
                met=share > 0.0,
                why=f"{share:.0%} of random (state, action) pairs give differing next states "
                f"over {cfg.reference.outcomes} draws",
            )
        )
        out.append(
            dict(
                text="the person's belief lies in f_φ's family",
                met=False,
                why="the reliable belief is a point mass on the physics' next state, not a Gaussian",
            )
        )
    return out


def _stochastic_share(world, cfg, count: int) -> float:
    """Share of random (state, action) pairs of a pure-JAX world whose fresh next observations differ."""
    from .. import rng

    r = cfg.reference
    k_s, k_a, k_o = jax.random.split(rng.key(r.seed + 29), 3)
    n = min(count, 200)
    states = jax.vmap(lambda k: world.env.reset(k, world.params))(jax.random.split(k_s, n))
    acts = jax.random.uniform(k_a, (n, world.env.action_space.dim), minval=-1.0, maxval=1.0)

    def spread(s, a, k):
        nxt = jax.vmap(lambda kk: world.env.observe(world.env.step(kk, s, a, world.params).state, world.params))(
            jax.random.split(k, r.outcomes)
        )
        return jax.numpy.max(jax.numpy.ptp(nxt, axis=0))

    gaps = jax.vmap(spread)(states, acts, jax.random.split(k_o, n))
    return float(np.mean(np.asarray(gaps) > 1e-4))
