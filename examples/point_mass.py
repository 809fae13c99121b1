"""A user's own world, written against mindgap's environment interface: a point mass that drifts.

The agent pushes a point on the plane towards a goal disc; a steady current carries it to
the right at every step. The person watching believes there is no current, so a step that
the current bends looks unlikely to them. Every learner of mindgap runs on it unchanged::

    mindgap pebble --env examples/point_mass.py:make_world --fast --out runs/pm-pebble

Nothing here imports mindgap's own worlds: only the interface (``Env``, ``Box``, ``Step``,
``World``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from mindgap import Box, Env, Step, World

HORIZON = 40
SPEED = 0.15  # distance per step at a full push
GOAL_RADIUS = 0.2


class Params(NamedTuple):
    """What may differ between the world and a person's view of it."""

    drift: jax.Array  # [2] the current's displacement per step
    noise: jax.Array  # standard deviation of each step's Gaussian noise
    goal: jax.Array  # [2] centre of the goal disc


class State(NamedTuple):
    pos: jax.Array  # [2]
    t: jax.Array


def reset(key, params: Params) -> State:
    """Start somewhere in the left third of the square, at rest."""
    pos = jax.random.uniform(key, (2,), minval=jnp.array([-0.9, -0.6]), maxval=jnp.array([-0.5, 0.6]))
    return State(pos, jnp.zeros((), jnp.int32))


def _mean(pos, action, params: Params):
    return pos + SPEED * jnp.clip(action, -1.0, 1.0) + params.drift


def _reward(next_pos, params: Params):
    """Minus the distance to the goal, and +1 inside it."""
    dist = jnp.linalg.norm(next_pos - params.goal)
    return -dist + jnp.where(dist < GOAL_RADIUS, 1.0, 0.0)


def step(key, state: State, action, params: Params) -> Step:
    pos = _mean(state.pos, action, params) + params.noise * jax.random.normal(key, (2,))
    t = state.t + 1
    terminated = jnp.linalg.norm(pos - params.goal) < GOAL_RADIUS
    return Step(State(pos, t), _reward(pos, params), terminated, ~terminated & (t >= HORIZON))


def observe(state: State, params: Params):
    return state.pos


def reward(obs, action, next_obs, params: Params):
    return _reward(next_obs, params)


def log_prob(obs, action, next_obs, params: Params):
    """The exact Gaussian density of the next position."""
    z = (next_obs - _mean(obs, action, params)) / params.noise
    return jnp.sum(-0.5 * z**2 - jnp.log(params.noise) - 0.5 * jnp.log(2 * jnp.pi))


ENV = Env(reset, step, observe, Box((2,), -3.0, 3.0), Box((2,)), reward=reward, log_prob=log_prob)


def make_world(drift: float = 0.05) -> World:
    """The drifting world; its one belief, ``still``, is the same world without the current."""
    f = jnp.float32
    truth = Params(jnp.array([drift, 0.0], f), jnp.asarray(0.03, f), jnp.array([0.7, 0.0], f))
    still = truth._replace(drift=jnp.zeros(2, f))
    return World("point-mass", ENV, truth, {"still": still}, horizon=HORIZON, source=__file__)
