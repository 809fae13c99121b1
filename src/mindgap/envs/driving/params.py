"""The numbers of the driving scenario (§4.4.2): highway-env's constants, the params pytree, the state.

highway-env's constants are transcribed from its sources (``highway_env/vehicle/kinematics.py``
``Vehicle``, ``highway_env/vehicle/controller.py`` ``ControlledVehicle``/``MDPVehicle``,
``highway_env/road/lane.py`` ``AbstractLane``, ``highway_env/envs/common/abstract.py``'s
default frequencies); ``tests/envs/test_driving_highway.py`` checks them against the installed
package. Everything a jitted function may vary — the sleet, the road, the front car's braking,
the reward — is an array leaf of :class:`DrivingParams`, so a person's belief is the same world
with other params (:meth:`DrivingParams.with_sleet`) and beliefs stack along a leading axis.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

# highway-env's vehicle and road (Vehicle, ControlledVehicle, AbstractLane)
LENGTH = 5.0
"""Vehicle length [m]."""
WIDTH = 2.0
"""Vehicle width [m]."""
LANE_WIDTH = 4.0
"""Lane width [m]; lane i's centre line is at y = 4 i, lane 0 the leftmost (LANE_LEFT lowers the index)."""
MAX_SPEED, MIN_SPEED = 40.0, -40.0
"""The bicycle model's speed limits [m/s] (``Vehicle.clip_actions``)."""
TAU_ACC, TAU_HEADING, TAU_LATERAL = 0.6, 0.2, 0.6
"""Time constants [s] of the speed, heading and lateral-position controllers."""
KP_A, KP_HEADING, KP_LATERAL = 1 / TAU_ACC, 1 / TAU_HEADING, 1 / TAU_LATERAL
MAX_STEERING_ANGLE = float(np.pi / 3)
NOT_ZERO = 1e-2
"""``utils.not_zero``'s floor on a speed divided by."""

# highway-env's AbstractEnv defaults: one decision a second, 15 integration steps per decision
POLICY_FREQUENCY = 1
SIMULATION_FREQUENCY = 15
SUBSTEPS = SIMULATION_FREQUENCY // POLICY_FREQUENCY
DT = 1.0 / SIMULATION_FREQUENCY

TARGET_SPEEDS = tuple(float(v) for v in np.linspace(0.0, 30.0, 7))
"""The speeds FASTER/SLOWER step between [m/s]: highway-env's default is (20, 25, 30); the
scenario extends it down to a stop in the same 5 m/s steps, so braking can go below the road speed."""

ACTIONS = ("LANE_LEFT", "IDLE", "LANE_RIGHT", "FASTER", "SLOWER")
"""The five meta-actions, numbered as highway-env's ``DiscreteMetaAction.ACTIONS_ALL``."""
LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = range(5)

FEATURES = ("speed", "front_distance", "relative_speed", "lane_following")
"""r_A's features, in the order of Fig. 32's importance ratings (:mod:`~mindgap.envs.driving.reward`)."""
STUDY_IMPORTANCE = (3.42, 4.57, 3.28, 3.78)
"""The participants' average importance ratings (1–5) of the features (§4.4.2, Fig. 32)."""


class Grip(NamedTuple):
    """How well braking works, between a dry road (sleet 0) and full sleet (sleet 1).

    The braking factor μ of a decision step is Beta-distributed with mean and concentration
    interpolated in the sleet level s (see :mod:`~mindgap.envs.driving.sleet`)::

        m(s) = dry_mean + (sleet_mean − dry_mean) · s
        κ(s) = dry_concentration^(1−s) · sleet_concentration^s

    Defaults: dry 0.95 ± 0.022 (a little tyre slip, never more than a few percent), full
    sleet 0.40 ± 0.185 (braking at less than half its effect, and unpredictably).
    """

    dry_mean: jax.Array = np.float32(0.95)
    sleet_mean: jax.Array = np.float32(0.40)
    dry_concentration: jax.Array = np.float32(100.0)
    sleet_concentration: jax.Array = np.float32(6.0)


class RewardParams(NamedTuple):
    """r_A: a linear combination of four features in [0, 1] and a collision penalty (reward.py).

    Attributes:
        weights: [4] the features' weights, in :data:`FEATURES` order (sum 1 when made by
            :func:`~mindgap.envs.driving.reward.importance_weights`).
        collision: the penalty of the step that ends in a collision (the episode ends there).
        top_speed: forward speed [m/s] at which the speed feature is 1 (it is 0 at a stop).
        headway: time headway [s] of the desired gap ``standstill + headway · v`` (IDM's, as
            highway-env's ``IDMVehicle``: 1.5 s); the front-distance feature is the gap over it.
        standstill: the desired gap at a stop [m] (IDM's 5 m beyond the car length).
        speed_scale: a speed difference [m/s] at which the relative-speed feature is 0.
        neighbourhood: cars within this many metres ahead or behind, in the ego's lane or the
            next ones, are its neighbours.
    """

    weights: jax.Array
    collision: jax.Array = np.float32(5.0)
    top_speed: jax.Array = np.float32(30.0)
    headway: jax.Array = np.float32(1.5)
    standstill: jax.Array = np.float32(5.0)
    speed_scale: jax.Array = np.float32(10.0)
    neighbourhood: jax.Array = np.float32(50.0)


class DrivingParams(NamedTuple):
    """Everything the functional API needs about one scenario (a belief is another instance).

    Attributes:
        sleet: 0 a dry road … 1 full sleet: scales and randomises braking (:class:`Grip`).
        grip: the braking factor's distribution at either end.
        lanes: number of lanes (int32).
        start_lane: the lane both cars start in (int32; 0 the leftmost).
        speed: the speed both cars start at [m/s] (the road speed).
        gap: bumper-to-bumper distance from the ego to the front car at the start [m].
        front_decel: the front car's deceleration once it brakes [m/s²].
        front_final_speed: the speed it brakes down to and then keeps [m/s].
        brake_first, brake_last: it starts braking at a decision step drawn uniformly from
            ``brake_first … brake_last`` (int32; equal for a fixed moment).
        target_speeds: [K] the speeds FASTER/SLOWER step between, evenly spaced.
        traffic_lane, traffic_dx, traffic_speed: [N] other cars (none by default): lane,
            distance ahead of the ego at the start [m] and constant speed [m/s].
        traffic_jitter: each other car's start distance is moved by up to ± this [m].
        horizon: decision steps in an episode (int32).
        rewards: r_A.
    """

    sleet: jax.Array
    grip: Grip
    lanes: jax.Array
    start_lane: jax.Array
    speed: jax.Array
    gap: jax.Array
    front_decel: jax.Array
    front_final_speed: jax.Array
    brake_first: jax.Array
    brake_last: jax.Array
    target_speeds: jax.Array
    traffic_lane: jax.Array
    traffic_dx: jax.Array
    traffic_speed: jax.Array
    traffic_jitter: jax.Array
    horizon: jax.Array
    rewards: RewardParams

    @property
    def n_traffic(self) -> int:
        return int(self.traffic_lane.shape[-1])

    def with_sleet(self, sleet: float) -> DrivingParams:
        """The same scenario at another sleet level (e.g. 0: a person who believes braking works as on a dry road)."""
        return self._replace(sleet=jnp.asarray(check_sleet(sleet), jnp.float32))


class DrivingState(NamedTuple):
    """One moment of the scenario.

    The ego car's kinematic state (``x``, ``y`` [m], ``heading`` [rad], ``speed`` [m/s]) and its
    controller's set-points (``target_lane``, ``target_speed``: highway-env's ``MDPVehicle``);
    the other cars (``others_*`` [M], the front car first, then the traffic), which drive
    straight along their lanes; ``braking``: the front car has started to brake; ``t``: decision
    steps taken; ``crashed``: the ego collided (the episode ends); ``done``: the episode ended
    (later steps change nothing).
    """

    x: jax.Array
    y: jax.Array
    heading: jax.Array
    speed: jax.Array
    target_lane: jax.Array
    target_speed: jax.Array
    others_x: jax.Array
    others_y: jax.Array
    others_speed: jax.Array
    braking: jax.Array
    t: jax.Array
    crashed: jax.Array
    done: jax.Array


def check_sleet(sleet) -> float:
    """``sleet`` as a float, or a one-line ValueError when it is outside [0, 1]."""
    s = float(sleet)
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"sleet must be in [0, 1] (0 a dry road, 1 full sleet), got {sleet}")
    return s


def make_params(
    *,
    sleet: float = 1.0,
    grip: Grip = Grip(),
    lanes: int = 3,
    start_lane: int = 1,
    speed: float = 25.0,
    gap: float | None = None,
    front_decel: float = 5.0,
    front_final_speed: float = 5.0,
    brake_window: tuple[int, int] = (1, 4),
    target_speeds: tuple[float, ...] = TARGET_SPEEDS,
    traffic: int = 0,
    traffic_jitter: float = 5.0,
    horizon: int = 15,
    weights=None,
    collision: float = 5.0,
) -> DrivingParams:
    """Assemble and check a scenario's params (host side, once); every problem is a one-line ValueError.

    Args:
        sleet: in [0, 1].
        traffic: how many other cars (0 to ``2 · (lanes − 1)``): they cruise in the lanes
            other than the start lane, alternately 40 m behind and 30 m ahead of the ego and
            further out, at the road speed ± 2 m/s.
        gap: the start gap [m]; by default the desired gap at the road speed (r_A's
            ``standstill + headway · speed``: 42.5 m at 25 m/s): steady following, where the
            front-distance feature is 1 and nothing calls for a response until the front car
            brakes. A shorter gap starts the car tailgating by the reward's own measure.
        brake_window: (first, last) decision step at which the front car may start to brake.
        weights: r_A's [4] feature weights (default: from the study's importance ratings,
            :func:`~mindgap.envs.driving.reward.importance_weights`).
    """
    from .reward import importance_weights

    sleet = check_sleet(sleet)
    if lanes < 2:
        raise ValueError(f"lanes must be at least 2 (a car must be able to change lane), got {lanes}")
    if not 0 <= start_lane < lanes:
        raise ValueError(f"start_lane must be in 0 … {lanes - 1}, got {start_lane}")
    first, last = (int(k) for k in brake_window)
    if not 0 <= first <= last < horizon:
        raise ValueError(f"brake_window must satisfy 0 <= first <= last < horizon ({horizon}), got {brake_window}")
    ts = np.asarray(target_speeds, np.float64)
    if ts.ndim != 1 or ts.size < 2 or not np.allclose(np.diff(ts), ts[1] - ts[0]) or ts[1] <= ts[0]:
        raise ValueError("target_speeds must be at least two increasing, evenly spaced speeds")
    if not ts[0] <= speed <= ts[-1]:
        raise ValueError(f"speed must lie within the target speeds [{ts[0]}, {ts[-1]}], got {speed}")
    if gap is None:
        d = RewardParams._field_defaults
        gap = float(d["standstill"] + d["headway"] * speed)
    if not 0.0 <= front_final_speed < speed or front_decel <= 0 or gap <= 0:
        raise ValueError("the front car must brake (front_decel > 0) to a speed below the road speed, from a gap > 0")
    for name in ("dry_mean", "sleet_mean"):
        if not 0.0 < float(getattr(grip, name)) < 1.0:
            raise ValueError(f"grip.{name} must be in (0, 1), got {getattr(grip, name)}")
    for name in ("dry_concentration", "sleet_concentration"):
        if not float(getattr(grip, name)) > 0.0:
            raise ValueError(f"grip.{name} must be positive, got {getattr(grip, name)}")
    others = [lane for lane in range(lanes) if lane != start_lane]
    if not 0 <= traffic <= 2 * len(others):
        raise ValueError(f"traffic must be in 0 … {2 * len(others)} on {lanes} lanes, got {traffic}")
    lane_of = [others[i % len(others)] for i in range(traffic)]
    dx = [(-40.0 if (i // len(others)) % 2 == 0 else 30.0) - 25.0 * (i // (2 * len(others))) for i in range(traffic)]
    v = [speed + (2.0 if i % 2 else -2.0) for i in range(traffic)]
    w = importance_weights(STUDY_IMPORTANCE) if weights is None else np.asarray(weights, np.float32)
    if np.shape(w) != (len(FEATURES),):
        raise ValueError(f"weights must hold {len(FEATURES)} numbers ({', '.join(FEATURES)}), got shape {np.shape(w)}")
    f32, i32 = jnp.float32, jnp.int32
    return DrivingParams(
        sleet=jnp.asarray(sleet, f32),
        grip=Grip(*(jnp.asarray(float(g), f32) for g in grip)),
        lanes=jnp.asarray(lanes, i32),
        start_lane=jnp.asarray(start_lane, i32),
        speed=jnp.asarray(speed, f32),
        gap=jnp.asarray(gap, f32),
        front_decel=jnp.asarray(front_decel, f32),
        front_final_speed=jnp.asarray(front_final_speed, f32),
        brake_first=jnp.asarray(first, i32),
        brake_last=jnp.asarray(last, i32),
        target_speeds=jnp.asarray(ts, f32),
        traffic_lane=jnp.asarray(lane_of, i32).reshape(traffic),
        traffic_dx=jnp.asarray(dx, f32).reshape(traffic),
        traffic_speed=jnp.asarray(v, f32).reshape(traffic),
        traffic_jitter=jnp.asarray(traffic_jitter, f32),
        horizon=jnp.asarray(horizon, i32),
        rewards=RewardParams(jnp.asarray(w, f32), collision=jnp.asarray(collision, f32)),
    )
