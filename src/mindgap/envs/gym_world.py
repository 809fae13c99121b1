"""gymnasium environments as worlds that learners step on the host (``--env gym:Pendulum-v1,g=9.81``).

A :class:`GymWorld` is a :class:`~mindgap.envs.interface.World` whose env cannot be traced:
its ``reset``/``step``/``observe`` refuse (the host loop,
:mod:`~mindgap.algorithms.host_loop`, steps :meth:`GymWorld.make`'s gymnasium envs in
numpy instead), while its spaces are the interface's — a flat observation :class:`Box` and
actions in [−1, 1]^a, which :meth:`GymWorld.to_env` maps affinely onto the env's bounds.

For a simulated person on the true reward, :data:`REWARDS` holds exact pure-JAX rewards
``reward(obs, act, next_obs, params)`` (``act`` the agent's, in [−1, 1]) of the envs whose
reward is a function of the transition's observations: Pendulum-v1 and
MountainCarContinuous-v0, transcribed from gymnasium's ``classic_control`` sources, and the
continuous lunar lander's (:func:`~mindgap.envs.lunar.lander_reward`; with the solar wind of
:mod:`~mindgap.envs.lunar` too), and the MuJoCo hopper's and half-cheetah's where the observation
holds the x position (:mod:`~mindgap.envs.mujoco_noise`, with or without its hidden noise). Other
ids, and a user's own env from a file (:func:`user_gym_world`), get no reward function: SAC runs, and
the ordinary simulated person (``--teacher true``) sums the rewards the env returned. A gym world has no
exact ``log_prob``: a biased person's belief is learned from a variant of the env
(:mod:`~mindgap.teachers.learned_belief`), and learners that need it refuse a gym world
without one (:func:`refuse_without_dynamics`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import re
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .driving.highway import register as register_driving
from .interface import Box, Env, EnvError, World
from .lunar import ENV_ID as LANDER_ID
from .lunar import lander_reward
from .lunar import register as register_lander
from .mujoco_noise import CHEETAH, HOPPER, cheetah_reward, hopper_reward, reward_params
from .mujoco_noise import register as register_noisy


def register_envs() -> None:
    """Register this package's gymnasium ids (the solar-wind lander, the noisy hopper and cheetah, the sleety
    highway of :mod:`~mindgap.envs.driving.highway`)."""
    register_lander()
    register_noisy()
    register_driving()


def _host_only(*_args, **_kwargs):
    raise EnvError("a gym world steps on the host (mindgap.algorithms.host_loop); it has no JAX reset/step/observe")


def _scaled(act, p):
    """The env's action of the agent's ``act`` in [−1, 1]: ``low + (act + 1)(high − low)/2``, clipped."""
    return jnp.clip(p["low"] + (act + 1.0) * 0.5 * (p["high"] - p["low"]), p["low"], p["high"])


def pendulum_reward(obs, act, next_obs, params):
    """Pendulum-v1's reward ``−(θ² + 0.1 θ̇² + 0.001 u²)`` of the state before the step.

    ``obs = (cos θ, sin θ, θ̇)``; θ normalised to [−π, π) as gymnasium's ``angle_normalize``
    (atan2 differs only at ±π, where θ² is the same); ``u`` the torque clipped to ±max_torque.
    """
    u = _scaled(act, params)[0]
    th = jnp.arctan2(obs[1], obs[0])
    return -(th**2 + 0.1 * obs[2] ** 2 + 0.001 * u**2)


def mountain_car_reward(obs, act, next_obs, params):
    """MountainCarContinuous-v0's reward: 100 on reaching the goal (next position ≥ goal_position and
    next velocity ≥ goal_velocity, the termination test) minus ``0.1 force²`` (the action before clipping)."""
    force = params["low"] + (act[0] + 1.0) * 0.5 * (params["high"] - params["low"])
    goal = (next_obs[0] >= params["goal_position"]) & (next_obs[1] >= params["goal_velocity"])
    return jnp.where(goal, 100.0, 0.0) - 0.1 * force[0] ** 2


REWARDS = {
    "Pendulum-v1": (pendulum_reward, lambda kw: {}),
    "LunarLander-v3": (lander_reward, lambda kw: {}),
    LANDER_ID: (lander_reward, lambda kw: {}),
    "Hopper-v5": (hopper_reward, reward_params(**HOPPER, excluded_by_default=True)),
    "HalfCheetah-v5": (cheetah_reward, reward_params(**CHEETAH, excluded_by_default=True)),
    "mindgap/NoisyHopper-v0": (hopper_reward, reward_params(**HOPPER, excluded_by_default=False)),
    "mindgap/NoisyHalfCheetah-v0": (cheetah_reward, reward_params(**CHEETAH, excluded_by_default=False)),
    "MountainCarContinuous-v0": (
        mountain_car_reward,
        lambda kw: {"goal_position": 0.45, "goal_velocity": float(kw.get("goal_velocity", 0.0))},
    ),
}
"""id → (reward, kwargs → its params beyond the action bounds, or None where the env so made has no reward
the observations determine)."""


@dataclasses.dataclass(frozen=True, eq=False)
class GymWorld(World):
    """A gymnasium env as a world: ``env_id`` and ``kwargs`` make it; ``params`` hold the reward's numbers.

    Attributes:
        env_id: the gymnasium id (``Pendulum-v1``).
        kwargs: keyword arguments of ``gymnasium.make`` as sorted (key, value) pairs.
        act_low, act_high: the env's action bounds, per dimension.
    """

    env_id: str = ""
    kwargs: tuple = ()
    act_low: tuple = ()
    act_high: tuple = ()
    entry: str = ""
    """For a user's env (``--env path.py:factory``): ``path.py:factory`` with the path made absolute,
    which :meth:`make` registers again in a process that has not (a sweep's worker); else empty."""

    def make(self, seed: int | None = None, render_mode: str | None = None):
        """A fresh gymnasium env (time-limited at ``horizon``, drawing itself with ``render_mode``), reset with
        ``seed``; returns (env, obs)."""
        import gymnasium

        register_envs()
        if self.entry and self.env_id not in gymnasium.registry:
            register_user_env(self.entry)
        extra = {} if render_mode is None else {"render_mode": render_mode}
        env = gymnasium.make(self.env_id, max_episode_steps=self.horizon, **dict(self.kwargs), **extra)
        obs, _ = env.reset(seed=seed)
        return env, np.asarray(obs, np.float32).reshape(-1)

    def to_env(self, act: np.ndarray) -> np.ndarray:
        """The env's action of the agent's ``act`` in [−1, 1] (affine onto its bounds, clipped)."""
        low, high = np.asarray(self.act_low, np.float32), np.asarray(self.act_high, np.float32)
        return np.clip(low + (np.asarray(act, np.float32) + 1.0) * 0.5 * (high - low), low, high)

    def fingerprint_tree(self):
        """The reward's params, the action bounds (the id and kwargs are in the world's name) and, when the
        person's belief is learned (:mod:`~mindgap.teachers.learned_belief`), the beliefs."""
        tree = (self.params, np.asarray(self.act_low, np.float32), np.asarray(self.act_high, np.float32))
        return (*tree, dict(self.beliefs)) if self.beliefs else tree


def make_gym_world(env_id: str, **kwargs) -> GymWorld:
    """The :class:`GymWorld` of gymnasium's ``env_id`` made with ``kwargs``; one-line EnvError otherwise."""
    return _gym_world(env_id, kwargs, f"gym:{env_id}")


def _gym_world(env_id: str, kwargs: dict, who: str) -> GymWorld:
    """:func:`make_gym_world`, its errors naming the env as ``who`` (``gym:ID`` or a user's ``path.py:factory``)."""
    import gymnasium

    register_envs()
    try:
        probe = gymnasium.make(env_id, **kwargs)
    except gymnasium.error.Error as e:
        raise EnvError(f"{who}: {type(e).__name__}: {e}".splitlines()[0]) from None
    except Exception as e:
        raise EnvError(f"{who}: cannot make it: {type(e).__name__}: {e}".splitlines()[0]) from None
    try:
        obs_space, act_space = probe.observation_space, probe.action_space
        horizon = probe.spec.max_episode_steps if probe.spec is not None else None
    finally:
        probe.close()
    if not isinstance(act_space, gymnasium.spaces.Box) or len(act_space.shape) != 1:
        raise EnvError(f"{who}: mindgap's learners need a flat Box action space, this env has {act_space}")
    if not (np.all(np.isfinite(act_space.low)) and np.all(np.isfinite(act_space.high))):
        raise EnvError(f"{who}: its action bounds are not finite, so actions in [-1, 1] cannot be scaled")
    if not isinstance(obs_space, gymnasium.spaces.Box):
        raise EnvError(f"{who}: mindgap's learners need a Box observation space, this env has {obs_space}")
    if not horizon:
        raise EnvError(f"{who}: it declares no max_episode_steps; pass one, e.g. {who},max_episode_steps=500")
    low, high = (tuple(float(x) for x in b) for b in (act_space.low, act_space.high))
    params = {"low": jnp.asarray(low, jnp.float32), "high": jnp.asarray(high, jnp.float32)}
    reward = None
    if env_id in REWARDS:
        reward, extra = REWARDS[env_id]
        more = extra(kwargs)
        if more is None:
            reward = None
        else:
            params.update({k: jnp.asarray(v, jnp.float32) for k, v in more.items()})
    d = int(np.prod(obs_space.shape))
    obs_bounds = (float(np.min(obs_space.low)), float(np.max(obs_space.high)))
    env = Env(_host_only, _host_only, _host_only, Box((d,), *obs_bounds), Box((len(low),)), reward=reward)
    name = "gym:" + ",".join([env_id, *(f"{k}={v}" for k, v in sorted(kwargs.items()))])
    return GymWorld(
        name,
        env,
        params,
        horizon=int(horizon),
        source=name,
        env_id=env_id,
        kwargs=tuple(sorted(kwargs.items())),
        act_low=low,
        act_high=high,
    )


def gym_world_from_spec(spec: str) -> GymWorld:
    """``gym:ID,key=value,…`` → :func:`make_gym_world` (``max_episode_steps`` sets the horizon)."""
    from .resolve import parse_kwargs

    head, _, rest = spec.partition(",")
    env_id = head[len("gym:") :].strip()
    if not env_id:
        raise EnvError(f"{spec}: expected gym:ID (gym:Pendulum-v1)")
    kwargs = parse_kwargs(rest)
    steps = kwargs.pop("max_episode_steps", None)
    world = make_gym_world(env_id, **kwargs)
    if steps is not None:
        if not isinstance(steps, int) or steps < 1:
            raise EnvError(f"{spec}: max_episode_steps must be a positive integer")
        world = dataclasses.replace(world, horizon=steps, name=f"{world.name},max_episode_steps={steps}")
    return world


def user_env_id(entry: str) -> str:
    """The gymnasium id under which a user's ``path.py:factory`` (or ``module:factory``) is registered:
    ``mindgap-user/STEM.FACTORY_HASH-v0``, the hash telling apart two files of one name."""
    target, _, factory = entry.rpartition(":")
    stem = Path(target).stem if target.endswith(".py") else target.rsplit(".", 1)[-1]
    digest = hashlib.sha1(entry.encode()).hexdigest()[:8]
    safe = (re.sub(r"[^A-Za-z0-9_]", "_", x) for x in (stem, factory))
    return f"mindgap-user/{'.'.join(safe)}_{digest}-v0"


def register_user_env(entry: str, factory=None, max_episode_steps: int | None = None) -> str:
    """Register a user's env factory (``entry`` = ``path.py:factory``; ``factory`` the callable, imported
    from ``entry`` when None) with gymnasium once per process; returns its id (:func:`user_env_id`)."""
    import gymnasium

    env_id = user_env_id(entry)
    if env_id not in gymnasium.registry:
        if factory is None:
            from .resolve import import_factory

            factory = import_factory(entry)
        gymnasium.register(env_id, entry_point=factory, max_episode_steps=max_episode_steps)
    return env_id


def _declared_steps(env) -> int | None:
    """The episode limit a made env carries: its spec's ``max_episode_steps`` or a TimeLimit wrapper's."""
    spec = getattr(env, "spec", None)
    if spec is not None and spec.max_episode_steps:
        return int(spec.max_episode_steps)
    while env is not None:
        limit = getattr(env, "_max_episode_steps", None)
        if limit:
            return int(limit)
        env = getattr(env, "env", None)
    return None


def user_gym_world(entry: str, who: str, factory, kwargs: dict, made, max_episode_steps: int | None) -> GymWorld:
    """The :class:`GymWorld` of a user's factory (or class) whose call ``made`` a ``gymnasium.Env``.

    It runs through the host loop as a ``gym:ID`` world does, under the name ``who,key=value…``.
    The horizon is ``max_episode_steps`` if given, else the limit the made env carries (a
    TimeLimit or its spec). It has no exact reward: the ordinary simulated person
    (``--teacher true``) sums the rewards the env returned
    (:func:`~mindgap.teachers.preference.segment_scores`), as B-Pref's scripted teacher does.
    """
    declared = _declared_steps(made)
    with contextlib.suppress(Exception):  # the probe is only read; a close that fails changes nothing
        made.close()
    if max_episode_steps is not None and (not isinstance(max_episode_steps, int) or max_episode_steps < 1):
        raise EnvError(f"{who}: max_episode_steps must be a positive integer")
    if not (declared or max_episode_steps):
        raise EnvError(f"{who}: it declares no max_episode_steps; pass one, e.g. {who},max_episode_steps=500")
    env_id = register_user_env(entry, factory, declared or max_episode_steps)
    world = _gym_world(env_id, kwargs, who)
    name = ",".join([who, *(f"{k}={v}" for k, v in sorted(kwargs.items()))])
    world = dataclasses.replace(world, name=name, source=name, entry=entry)
    if max_episode_steps is not None:
        name = f"{name},max_episode_steps={max_episode_steps}"
        world = dataclasses.replace(world, horizon=max_episode_steps, name=name, source=name)
    return world


NO_BELIEF = (
    "the person's believed dynamics: a gym world has no exact log_prob; give it a learned one with "
    "--belief-env gym:ID,key=value (the env as the person imagines it)"
)


def refuse_without_dynamics(world, who: str) -> None:
    """One line for learners whose simulated person needs believed dynamics (PrefBias, EPS) on a gym world
    that has none (:func:`~mindgap.teachers.learned_belief.with_learned_belief` gives it one)."""
    if isinstance(world, GymWorld) and world.env.log_prob is None:
        raise EnvError(f"{who} needs {NO_BELIEF}")
