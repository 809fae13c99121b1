"""The interface every learner runs on: a world as pure JAX functions over an explicit params pytree.

An :class:`Env` is a bundle of functions, hashable so that learners take it as a static
argument of their jitted programs, with every number that may change (layout, dynamics,
rewards) in a params pytree passed alongside:

* ``reset(key, params) → state`` and ``step(key, state, action, params) → Step``: one episode's
  start and one transition; ``state`` is any pytree;
* ``observe(state, params) → obs [d]``: what the agent (and a person watching) sees;
* ``observation_space`` and ``action_space``: a :class:`Box` or a :class:`Discrete`; learners
  read every dimension from them;
* optionally ``reward(obs, act, next_obs, params) → r`` and ``log_prob(obs, act, next_obs, params)
  → log T(next_obs | obs, act)``: the task's reward and the exact transition density, over
  observations. A simulated person scores the segments it is shown with these two, under
  *its own* params — a belief is the same world with other params.

Continuous actions are in [−1, 1]^a (a tanh policy's range); a world scales them to its own
units inside ``step``. A discrete action reaches ``step`` (and ``reward``, ``log_prob``) as
a float vector ``[1]`` holding its index, as the learners store it; the learners' networks
see it one-hot (:func:`action_width` numbers). The learners reset an episode when ``step`` reports it terminated or
truncated, and count the episode's steps themselves.

A :class:`World` is an Env with its true params, its named beliefs and its horizon: what a
learner's ``train`` takes. :class:`~mindgap.envs.terrain.TerrainWorld` is one; a user's own Env
becomes one as ``World(name, env, params, beliefs, horizon=…)`` (``examples/point_mass.py``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp


class Step(NamedTuple):
    """What ``step`` returns: the next state, the reward, and whether the episode ended.

    ``terminated``: entered a terminal state (a goal, a pit; no bootstrapping past it);
    ``truncated``: stopped for another reason (the horizon).
    """

    state: Any
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array


@dataclasses.dataclass(frozen=True)
class Box:
    """A box of real vectors of ``shape`` within [``low``, ``high``] (scalars, the same on every axis)."""

    shape: tuple[int, ...]
    low: float = -1.0
    high: float = 1.0

    @property
    def dim(self) -> int:
        """The number of reals (the learners flatten to this)."""
        return math.prod(self.shape)


@dataclasses.dataclass(frozen=True)
class Discrete:
    """``n`` actions, numbered 0 … n−1."""

    n: int

    @property
    def dim(self) -> int:
        """The numbers a stored action takes: one, the index."""
        return 1


Space = Box | Discrete


def action_width(space: Space) -> int:
    """How many numbers a network that takes an action as input reads: a Box's dimension, or a
    Discrete space's number of actions (the action one-hot)."""
    return space.n if isinstance(space, Discrete) else space.dim


@dataclasses.dataclass(frozen=True)
class Env:
    """A world's functions and spaces (see the module docstring for each function's signature)."""

    reset: Callable
    step: Callable
    observe: Callable
    observation_space: Space
    action_space: Space
    reward: Callable | None = None
    log_prob: Callable | None = None


class EnvError(ValueError):
    """An environment that does not follow the interface, or that a learner cannot handle."""


def check_env(
    env: Env,
    *,
    continuous_actions: bool = True,
    density: bool = False,
    who: str = "this learner",
    discrete_actions: bool = False,
) -> None:
    """Refuse, with one line naming the problem, an env that ``who`` cannot run on.

    Args:
        continuous_actions: the learner needs a :class:`Box` action space in [−1, 1].
        discrete_actions: the learner also runs on a :class:`Discrete` space of at least two actions.
        density: the learner (or its simulated person) needs ``reward`` and ``log_prob``.
    """
    if not isinstance(env, Env):
        raise EnvError(f"expected a mindgap Env, got {type(env).__name__}")
    for name in ("reset", "step", "observe"):
        if not callable(getattr(env, name)):
            raise EnvError(f"the env's {name} is not a function")
    obs = env.observation_space
    if not isinstance(obs, Box) or len(obs.shape) != 1:
        raise EnvError(f"{who} needs a flat Box observation space, got {obs}")
    act = env.action_space
    if discrete_actions and isinstance(act, Discrete):
        if act.n < 2:
            raise EnvError(f"{who} needs at least two discrete actions, got {act.n}")
    elif continuous_actions:
        if not isinstance(act, Box) or len(act.shape) != 1:
            raise EnvError(f"{who} needs a continuous (Box) action space, got {act}")
        if (act.low, act.high) != (-1.0, 1.0):
            raise EnvError(f"{who} needs actions in [-1, 1] (scale them inside step), got [{act.low}, {act.high}]")
    if density and (env.reward is None or env.log_prob is None):
        raise EnvError(f"{who} needs the env's reward and exact log_prob for the simulated person; this env has none")


@dataclasses.dataclass(frozen=True, eq=False)
class World:
    """An :class:`Env` with its true params, named beliefs (params of the same env) and episode horizon.

    Attributes:
        name: how run records and progress bars name it.
        env: the functions.
        params: the true world.
        beliefs: belief name → params, each the world as a person sees it.
        horizon: the most steps an episode lasts (evaluation rolls out this many).
        source: where it was made (a file, ``module:factory``), for run records.
    """

    name: str
    env: Env
    params: Any
    beliefs: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    horizon: int = 200
    source: str | None = None

    def belief(self, name: str | None = None):
        """The params of belief ``name`` (default: the first)."""
        return pick_belief(self.name, self.beliefs, name)

    def fingerprint_tree(self):
        """What a run record hashes to recognise this world."""
        return (self.params, dict(self.beliefs))

    def trace(self, obs):
        """Points to draw a path through ``obs [..., T+1, d]``: the observations themselves."""
        return obs

    def obs_units(self) -> jax.Array:
        """[d] the world's units per unit of observation (entropies of next states are measured in
        the world's units): ones, the observation's own."""
        return jnp.ones(self.env.observation_space.dim, jnp.float32)


def pick_belief(world: str, beliefs: Mapping, name: str | None):
    """``beliefs[name]`` (the first when ``name`` is None), or one line saying what exists."""
    if not beliefs:
        raise ValueError(f"world {world!r} declares no belief")
    name = name or next(iter(beliefs))
    if name not in beliefs:
        raise ValueError(f"world {world!r} has no belief {name!r}; it has: {', '.join(beliefs)}")
    return beliefs[name]
