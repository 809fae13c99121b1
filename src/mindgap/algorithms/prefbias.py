"""PrefBias (Algorithm 2): preference-based RL that learns the person's belief along with the reward.

The loop of Algorithm 2 on the engine of :mod:`~mindgap.algorithms.engine` (same phases,
checkpoints, evaluation and curve rows), vmapped over seeds in jitted chunks:

1. ``random`` steps until ``sac.learning_starts``, then (optionally, as PEBBLE)
   ``explore``: SAC on the state-entropy reward for ``explore_steps``, critic reset after;
2. every ``feedback_every`` steps while the budget lasts, a feedback round:

   * train the agent's dynamics model f_ψ on the replay buffer D_dyna (line 4; §3.3.3.4),
     from scratch the first time, warm-started (``init=``) after, so its normalisation —
     which f_φ reads — stays fixed;
   * re-centre the belief prior p(φ) on the new f_ψ (``belief_prior="dynamics"``, §3.3.3.1);
   * select K = ``per_round`` of ``candidates × K`` random pairs of segments with the
     sampler (default ``preference_disagreement``, §3.3.3.3) and ask the person (line 6):
     the simulated teacher of :mod:`~mindgap.teachers.preference` (biased: r_H + log T_H;
     true: r_H) or a host teacher (people through the study app);
   * fit q(w) q(φ) to all answers by the negative ELBO (line 7; Eqs. 3.2–3.5);
   * relabel the whole buffer with the posterior-mean reward r_w (PEBBLE's relabelling),
     and with ``prefbias.absorbing`` the terminal transitions with the value of their
     absorbing state on top (:func:`~mindgap.data.replay.terminal_bonus`);

3. in between, SAC on the relabelled reward under the true dynamics (line 9).

The first round also initialises the posteriors (line 1): q(φ) starts at the first f_ψ.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..envs.gym_world import refuse_without_dynamics
from ..envs.interface import Env, check_env
from ..feedback.queries import check_sampler
from ..models.gaussian_dynamics import DynamicsConfig, DynamicsModel, Norm, dynamics_init, fit_norm, train_dynamics
from ..models.prefbias_nets import absorbing_value, posterior_reward
from ..teachers.host import HostTeacher
from .engine import FAST_SCHEDULE, Learner, Schedule, preference_teacher
from .prefbias_inference import PrefBiasConfig, PrefBiasState, fit, prefbias_init, with_dynamics
from .prefbias_queries import select_queries


@dataclasses.dataclass(frozen=True)
class PrefBiasLoopConfig(Schedule):
    """One PrefBias run (all seeds share it; hashable, a static jit argument); the schedule's fields are :class:`Schedule`'s."""

    total_steps: int = 50_000
    """Environment steps per seed. Longer than the engine's 40 000, so that SAC trains long on the final
    reward: the reward and the belief still change until the last feedback round (step 22 000 with
    800 queries, 80 a round); docs/experiments/prefbias.md."""
    method: str = "prefbias"
    """Always 'prefbias' (the engine's schedule reads it)."""
    prefbias: PrefBiasConfig = PrefBiasConfig()
    """Inference of r_w and f_φ, and the dynamics model f_ψ (``prefbias.dynamics``)."""
    sampler: str = "preference_disagreement"
    """uniform, disagreement, entropy or preference_disagreement (§3.3.3.3)."""
    candidates: int = 3
    """Random pairs drawn per query kept (3K candidates, §3.3.3.3)."""
    samples: int = 8
    """Posterior draws for the disagreement and entropy samplers."""
    explore_steps: int = 4000
    """State-entropy pre-training steps (as PEBBLE; 0 for none)."""
    reset_critic: bool = True
    """Re-initialise the critic after pre-training (as PEBBLE)."""

    def as_dict(self) -> dict:
        """The run record's config; ``prefbias.absorbing``, ``prefbias.stay_head`` and ``prefbias.noise_local``
        (with its prior) only when on, and
        ``prefbias.absorbing_state`` only when not the default, ``prefbias.log_f_floor`` and
        ``prefbias.scale_prior_std`` only when set, so run folders from before them still resume."""
        d = super().as_dict()
        for name in ("absorbing", "stay_head"):
            if not getattr(self.prefbias, name):
                del d["prefbias"][name]
        if not self.prefbias.noise_local:  # recorded only when on, so run folders from before it still resume
            del d["prefbias"]["noise_local"], d["prefbias"]["noise_prior_std"]
        if not self.prefbias.absorbing or self.prefbias.absorbing_state == "terminal":
            del d["prefbias"]["absorbing_state"]
        for name in ("log_f_floor", "scale_prior_std"):  # recorded only when set (run folders from before resume)
            if getattr(self.prefbias, name) is None:
                del d["prefbias"][name]
        return d

    def check(self) -> None:
        if self.method != "prefbias":
            raise ValueError(f"method must be 'prefbias', got {self.method!r}")
        check_sampler(self.sampler, belief=True)
        self.prefbias.check()
        self.check_schedule()
        if self.queries < 1 or self.per_round < 1 or self.candidates < 1:
            raise ValueError("queries, per_round and candidates must be at least 1")


_FAST = dict(
    **FAST_SCHEDULE,
    explore_steps=250,
    prefbias=PrefBiasConfig(
        reward_hidden=(8, 8),
        updates=10,
        check_every=5,
        batch_size=8,
        dynamics=DynamicsConfig(hidden=(8, 8), max_epochs=3, steps_per_epoch=5, batch_size=32),
    ),
)
PRESETS = ("full", "fast")


def prefbias_config(preset: str = "full", **overrides) -> PrefBiasLoopConfig:
    """A preset with ``overrides`` applied, checked.

    ``full``: the defaults of :class:`PrefBiasLoopConfig`. ``fast``: tiny networks and fits,
    1500 steps, 30 queries — seconds once compiled; for tests and dry runs, not for results.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}: choose from {', '.join(PRESETS)}")
    base = _FAST if preset == "fast" else {}
    cfg = PrefBiasLoopConfig(**{**base, **overrides})
    cfg.check()
    return cfg


class PrefBiasModel(NamedTuple):
    """One seed's PrefBias model: the posteriors q(w) q(φ), the agent's dynamics model f_ψ, and
    whether the first feedback round has initialised them (Alg. 2, line 1)."""

    posterior: PrefBiasState
    dynamics: DynamicsModel
    started: jax.Array = jnp.zeros((), bool)


def _init(key, env: Env, cfg: PrefBiasLoopConfig):
    # Placeholders of the right structure: the first feedback round fits f_ψ and its
    # normalisation and initialises the posteriors from it (Alg. 2, line 1).
    pcfg = cfg.prefbias
    d, a = env.observation_space.dim, env.action_space.dim
    k_loop, k_dyn, k_model, k_run = jax.random.split(key, 4)
    norm = Norm(jnp.zeros(d + a), jnp.ones(d + a), jnp.zeros(d), jnp.ones(d))
    dyn = dynamics_init(k_dyn, d, a, pcfg.dynamics, norm, stay=pcfg.stay_head)
    return PrefBiasModel(prefbias_init(k_model, d, a, pcfg, dyn, jnp.ones(d)), dyn), k_loop, k_run


def _select(m: PrefBiasModel, buf, key, w, env, cfg: PrefBiasLoopConfig):
    """Lines 4 and 6 of Alg. 2 for one seed: (re)train f_ψ, re-centre p(φ), pick the queries.

    In the first round (the posteriors still at their placeholder) f_ψ starts afresh with the
    normalisation of the buffer and the posteriors are initialised from it (line 1); later
    rounds warm-start f_ψ and keep the posteriors. Both cases are one program (a select, not a
    branch), so a run compiles one feedback round.
    """
    pcfg = cfg.prefbias
    key, k_dyn, k_psi0, k_init, k_q, k_t, k_r = jax.random.split(key, 7)
    d, a = buf.obs.shape[-1], buf.act.shape[-1]
    valid = jnp.arange(buf.capacity) < buf.size
    first = ~m.started
    norm = fit_norm(buf.obs, buf.act, buf.next_obs, valid)
    fresh = dynamics_init(k_psi0, d, a, pcfg.dynamics, norm, stay=pcfg.stay_head)
    start = _where(first, fresh, m.dynamics)
    dyn, _ = train_dynamics(k_dyn, buf.obs, buf.act, buf.next_obs, valid, pcfg.dynamics, init=start)
    model = _where(first, prefbias_init(k_init, d, a, pcfg, dyn, w.units), with_dynamics(m.posterior, dyn, pcfg))
    seg_a, seg_b = select_queries(
        k_q, buf, model, dyn, cfg.per_round, cfg.segment, cfg.sampler, pcfg, cfg.candidates, cfg.samples,
        from_start=cfg.queries_from_start,
    )  # fmt: skip
    return PrefBiasModel(model, dyn, jnp.ones((), bool)), seg_a, seg_b, (key, k_t, k_r)


def _absorbing_fn(cfg: PrefBiasLoopConfig):
    """The engine's ``absorbing_fn``: r_abs at the posterior mean, or None without absorbing states."""
    return absorbing_value if cfg.prefbias.absorbing else None


def _where(cond, a, b):
    return jax.tree.map(lambda x, y: jnp.where(cond, x, y), a, b)


def _learn(m: PrefBiasModel, prefs, replay, key, w, env, cfg: PrefBiasLoopConfig):
    """Line 7 of Alg. 2 for one seed: fit q(w) q(φ) to every answer so far (Eqs. 3.2–3.5)."""
    posterior, info = fit(m.posterior, prefs, key, cfg.prefbias)
    return m._replace(posterior=posterior), info


def _reward(m: PrefBiasModel, w, env, cfg: PrefBiasLoopConfig):
    """Line 9: SAC optimises the posterior-mean reward r_w (and its absorbing states' value)."""
    return posterior_reward, m.posterior.reward.mean, _absorbing_fn(cfg)


LEARNER = Learner(_init, _select, _learn, _reward, absorbing=lambda cfg: cfg.prefbias.absorbing)
"""PrefBias (Algorithm 2) as a :class:`~mindgap.algorithms.engine.Learner`."""


def learned_reward(m: PrefBiasModel):
    """What PrefBias learned, as ``(reward_fn, params)``: r_w at its posterior mean."""
    return posterior_reward, m.posterior.reward.mean


def prepare(
    world, cfg: PrefBiasLoopConfig, seeds: int, teacher: str | HostTeacher = "biased", belief: str | None = None
):
    """The engine's ``(teacher, meta, oracle)`` for :func:`~mindgap.algorithms.engine.run` (no oracle)."""
    refuse_without_dynamics(world, "PrefBias")
    person, meta = preference_teacher(world, cfg, seeds, teacher, belief, who="PrefBias")
    check_env(world.env, density=True, who="PrefBias")
    return person, meta, None


def train(
    world,
    cfg: PrefBiasLoopConfig,
    seeds: int = 1,
    teacher: str | HostTeacher = "biased",
    belief: str | None = None,
    out: Path | None = None,
    progress: bool = True,
    fresh: bool = False,
) -> dict:
    """Run ``seeds`` seeds of PrefBias (Algorithm 2) on a terrain world; checkpoint to ``out``.

    Args:
        world: a :class:`~mindgap.envs.terrain.TerrainWorld`.
        teacher: ``"biased"`` (r_H + log T_H under ``belief``, default the world's first),
            ``"true"`` (r_H only) or a :class:`~mindgap.teachers.host.HostTeacher`.

    Returns:
        the dict of :func:`mindgap.algorithms.engine.run` (``curve``, ``final_returns``,
        ``paths``, ``config``, ``carry``); on a terrain world,
        :func:`~mindgap.planning.terrain_maps.noise_maps` draws the learned belief from ``carry``.
    """
    from . import methods

    return methods.train(
        methods.PREFBIAS, world, cfg, seeds, out=out, progress=progress, fresh=fresh, teacher=teacher, belief=belief
    )
