"""The simulated person's expected policy π_H for the terrain worlds (§4.3.3), trained once and cached.

π_H is the person's expectation of the agent: soft-optimal for r_H under their belief T_H.
For a terrain world it is therefore SAC — the maximum-entropy, i.e. soft,
optimum — trained on the world's reward with the person's dynamics table (the person's
reward is the world's, as in the dissertation's d1–d4: only the belief about the dynamics
differs). A policy from value iteration on the discretised belief world would give an
action distribution over the 16 compass actions only, with no density over continuous
actions, which the score of :mod:`~mindgap.teachers.expectation` and the explicability
score (Eq. 4.4) need; SAC's tanh-Gaussian actor has one (:func:`expected_log_prob`).

SAC on the sparse-goal terrain worlds fails on some seeds (docs/experiments/pbrl.md).
:func:`train_expected_policy` therefore trains ``seeds`` seeds in one vmapped program and
keeps the one whose greedy policy earns the most in the belief world — the person's
expectation of a competent agent, not of one that idles.

Training costs minutes, so :func:`expected_policy` stores the actor under
``<cache>/expected_policy/<hash>.npz``; the hash covers every array of the belief world
(layout, rewards, the person's dynamics table, horizon) and the training configuration,
so any change of world, belief or configuration trains anew. The cache folder is
``$MINDGAP_CACHE`` or ``~/.cache/mindgap`` unless given.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json

import jax
import jax.numpy as jnp
import numpy as np

from .. import rng
from .._io import cache_root
from ..checkpoint import load_pytree, save_pytree
from ..data.fingerprint import identity_leaves
from ..envs.gym_world import GymWorld, gym_world_from_spec, refuse_without_dynamics
from ..envs.interface import Env, World
from ..models.mlp import Params
from ..teachers.expectation import ExpectationTeacher
from .sac import SACConfig
from .sac_loop import agent_init, evaluate, loop_init, run_chunk

CACHE_VERSION = 1
"""Part of every cache key: raise it when the stored format or the training changes meaning."""


@dataclasses.dataclass(frozen=True)
class ExpectedPolicyConfig:
    """How π_H is trained (every field enters the cache key)."""

    total_steps: int = 30_000
    """Environment steps per seed."""
    chunk: int = 1000
    """Steps per jitted chunk (``total_steps`` and ``sac.learning_starts`` are multiples of it)."""
    seeds: int = 5
    """Seeds trained side by side; the best in the belief world is kept."""
    eval_episodes: int = 20
    """Greedy episodes that rank the seeds."""
    sac: SACConfig = SACConfig(hidden=(64, 64), learning_starts=5000)
    """SAC of π_H; 5000 random steps first, which found d1's goal in the most seeds (docs/experiments/pbrl.md)."""
    seed: int = 0
    """Base seed."""

    @classmethod
    def fast(cls) -> ExpectedPolicyConfig:
        """A few hundred steps of a tiny network: for tests and smoke runs, not for experiments."""
        return cls(total_steps=200, chunk=100, seeds=1, sac=SACConfig(hidden=(8,), learning_starts=0, batch_size=32))

    def check(self) -> None:
        if self.total_steps % self.chunk or self.sac.learning_starts % self.chunk:
            raise ValueError(f"total_steps and sac.learning_starts must be multiples of chunk ({self.chunk})")
        if self.sac.learning_starts >= self.total_steps:
            raise ValueError("sac.learning_starts leaves no training steps")
        if self.seeds < 1 or self.eval_episodes < 1:
            raise ValueError("seeds and eval_episodes must be at least 1")


def cache_key(belief_params, cfg: ExpectedPolicyConfig, salt=None) -> str:
    """Hash of the belief world's arrays (shapes and dtypes included), of the training configuration and,
    when given, of ``salt`` (JSON: on a gym world the name and horizon of the env π_H is trained in)."""
    h = hashlib.sha256(f"expected-policy v{CACHE_VERSION}".encode())
    if salt is not None:
        h.update(json.dumps(salt).encode())
    for leaf in identity_leaves(belief_params):
        a = np.asarray(leaf)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    h.update(json.dumps(dataclasses.asdict(cfg), sort_keys=True).encode())
    return h.hexdigest()[:20]


def _actor_template(env: Env, cfg: ExpectedPolicyConfig) -> Params:
    return agent_init(jax.random.key(0), env, cfg.sac).params.actor  # a Gaussian or a categorical actor


def train_expected_policy(world: World, belief_params, cfg: ExpectedPolicyConfig) -> tuple[Params, np.ndarray]:
    """SAC on the belief world's own reward, ``cfg.seeds`` seeds at once; the best seed's actor.

    Returns:
        (actor parameters, mean greedy return of every seed in the belief world [seeds]; NaN
        for a single seed, which is not evaluated).
    """
    cfg.check()
    keys = jax.random.split(rng.key(cfg.seed), cfg.seeds)
    env = world.env
    init = jax.jit(jax.vmap(lambda k, p: loop_init(k, env, p, cfg.sac, cfg.total_steps), (0, None)))
    loop = init(keys, belief_params)
    for start in range(0, cfg.total_steps, cfg.chunk):
        phase = "random" if start < cfg.sac.learning_starts else "train"
        loop = jax.vmap(
            lambda ls: run_chunk(ls, env, belief_params, None, n_steps=cfg.chunk, cfg=cfg.sac, phase=phase)
        )(loop)
    actors = [jax.tree.map(lambda x, i=i: x[i], loop.sac.params.actor) for i in range(cfg.seeds)]
    if cfg.seeds == 1:
        return actors[0], np.full(1, np.nan)  # nothing to rank
    eval_keys = jax.random.split(rng.key(cfg.seed + 1), cfg.seeds)
    # one seed at a time: the compiled rollouts of an unbatched actor serve every seed
    returns = np.array(
        [
            float(evaluate(k, env, a, belief_params, cfg.eval_episodes, world.horizon)[0].mean())
            for k, a in zip(eval_keys, actors)
        ]
    )
    return actors[int(np.argmax(returns))], returns


def train_expected_policy_host(
    belief_world: GymWorld, cfg: ExpectedPolicyConfig, progress: bool = False
) -> tuple[Params, np.ndarray]:
    """π_H on a gym world: SAC on the host (:mod:`~mindgap.algorithms.host_loop`) in the env as the person
    imagines it, ``cfg.seeds`` seeds; the actor of the seed with the best greedy return at the end."""
    from .pbrl import method_config, train

    sac = method_config(
        "sac", total_steps=cfg.total_steps, chunk=cfg.chunk, eval_every=cfg.total_steps,
        eval_episodes=cfg.eval_episodes, sac=cfg.sac, seed=cfg.seed,
    )  # fmt: skip
    res = train(belief_world, sac, seeds=cfg.seeds, teacher="true", progress=progress)
    returns = np.asarray(res["final_returns"]).mean(1)
    best = int(np.argmax(returns))
    return jax.tree.map(lambda x: x[best], res["carry"].loop.sac.params.actor), returns


def expected_policy(
    world: World,
    belief_params,
    cfg: ExpectedPolicyConfig = ExpectedPolicyConfig(),
    cache_dir=None,
    belief_world=None,
    progress: bool = False,
) -> Params:
    """π_H's actor for the person whose view of the world is ``belief_params``: from the cache, else trained and stored.

    Args:
        belief_params: the world under the person's dynamics table (``world.belief(name)``;
            ``world.params`` for a person who knows the true dynamics); on a gym world the
            person's learned model (:mod:`~mindgap.teachers.learned_belief`).
        cfg: training configuration (part of the cache key).
        cache_dir: cache root; None uses :func:`cache_root`.
        belief_world: on a gym world, the env as the person imagines it, where π_H is trained
            (:func:`train_expected_policy_host`).
        progress: a progress bar while π_H trains on the host (the jitted training has none).
    """
    gym = isinstance(world, GymWorld)
    if gym and belief_world is None:
        raise ValueError("π_H on a gym world is trained in the env the person imagines: pass belief_world")
    salt = (belief_world.name, belief_world.horizon) if gym else None
    path = cache_root(cache_dir) / "expected_policy" / f"{cache_key(belief_params, cfg, salt)}.npz"
    template = _actor_template(world.env, cfg)
    if path.exists():
        actor, _ = load_pytree(path, template)
        return actor
    if gym:
        actor, returns = train_expected_policy_host(belief_world, cfg, progress)
    else:
        actor, returns = train_expected_policy(world, belief_params, cfg)
    actor = jax.tree.map(lambda t, a: jnp.asarray(a, t.dtype), template, actor)
    save_pytree(path, actor, returns=np.asarray(returns), config=json.dumps(dataclasses.asdict(cfg)))
    return actor


def expectation_teacher(
    world: World,
    belief: str | None = None,
    *,
    unbiased: bool = False,
    policy_cfg: ExpectedPolicyConfig = ExpectedPolicyConfig(),
    cache_dir=None,
    progress: bool = False,
) -> ExpectationTeacher:
    """The simulated person of ``world``: belief ``belief`` (default the world's first), π_H from the cache.

    Args:
        unbiased: the person knows the true dynamics (Fig. 29); ``belief`` is then ignored.
        policy_cfg: how π_H is trained when the cache does not hold it.
        cache_dir: cache root (see :func:`cache_root`).
        progress: a progress bar while π_H trains on a gym world.
    """
    if isinstance(world, GymWorld):
        # the person's belief is a learned model of a variant of the env, named by its spec; π_H is trained there
        refuse_without_dynamics(world, "EPS's simulated person")
        if unbiased:
            raise ValueError("on a gym world an unbiased person believes a learned model of the true env itself")
        name = belief or next(iter(world.beliefs))
        params = world.belief(name)
        belief_world = gym_world_from_spec(name)
        actor = expected_policy(world, params, policy_cfg, cache_dir, belief_world=belief_world, progress=progress)
        return ExpectationTeacher(params, actor, world.env)
    params = world.params if unbiased else world.belief(belief)
    return ExpectationTeacher(params, expected_policy(world, params, policy_cfg, cache_dir), world.env)
