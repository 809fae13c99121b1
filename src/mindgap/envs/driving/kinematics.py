"""highway-env's vehicle model in JAX: meta-actions, the speed and steering controllers, the bicycle model.

Transcribed from highway-env (``MDPVehicle.act``, ``ControlledVehicle.act``/``steering_control``/
``speed_control``, ``Vehicle.step``/``clip_actions``, ``AbstractLane.is_reachable_from``) for a
straight road whose lanes run along x (lane i's centre at y = 4 i, heading 0), so each function
is a few lines of ``jnp`` on scalars that jit and vmap. highway-env itself steps Python objects
one at a time (a few steps per second for ``highway-v0``); nothing else offers its dynamics as
pure functions. ``tests/envs/test_driving_highway.py`` drives both with the same actions.

One decision step (``POLICY_FREQUENCY`` = 1 Hz) applies a meta-action to the set-points
(:func:`apply_meta_action`), then integrates ``SUBSTEPS`` = 15 Euler steps of ``DT`` = 1/15 s,
each recomputing the controls from the current state (:func:`controls`, :func:`bicycle_step`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .params import (
    DT,
    FASTER,
    KP_A,
    KP_HEADING,
    KP_LATERAL,
    LANE_LEFT,
    LANE_RIGHT,
    LANE_WIDTH,
    LENGTH,
    MAX_SPEED,
    MAX_STEERING_ANGLE,
    MIN_SPEED,
    NOT_ZERO,
    SLOWER,
    WIDTH,
)


def not_zero(x: jax.Array) -> jax.Array:
    """highway-env's ``utils.not_zero``: ``x`` pushed away from 0 to at least ±0.01."""
    return jnp.where(jnp.abs(x) > NOT_ZERO, x, jnp.where(x >= 0, NOT_ZERO, -NOT_ZERO))


def wrap_to_pi(x: jax.Array) -> jax.Array:
    return jnp.mod(x + jnp.pi, 2 * jnp.pi) - jnp.pi


def speed_to_index(speed: jax.Array, target_speeds: jax.Array) -> jax.Array:
    """``MDPVehicle.speed_to_index``: the index of the nearest of the evenly spaced target speeds (int32)."""
    n = target_speeds.shape[-1]
    frac = (speed - target_speeds[0]) / (target_speeds[-1] - target_speeds[0])
    return jnp.clip(jnp.round(frac * (n - 1)), 0, n - 1).astype(jnp.int32)


def apply_meta_action(action, y, speed, target_lane, target_speed, lanes, target_speeds):
    """``MDPVehicle.act`` of a meta-action: the new ``(target_lane, target_speed)``.

    FASTER/SLOWER step one target speed up/down from the one nearest the *current* speed
    (highway-env's rule, so repeated SLOWER keeps braking), clipped to the list; LANE_LEFT/RIGHT
    move the target lane by one, clipped to the road, when that lane's centre is within two
    lane widths of the car (``is_reachable_from``); IDLE keeps both.
    """
    n = target_speeds.shape[-1]
    here = speed_to_index(speed, target_speeds)
    idx = jnp.clip(here + jnp.where(action == FASTER, 1, -1), 0, n - 1)
    target_speed = jnp.where((action == FASTER) | (action == SLOWER), target_speeds[idx], target_speed)
    step = jnp.where(action == LANE_LEFT, -1, jnp.where(action == LANE_RIGHT, 1, 0))
    lane = jnp.clip(target_lane + step, 0, lanes - 1)
    reachable = jnp.abs(y - LANE_WIDTH * lane) <= 2 * LANE_WIDTH
    return jnp.where(reachable, lane, target_lane).astype(jnp.int32), target_speed


def steering_control(y, heading, speed, target_lane) -> jax.Array:
    """``ControlledVehicle.steering_control`` on a straight lane: the steering angle [rad] that
    brings the car onto the target lane's centre line (lateral P → heading reference → heading P
    → slip angle → steering)."""
    lateral = y - LANE_WIDTH * target_lane
    lateral_speed_command = -KP_LATERAL * lateral
    heading_command = jnp.arcsin(jnp.clip(lateral_speed_command / not_zero(speed), -1, 1))
    heading_ref = jnp.clip(heading_command, -jnp.pi / 4, jnp.pi / 4)  # the lane's own heading is 0
    heading_rate_command = KP_HEADING * wrap_to_pi(heading_ref - heading)
    slip_angle = jnp.arcsin(jnp.clip(LENGTH / 2 / not_zero(speed) * heading_rate_command, -1, 1))
    # arctan(2 tan δ) written so that a saturated slip angle keeps its sign: float32's π/2 is past the pole of tan
    steering = jnp.arctan2(2 * jnp.sin(slip_angle), jnp.cos(slip_angle))
    return jnp.clip(steering, -MAX_STEERING_ANGLE, MAX_STEERING_ANGLE)


def speed_control(speed, target_speed) -> jax.Array:
    """``ControlledVehicle.speed_control``: acceleration ``(target − speed) / τ`` [m/s²]."""
    return KP_A * (target_speed - speed)


def clip_acceleration(acceleration, speed) -> jax.Array:
    """``Vehicle.clip_actions``'s speed limits (a crashed car's override is not applied: see world.py)."""
    acceleration = jnp.where(speed > MAX_SPEED, jnp.minimum(acceleration, MAX_SPEED - speed), acceleration)
    return jnp.where(speed < MIN_SPEED, jnp.maximum(acceleration, MIN_SPEED - speed), acceleration)


def bicycle_step(x, y, heading, speed, steering, acceleration, dt=DT):
    """``Vehicle.step``: one Euler step of the kinematic bicycle model (position and heading move
    with the speed before the step, as in highway-env)."""
    beta = jnp.arctan(0.5 * jnp.tan(steering))
    x = x + speed * jnp.cos(heading + beta) * dt
    y = y + speed * jnp.sin(heading + beta) * dt
    heading = heading + speed * jnp.sin(beta) / (LENGTH / 2) * dt
    return x, y, heading, speed + acceleration * dt


def will_collide(x, y, heading, speed, ox, oy, ospeed, dt=DT) -> jax.Array:
    """highway-env's collision test of the ego against cars driving straight (heading 0).

    ``utils.are_polygons_intersecting`` on two 5 m × 2 m rectangles, separating axes with the
    ego's interval swept by the relative displacement over ``dt``: true when the cars overlap
    or will within ``dt`` at their current velocities ("will intersect", which highway-env
    turns into a crash). ``ox, oy, ospeed`` may be arrays: one answer per car.
    """
    c, s = jnp.cos(heading), jnp.sin(heading)
    dx, dy = ox - x, oy - y  # other minus ego
    rel = ((speed * c - ospeed) * dt, speed * s * dt)  # displacement of the ego relative to the other
    half_l, half_w = LENGTH / 2, WIDTH / 2
    overlap = True
    for nx, ny in ((c, s), (-s, c), (1.0, 0.0), (0.0, 1.0)):
        # half extents of both rectangles along the axis, and the centres' separation
        r_ego = half_l * jnp.abs(c * nx + s * ny) + half_w * jnp.abs(-s * nx + c * ny)
        r_other = half_l * jnp.abs(nx) + half_w * jnp.abs(ny)
        centre = dx * nx + dy * ny
        lo_a, hi_a = -r_ego, r_ego
        proj = rel[0] * nx + rel[1] * ny
        lo_a, hi_a = lo_a + jnp.minimum(proj, 0.0), hi_a + jnp.maximum(proj, 0.0)
        lo_b, hi_b = centre - r_other, centre + r_other
        gap = jnp.where(lo_a < lo_b, lo_b - hi_a, lo_a - hi_b)
        overlap = overlap & (gap <= 0.0)
    return overlap
