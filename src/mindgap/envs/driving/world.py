"""The driving scenario's functional API (§4.4.2, Figs. 33–36): ``reset``, ``step``, ``observe``, ``log_prob``, ``reward``.

A straight highway (3 lanes by default); the ego car and a front car start in the same lane at
the same speed; the front car brakes hard at a random decision step and slows to a crawl; other
traffic, cruising in the other lanes, is off by default (the study showed two cars). The ego
acts with highway-env's five meta-actions (:data:`~mindgap.envs.driving.params.ACTIONS`) through
highway-env's controllers and bicycle model (:mod:`~mindgap.envs.driving.kinematics`); on sleet
its braking is weaker and noisy (:mod:`~mindgap.envs.driving.sleet`). Written by hand in JAX:
no library offers a jittable highway scenario, let alone one with an exact transition density.

Pure functions of (key, state, action, params), jittable and vmappable over any argument::

    states = jax.vmap(reset, (0, None))(keys, params)
    out = jax.vmap(step, (0, 0, 0, None))(keys, states, actions, params)

**A step** (one decision, 1 s): the meta-action moves the set-points; the braking factor μ is
drawn (used only if the step brakes); the front car starts braking with the hazard of a
uniform onset over ``brake_first … brake_last`` — probability 1/(last − t + 1) at decision
t ∈ [first, last] if it has not yet, so the onset is uniform and the chain is Markov in the
observation; then 15 Euler steps of 1/15 s move every car, and a collision (highway-env's
swept rectangle test) ends the episode.

**The horizon is terminal.** An episode is the study's clip of ``horizon`` decisions, and the
observation carries the decisions taken (``t / horizon``), so the last decision ends the task
as a collision does: ``step`` reports both as ``terminated`` and never ``truncated``. A time
limit is a truncation to bootstrap past only when the agent cannot see the time (Pardo et al.
2018, "Time Limits in Reinforcement Learning"); here the state after the last decision
(``t / horizon = 1``) never starts a stored transition, so a critic bootstrapping from it
reads an extrapolation that nothing anchors, and the learners' critics diverged
(docs/experiments/driving.md, Status).

**The stochastic part and its exact density** (:func:`log_prob`): the onset (a Bernoulli of
the hazard above) and, on a braking step, the next speed (sleet.py's Beta density through the
speed map); the rest of the next state is a deterministic function of these, the state and the
action, and is not scored.

**Observation** [8 + 3 M] (M = 1 + traffic cars, the front car first), each scaled to order 1:
the ego's lateral position in lane widths (lane i's centre is i), heading [rad], speed / 30,
target lane, target speed / 30, decision steps / horizon, crashed (0/1), the front car braking
(0/1); then per other car: distance ahead of the ego (centre to centre) / 100 m, lateral
position in lane widths, speed / 30.

Differences from highway-env's version (:mod:`~mindgap.envs.driving.highway`), both by design:
a collision ends the episode at the end of its decision step with the cars moving on as they
were (highway-env brakes crashed cars with ``a = −v`` and pushes them apart, which would make
the speed of that step depend on when the crash happened); and the collision is counted at the
sub-step where highway-env's swept test fires, where highway-env marks the car crashed at its
next sub-step (a decision later when the test fires on a decision's last sub-step).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from ..interface import Box, Discrete, Env, Step, World
from .kinematics import (
    apply_meta_action,
    bicycle_step,
    clip_acceleration,
    speed_control,
    speed_to_index,
    steering_control,
    will_collide,
)
from .params import ACTIONS, DT, LANE_WIDTH, SUBSTEPS, DrivingParams, DrivingState, make_params
from .reward import combine, features
from .sleet import brakes, log_prob_speed, sample_factor

SPEED_SCALE = 30.0
"""Observed speeds are divided by this [m/s]."""
DIST_SCALE = 100.0
"""Observed distances along the road are divided by this [m]."""
EGO_OBS = 8
"""Observation entries of the ego and the episode, before the other cars' three each."""


def reset(key: jax.Array, params: DrivingParams) -> DrivingState:
    """Both cars in the start lane at the road speed, the front car ``gap`` m ahead; traffic where
    ``params`` puts it, each moved by up to ± ``traffic_jitter`` m."""
    f32 = jnp.float32
    lane_y = LANE_WIDTH * params.start_lane.astype(f32)
    jitter = jax.random.uniform(key, params.traffic_dx.shape, minval=-1.0, maxval=1.0) * params.traffic_jitter
    target_speed = params.target_speeds[speed_to_index(params.speed, params.target_speeds)]
    return DrivingState(
        x=jnp.zeros((), f32),
        y=lane_y,
        heading=jnp.zeros((), f32),
        speed=params.speed,
        target_lane=params.start_lane,
        target_speed=target_speed,
        others_x=jnp.concatenate([(params.gap + 5.0)[None], params.traffic_dx + jitter]),
        others_y=jnp.concatenate([lane_y[None], LANE_WIDTH * params.traffic_lane.astype(f32)]),
        others_speed=jnp.concatenate([params.speed[None], params.traffic_speed]),
        braking=jnp.zeros((), bool),
        t=jnp.zeros((), jnp.int32),
        crashed=jnp.zeros((), bool),
        done=jnp.zeros((), bool),
    )


def onset_hazard(t: jax.Array, params: DrivingParams) -> jax.Array:
    """P(the front car starts braking at decision ``t`` | it has not yet): the hazard of a uniform onset."""
    left = (params.brake_last - t + 1).astype(jnp.float32)
    return jnp.where(t < params.brake_first, 0.0, jnp.where(t >= params.brake_last, 1.0, 1.0 / left))


def advance(state: DrivingState, action, mu, onset, params: DrivingParams) -> DrivingState:
    """The deterministic rest of a live step, given its draws: braking factor ``mu`` and whether the
    front car starts braking now (``onset``). ``step`` samples both and calls this."""
    a = jnp.asarray(action).astype(jnp.int32).reshape(())
    target_lane, target_speed = apply_meta_action(
        a, state.y, state.speed, state.target_lane, state.target_speed, params.lanes, params.target_speeds
    )
    gain = jnp.where(brakes(state.speed, target_speed), mu, 1.0)
    braking = state.braking | onset
    is_front = jnp.arange(state.others_x.shape[0]) == 0

    def substep(_, c):
        x, y, heading, speed, ox, ov, crashed = c
        steer = steering_control(y, heading, speed, target_lane)
        acc = clip_acceleration(gain * speed_control(speed, target_speed), speed)
        # the front car brakes at front_decel, landing on front_final_speed exactly
        front_acc = -jnp.minimum(params.front_decel, jnp.maximum(ov - params.front_final_speed, 0.0) / DT)
        o_acc = jnp.where(is_front & braking, front_acc, 0.0)
        x, y, heading, speed = bicycle_step(x, y, heading, speed, steer, acc)
        ox, ov = ox + ov * DT, ov + o_acc * DT
        hit = jnp.any(will_collide(x, y, heading, speed, ox, state.others_y, ov))
        return x, y, heading, speed, ox, ov, crashed | hit

    init = (state.x, state.y, state.heading, state.speed, state.others_x, state.others_speed, state.crashed)
    x, y, heading, speed, ox, ov, crashed = jax.lax.fori_loop(0, SUBSTEPS, substep, init, unroll=False)
    t = state.t + 1
    done = crashed | (t >= params.horizon)
    return DrivingState(
        x, y, heading, speed, target_lane, target_speed, ox, state.others_y, ov, braking, t, crashed, done
    )


def step(key: jax.Array, state: DrivingState, action, params: DrivingParams) -> Step:
    """One decision step: sample the braking factor and the front car's onset, advance, score.

    ``terminated`` on a collision and at the horizon (module docstring: the horizon is
    terminal), never ``truncated``; a finished state stays as it is (reward 0, neither flag).
    """
    k_mu, k_onset = jax.random.split(key)
    mu = sample_factor(k_mu, params.sleet, params.grip)
    onset = jax.random.uniform(k_onset) < onset_hazard(state.t, params)
    nxt = advance(state, action, mu, onset, params)
    r = reward(observe(state, params), action, observe(nxt, params), params)
    live = ~state.done
    nxt = jax.tree.map(lambda new, old: jnp.where(live, new, old), nxt, state)
    return Step(nxt, jnp.where(live, r, 0.0), live & nxt.done, jnp.zeros_like(live))


def observe(state: DrivingState, params: DrivingParams) -> jax.Array:
    """[8 + 3 M] the observation (module docstring)."""
    f32 = jnp.float32
    ego = jnp.stack(
        [
            state.y / LANE_WIDTH,
            state.heading,
            state.speed / SPEED_SCALE,
            state.target_lane.astype(f32),
            state.target_speed / SPEED_SCALE,
            state.t.astype(f32) / params.horizon.astype(f32),
            state.crashed.astype(f32),
            state.braking.astype(f32),
        ]
    )
    others = jnp.stack(
        [(state.others_x - state.x) / DIST_SCALE, state.others_y / LANE_WIDTH, state.others_speed / SPEED_SCALE], -1
    )
    return jnp.concatenate([ego, others.reshape(-1)]).astype(f32)


def decode(obs: jax.Array, params: DrivingParams) -> dict:
    """The quantities :func:`observe` scaled, back in metres, seconds and steps."""
    others = obs[EGO_OBS:].reshape(-1, 3)
    return {
        "y": obs[0] * LANE_WIDTH,
        "heading": obs[1],
        "speed": obs[2] * SPEED_SCALE,
        "target_lane": jnp.round(obs[3]).astype(jnp.int32),
        "target_speed": obs[4] * SPEED_SCALE,
        "t": jnp.round(obs[5] * params.horizon).astype(jnp.int32),
        "crashed": obs[6] > 0.5,
        "braking": obs[7] > 0.5,
        "others_dx": others[:, 0] * DIST_SCALE,
        "others_y": others[:, 1] * LANE_WIDTH,
        "others_speed": others[:, 2] * SPEED_SCALE,
    }


def state_from_obs(obs: jax.Array, params: DrivingParams) -> DrivingState:
    """The state an observation shows, with the ego at ``x = 0`` (only distances to it are observed).

    :func:`observe` of the result equals ``obs`` to float32 rounding: every part of the state that
    moves the scenario is in the observation (a person can roll a clip forward from its first frame,
    :mod:`~mindgap.teachers.believed_rollout`).
    """
    n = decode(obs, params)
    f32 = jnp.float32
    t = n["t"]
    return DrivingState(
        x=jnp.zeros((), f32),
        y=n["y"].astype(f32),
        heading=n["heading"].astype(f32),
        speed=n["speed"].astype(f32),
        target_lane=n["target_lane"],
        target_speed=n["target_speed"].astype(f32),
        others_x=n["others_dx"].astype(f32),
        others_y=n["others_y"].astype(f32),
        others_speed=n["others_speed"].astype(f32),
        braking=n["braking"],
        t=t,
        crashed=n["crashed"],
        done=n["crashed"] | (t >= params.horizon),
    )


def reward(obs: jax.Array, action, next_obs: jax.Array, params: DrivingParams) -> jax.Array:
    """r_A of a step given as observations (:mod:`~mindgap.envs.driving.reward`); it depends on ``next_obs`` only."""
    del obs, action
    n = decode(next_obs, params)
    phi = features(n["y"], n["heading"], n["speed"], n["others_dx"], n["others_y"], n["others_speed"], params.rewards)
    return combine(phi, n["crashed"], params.rewards)


def log_prob(obs: jax.Array, action, next_obs: jax.Array, params: DrivingParams) -> jax.Array:
    """Exact log density of a step's stochastic part (module docstring) under ``params``.

    log P(front car's braking flag') + [step brakes] · log p(v' | v, v_T); 0 from a finished
    state (nothing moves), −inf where the flag turns off or a braking step speeds up.
    """
    s, n = decode(obs, params), decode(next_obs, params)
    a = jnp.asarray(action).astype(jnp.int32).reshape(())
    _, target_speed = apply_meta_action(
        a, s["y"], s["speed"], s["target_lane"], s["target_speed"], params.lanes, params.target_speeds
    )
    h = onset_hazard(s["t"], params)
    lp_onset = jnp.where(
        s["braking"], jnp.where(n["braking"], 0.0, -jnp.inf), jnp.where(n["braking"], jnp.log(h), jnp.log1p(-h))
    )
    lp_speed = jnp.where(
        brakes(s["speed"], target_speed),
        log_prob_speed(s["speed"], target_speed, n["speed"], params.sleet, params.grip),
        0.0,
    )
    finished = s["crashed"] | (s["t"] >= params.horizon)
    return jnp.where(finished, 0.0, lp_onset + lp_speed)


def driving_env(n_traffic: int = 0) -> Env:
    """The scenario as an :class:`~mindgap.envs.interface.Env` with ``n_traffic`` other cars (the
    observation's length depends on it; the functions do not)."""
    dim = EGO_OBS + 3 * (1 + n_traffic)
    return Env(reset, step, observe, Box((dim,), -10.0, 10.0), Discrete(len(ACTIONS)), reward=reward, log_prob=log_prob)


DRIVING_ENV = driving_env(0)
"""The scenario without other traffic (the study's)."""


@dataclasses.dataclass(frozen=True, eq=False)
class DrivingWorld(World):
    """A driving :class:`~mindgap.envs.interface.World`: paths are drawn relative to the front car."""

    def trace(self, obs):
        """[..., T+1, 2] the ego's position relative to the front car: metres behind it (negative) and
        lateral position in lane widths."""
        return jnp.stack([-obs[..., EGO_OBS] * DIST_SCALE, obs[..., 0]], -1)

    def obs_units(self) -> jax.Array:
        """[d] metres, radians, m/s and steps per unit of observation."""
        d = self.env.observation_space.dim
        ego = jnp.array([LANE_WIDTH, 1.0, SPEED_SCALE, 1.0, SPEED_SCALE, float(self.horizon), 1.0, 1.0])
        per_car = jnp.array([DIST_SCALE, LANE_WIDTH, SPEED_SCALE])
        return jnp.concatenate([ego, jnp.tile(per_car, (d - EGO_OBS) // 3)]).astype(jnp.float32)


def make_world(
    sleet: float = 1.0, traffic: int = 0, brake_first: int = 1, brake_last: int = 4, **kwargs
) -> DrivingWorld:
    """The driving world at sleet level ``sleet`` with ``traffic`` other cars, the front car braking at a
    decision step drawn from ``brake_first … brake_last`` (``--env
    mindgap.envs.driving:make_world,sleet=0.5,brake_first=2``); other ``kwargs`` go to
    :func:`~mindgap.envs.driving.params.make_params`.

    Its belief ``dry`` is the same world on a dry road: the availability bias of §4.4.2, a person
    who expects braking on sleet to work as it always has.
    """
    params = make_params(sleet=sleet, traffic=traffic, brake_window=(brake_first, brake_last), **kwargs)
    args = {"sleet": sleet, "traffic": traffic, "brake_first": brake_first, "brake_last": brake_last, **kwargs}
    defaults = {"sleet": 1.0, "traffic": 0, "brake_first": 1, "brake_last": 4}
    name = ",".join(["driving", *(f"{k}={v}" for k, v in sorted(args.items()) if defaults.get(k, object()) != v)])
    return DrivingWorld(
        name,
        driving_env(traffic),
        params,
        {"dry": params.with_sleet(0.0)},
        horizon=int(params.horizon),
        source="mindgap.envs.driving:make_world",
    )
