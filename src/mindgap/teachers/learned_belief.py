"""A person's believed dynamics learned from a variant of a gymnasium env (§3.4.2, "the human's belief").

The terrain worlds state a belief as a table and score it exactly (``log_prob``). A
gymnasium env has no density at all, so for its simulated person the belief T_H is
*learned*: a Gaussian dynamics model — the two-headed model f_ψ of
:mod:`~mindgap.models.gaussian_dynamics`, the family PrefBias's f_φ belongs to — fitted by
maximum likelihood to transitions of the env as the person imagines it, e.g.
``gym:LunarLander-v3,continuous=True`` for a person who believes the lander flies in a
vacuum when a wind blows (:mod:`~mindgap.envs.lunar`). :func:`with_learned_belief` then gives the true world an ``env.log_prob`` that
reads the fitted model, and the preference and expectation teachers score segments with
it exactly as they score a terrain world's table (Eq. 3.5).

Choices:

* the transitions come from uniformly random actions in [−1, 1]^a (the learners'
  exploration before training), ``transitions`` steps for the fit and ``held_out`` more,
  from episodes of another seed, for its quality: the mean log-likelihood per transition
  on those, and on as many transitions of the *true* env (how far the person's
  expectation is from what happens; lower there than on the belief's own held-out steps
  when the variants differ), each with the share of steps whose log-likelihood falls below
  the preference teacher's floor (``log_t_floor``: steps the person finds all but
  impossible, where the mean alone is dominated by a few extreme values);
* no stay head: a continuous env does not repeat a state exactly;
* trained once per (belief env, configuration) and cached as
  ``<cache>/learned_belief/<hash>.npz`` with its quality beside it as JSON (the cache
  folder of :func:`~mindgap._io.cache_root`); :func:`load_learned_belief` reads such a
  file back, so a model fitted elsewhere can be handed to a run.

Written here because no library fits a person's believed dynamics; the fitting itself is
:func:`~mindgap.models.gaussian_dynamics.train_dynamics`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._io import atomic_write, cache_root
from ..checkpoint import load_pytree, save_pytree
from ..envs.gym_world import GymWorld
from ..envs.interface import EnvError
from ..models.gaussian_dynamics import (
    DynamicsConfig,
    DynamicsModel,
    dynamics_init,
    dynamics_log_prob,
    fit_norm,
    train_dynamics,
)
from .preference import TeacherConfig

CACHE_VERSION = 1
"""Part of every cache key: raise it when the stored format or the fitting changes meaning."""


@dataclasses.dataclass(frozen=True)
class BeliefFitConfig:
    """How a believed-dynamics model is fitted (every field enters the cache key)."""

    transitions: int = 20_000
    """Random-action steps of the belief env to fit on."""
    held_out: int = 2_000
    """Further steps (another seed's episodes), of the belief env and of the true env, to measure the fit on."""
    dynamics: DynamicsConfig = DynamicsConfig(max_epochs=100, patience=10)
    """The model and its training (f_ψ's architecture, so the person's belief is in f_φ's family)."""
    seed: int = 0
    """Seed of the envs, the actions and the training."""

    @classmethod
    def fast(cls) -> BeliefFitConfig:
        """A few hundred steps and a tiny network: for tests and dry runs."""
        return cls(transitions=600, held_out=200, dynamics=DynamicsConfig(hidden=(16,), max_epochs=5, patience=2))

    def check(self) -> None:
        if self.transitions < 10 or self.held_out < 1:
            raise ValueError("a belief fit needs at least 10 transitions and 1 held-out step")


class LearnedBelief(NamedTuple):
    """The params of a learned belief: the fitted model and its scale floor (an array: the env's params are traced)."""

    model: DynamicsModel
    min_std: jax.Array


def learned_log_prob(obs, act, next_obs, params: LearnedBelief) -> jax.Array:
    """log T_H(next_obs | obs, act) under a :class:`LearnedBelief`: the ``log_prob`` of an env whose belief is learned."""
    return dynamics_log_prob(params.model, obs, act, next_obs, params.min_std)


def collect(world: GymWorld, steps: int, seed: int, progress: bool = False):
    """``steps`` transitions of ``world``'s gymnasium env under uniformly random actions in [−1, 1]^a.

    Episodes restart when they end (terminated or truncated at the world's horizon).

    Returns:
        (obs [N, d], act [N, a], next_obs [N, d]) float32 NumPy arrays.
    """
    rng = np.random.default_rng(seed)
    env, o = world.make(seed)
    a_dim = len(world.act_low)
    obs, act, nxt = [], [], []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc=f"transitions of {world.name}", unit="step")
    try:
        episode = 0
        for _ in range(steps):
            a = rng.uniform(-1.0, 1.0, a_dim).astype(np.float32)
            o2, _, term, trunc, _ = env.step(world.to_env(a))
            o2 = np.asarray(o2, np.float32).reshape(-1)
            obs.append(o), act.append(a), nxt.append(o2)
            if term or trunc:
                episode += 1
                o = np.asarray(env.reset(seed=seed + 7919 * episode)[0], np.float32).reshape(-1)
            else:
                o = o2
            if bar is not None:
                bar.update()
    finally:
        env.close()
        if bar is not None:
            bar.close()
    return np.stack(obs), np.stack(act), np.stack(nxt)


def _quality(belief: LearnedBelief, data) -> tuple[float, float]:
    """Mean log-likelihood per transition of ``data``, and the share of its transitions below the
    preference teacher's floor on log T_H (steps the person finds all but impossible)."""
    obs, act, nxt = (jnp.asarray(x) for x in data)
    ll = learned_log_prob(obs, act, nxt, belief)
    return float(jnp.mean(ll)), float(jnp.mean(ll < TeacherConfig().log_t_floor))


def _same_spaces(world: GymWorld, belief_world: GymWorld) -> None:
    if world.env.observation_space.dim != belief_world.env.observation_space.dim or len(world.act_low) != len(
        belief_world.act_low
    ):
        raise EnvError(
            f"{belief_world.name} cannot be a belief about {world.name}: observations or actions differ in size"
        )


def cache_key(belief_world: GymWorld, cfg: BeliefFitConfig) -> str:
    """Hash of the belief env (its id and keyword arguments, the horizon) and of the fit's configuration."""
    h = hashlib.sha256(f"learned-belief v{CACHE_VERSION}".encode())
    h.update(json.dumps([belief_world.name, belief_world.horizon], sort_keys=True).encode())
    h.update(json.dumps(dataclasses.asdict(cfg), sort_keys=True).encode())
    return h.hexdigest()[:20]


def _template(obs_dim: int, act_dim: int, dcfg: DynamicsConfig) -> LearnedBelief:
    norm = fit_norm(jnp.zeros((1, obs_dim)), jnp.zeros((1, act_dim)), jnp.zeros((1, obs_dim)), jnp.ones(1, bool))
    return LearnedBelief(dynamics_init(jax.random.key(0), obs_dim, act_dim, dcfg, norm), jnp.float32(dcfg.min_std))


def load_learned_belief(path: str | Path) -> tuple[LearnedBelief, dict]:
    """A model saved by :func:`fit_learned_belief` (``.npz``, its ``.json`` beside it): (belief, its record)."""
    path = Path(path)
    meta_path = path.with_suffix(".json")
    if not path.is_file() or not meta_path.is_file():
        raise ValueError(f"{path}: no saved belief model there (expected {path.name} and {meta_path.name})")
    record = json.loads(meta_path.read_text())
    try:
        dcfg = DynamicsConfig(
            **{**record["config"]["dynamics"], "hidden": tuple(record["config"]["dynamics"]["hidden"])}
        )
        template = _template(int(record["obs_dim"]), int(record["act_dim"]), dcfg)
    except (KeyError, TypeError) as e:
        raise ValueError(f"{meta_path}: not a belief model's record ({e})") from None
    belief, _ = load_pytree(path, template)
    return belief, {**record, "path": str(path)}


def fit_learned_belief(
    belief_world: GymWorld,
    cfg: BeliefFitConfig = BeliefFitConfig(),
    *,
    true_world: GymWorld | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
    min_std: float | None = None,
) -> tuple[LearnedBelief, dict]:
    """Fit (or read from the cache) the person's believed dynamics to transitions of ``belief_world``.

    Args:
        belief_world: the env as the person imagines it (:func:`~mindgap.envs.gym_world.gym_world_from_spec`).
        true_world: the env as it is; its held-out transitions are scored too (``true_log_lik``).
        cache_dir: cache root (:func:`~mindgap._io.cache_root`).
        min_std: the person's own floor on her belief's spread, in units of the typical step's change
            (σ = out_std · (floor + softplus(raw))), in place of the fit's (``cfg.dynamics.min_std``): how
            sharply she expects the robot, a property of the person and not of the fit, so the fitted
            model (and its cache entry) is the same; the record's held-out figures are measured at it
            and it is recorded as ``person_min_std``. None: the fit's floor.

    Returns:
        (the belief, its record: ``path``, ``transitions``, ``epochs``, ``held_out_log_lik`` — mean
        log-likelihood per held-out transition of the belief env — and ``held_out_below_floor``, the
        share of those below the preference teacher's floor on log T_H; with ``true_world``,
        ``true_log_lik`` and ``true_below_floor``, the same on the true env's transitions).
    """
    cfg.check()
    if min_std is not None and not (isinstance(min_std, (int, float)) and min_std > 0):
        raise ValueError(f"a person's floor on her belief's spread must be positive, got {min_std!r}")
    if true_world is not None:
        _same_spaces(true_world, belief_world)
    path = cache_root(cache_dir) / "learned_belief" / f"{cache_key(belief_world, cfg)}.npz"
    held = None  # the belief env's held-out steps, once collected
    if path.is_file() and path.with_suffix(".json").is_file():
        belief, record = load_learned_belief(path)
    else:
        obs, act, nxt = collect(belief_world, cfg.transitions, cfg.seed, progress)
        valid = jnp.ones(obs.shape[0], bool)
        o, a, n = jnp.asarray(obs), jnp.asarray(act), jnp.asarray(nxt)
        start = dynamics_init(jax.random.key(cfg.seed), o.shape[1], a.shape[1], cfg.dynamics, fit_norm(o, a, n, valid))
        model, info = jax.jit(train_dynamics, static_argnames="cfg")(
            jax.random.key(cfg.seed + 1), o, a, n, valid, cfg=cfg.dynamics, init=start
        )
        belief = LearnedBelief(model, jnp.float32(cfg.dynamics.min_std))
        held = collect(belief_world, cfg.held_out, cfg.seed + 1)
        record = {
            "belief_env": belief_world.name,
            "obs_dim": int(o.shape[1]),
            "act_dim": int(a.shape[1]),
            "config": dataclasses.asdict(cfg),
            "transitions": int(cfg.transitions),
            "epochs": int(info.epochs),
        }
        record["held_out_log_lik"], record["held_out_below_floor"] = _quality(belief, held)
        path.parent.mkdir(parents=True, exist_ok=True)
        save_pytree(path, belief)
        atomic_write(path.with_suffix(".json"), json.dumps(record, indent=2))
    if min_std is not None:
        belief = belief._replace(min_std=jnp.float32(min_std))
        record = {**record, "person_min_std": float(min_std)}
        held = held if held is not None else collect(belief_world, cfg.held_out, cfg.seed + 1)
        record["held_out_log_lik"], record["held_out_below_floor"] = _quality(belief, held)
    if true_world is not None:
        record["true_env"] = true_world.name
        record["true_log_lik"], record["true_below_floor"] = _quality(
            belief, collect(true_world, cfg.held_out, cfg.seed + 1)
        )
    record["path"] = str(path)
    return belief, record


def with_learned_belief(world: GymWorld, name: str, belief: LearnedBelief) -> GymWorld:
    """``world`` whose simulated person believes ``belief`` (its only belief, named ``name``); its env's
    ``log_prob`` reads the belief's model (:func:`learned_log_prob`)."""
    env = dataclasses.replace(world.env, log_prob=learned_log_prob)
    return dataclasses.replace(world, env=env, beliefs={name: belief})
