"""The driving scenario in highway-env: the reference the JAX world is checked against, and what draws it.

:class:`SleetHighwayEnv` subclasses highway-env's ``HighwayEnv`` (``pip install
mindgap[driving]``; highway-env is imported only when the class is first used): the road,
controllers, bicycle model, collision test and pictures are highway-env's own; the scenario
(§4.4.2, Fig. 33: the green ego car behind the blue front car, same lane, same speed) and the
sleet are added by

* ``SleetyVehicle`` — highway-env's ``MDPVehicle`` whose speed controller, on a decision step
  that brakes, achieves μ times the commanded deceleration, μ drawn once per decision from the
  same Beta distribution as the JAX world (:mod:`~mindgap.envs.driving.sleet`);
* ``BrakingVehicle`` — a plain ``Vehicle`` that starts braking at ``front_decel`` down to
  ``front_final_speed`` at a decision step drawn with the JAX world's hazard;
* other cars (none by default) as plain ``Vehicle`` s that keep their speed.

Observations and rewards are the JAX world's (:func:`~mindgap.envs.driving.world.observe`'s
layout, r_A), so a policy trained on the JAX world runs here unchanged. ``reset(options=...)``
replays a JAX episode's draws (``grip``: μ of each decision; ``onset``: the front car's braking
step; ``traffic_dx``: the other cars' start offsets), so the same episode can be drawn.

Rendering: ``render_mode="rgb_array"`` draws offscreen (the ``offscreen_rendering`` config);
highway-env skips all drawing when ``SDL_VIDEODRIVER=dummy``, which would give black frames, so
this class turns its viewer back on. :meth:`SleetHighwayEnv.record` keeps every integration
step's frame (15 per decision) for animations, :func:`save_animation` writes them as a GIF.

The id ``mindgap/SleetHighway-v0`` is registered with gymnasium (:func:`register`)::

    env = gymnasium.make("mindgap/SleetHighway-v0", sleet=1.0, render_mode="rgb_array")
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium
import jax
import numpy as np

from .params import LENGTH, POLICY_FREQUENCY, SIMULATION_FREQUENCY, make_params
from .sleet import BRAKING_MARGIN, beta_params
from .world import EGO_OBS, onset_hazard
from .world import reward as _obs_reward

ENV_ID = "mindgap/SleetHighway-v0"
"""The scenario's gymnasium id (registered by :func:`register`)."""
START_X = 100.0
"""Where the ego starts along highway-env's road [m] (the JAX world starts it at 0): far enough in that
cars behind it are drawn on the road."""

_reward = jax.jit(_obs_reward)


def register() -> None:
    """Register :data:`ENV_ID` with gymnasium (once; highway-env is imported when the env is made)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(ENV_ID, entry_point=f"{__name__}:SleetHighwayEnv")


def _make_classes():
    from highway_env.envs.highway_env import HighwayEnv
    from highway_env.vehicle.controller import ControlledVehicle, MDPVehicle
    from highway_env.vehicle.graphics import VehicleGraphics
    from highway_env.vehicle.kinematics import Vehicle

    class SleetyVehicle(MDPVehicle):
        """highway-env's ``MDPVehicle``; on a braking decision step its speed controller's output is
        scaled by the grip μ that ``grip_source()`` returns (one draw per decision)."""

        def __init__(self, *args, grip_source=None, **kwargs):
            self.gain, self.grip, self.grip_source = 1.0, 1.0, grip_source
            super().__init__(*args, **kwargs)

        def act(self, action=None):
            super().act(action)
            if action is None:  # an integration step: the controls again, with this decision's gain
                return
            self.grip = float(self.grip_source()) if self.grip_source is not None else 1.0
            self.gain = self.grip if self.speed - self.target_speed > BRAKING_MARGIN else 1.0
            ControlledVehicle.act(self)

        def speed_control(self, target_speed: float) -> float:
            return self.gain * super().speed_control(target_speed)

    class BrakingVehicle(Vehicle):
        """A car driving straight that, once ``braking``, slows at ``decel`` to ``final_speed``."""

        def __init__(self, road, position, heading=0.0, speed=0.0, decel=5.0, final_speed=5.0, dt=0.1):
            super().__init__(road, position, heading, speed)
            self.braking, self.decel, self.final_speed, self.dt = False, decel, final_speed, dt
            self.color = VehicleGraphics.BLUE

        def act(self, action=None):
            a = -min(self.decel, max(self.speed - self.final_speed, 0.0) / self.dt) if self.braking else 0.0
            super().act({"steering": 0.0, "acceleration": a})

    class SleetHighwayEnv(HighwayEnv):
        """highway-env's highway as the driving scenario of §4.4.2 (module docstring).

        Args:
            config: highway-env config entries to change (rendering, mostly).
            render_mode: ``"rgb_array"`` for frames, ``"human"`` for a window, or None.
            sleet, traffic, **kwargs: the scenario, as :func:`~mindgap.envs.driving.params.make_params`.
        """

        def __init__(self, config: dict | None = None, render_mode: str | None = None, sleet=1.0, traffic=0, **kwargs):
            self.params = make_params(sleet=sleet, traffic=traffic, **kwargs)
            self.decisions, self.front, self._replay, self._recording, self.frames = 0, None, {}, False, []
            p = self.params
            if render_mode == "rgb_array" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
                os.environ.setdefault("SDL_VIDEODRIVER", "offscreen")  # no screen: SDL's offscreen driver
            base = {
                "lanes_count": int(p.lanes),
                "vehicles_count": 0,
                "duration": int(p.horizon) / POLICY_FREQUENCY,
                "policy_frequency": POLICY_FREQUENCY,
                "simulation_frequency": SIMULATION_FREQUENCY,
                "action": {"type": "DiscreteMetaAction", "target_speeds": [float(v) for v in p.target_speeds]},
                "offscreen_rendering": render_mode != "human",
            }
            super().__init__({**base, **(config or {})}, render_mode)

        def define_spaces(self) -> None:
            super().define_spaces()
            dim = EGO_OBS + 3 * (1 + self.params.n_traffic)
            self.observation_space = gymnasium.spaces.Box(-10.0, 10.0, (dim,), np.float32)

        def reset(self, *, seed: int | None = None, options: dict | None = None):
            """A new episode; ``options`` may replay a JAX episode's draws (``grip``, ``onset``, ``traffic_dx``)."""
            options = dict(options or {})
            self._replay = {k: options.pop(k) for k in ("grip", "onset", "traffic_dx") if k in options}
            self._grips = list(np.asarray(self._replay["grip"], np.float64)) if "grip" in self._replay else None
            self.decisions = 0
            super().reset(seed=seed, options=options or None)
            obs = self.observation()
            self.frames = [self.render()] if self._recording else []
            return obs, {"braking": False}

        def _create_vehicles(self) -> None:
            p, road = self.params, self.road
            lane = road.network.get_lane(("0", "1", int(p.start_lane)))
            speed = float(p.speed)
            ego = SleetyVehicle(
                road,
                lane.position(START_X, 0),
                lane.heading_at(START_X),
                speed,
                target_speeds=np.asarray(p.target_speeds, np.float64),
                grip_source=self._next_grip,
            )
            self.controlled_vehicles = [ego]
            road.vehicles.append(ego)
            self.front = BrakingVehicle(
                road,
                lane.position(START_X + float(p.gap) + LENGTH, 0),
                0.0,
                speed,
                decel=float(p.front_decel),
                final_speed=float(p.front_final_speed),
                dt=1.0 / self.config["simulation_frequency"],
            )
            road.vehicles.append(self.front)
            n = p.n_traffic
            if "traffic_dx" in self._replay:
                dx = np.asarray(self._replay["traffic_dx"], np.float64).reshape(n)
            else:
                dx = np.asarray(p.traffic_dx) + self.np_random.uniform(-1, 1, n) * float(p.traffic_jitter)
            for i in range(n):
                other = road.network.get_lane(("0", "1", int(p.traffic_lane[i])))
                road.vehicles.append(Vehicle(road, other.position(START_X + dx[i], 0), 0.0, float(p.traffic_speed[i])))

        def _next_grip(self) -> float:
            """μ of this decision: the replayed one, or a fresh draw from the sleet's Beta distribution."""
            if self._grips is not None:
                if not self._grips:
                    raise RuntimeError("the replayed grip sequence ran out: give one μ per decision step")
                return self._grips.pop(0)
            a, b = (float(v) for v in beta_params(self.params.sleet, self.params.grip))
            eps = float(np.finfo(np.float32).eps)
            return float(np.clip(self.np_random.beta(a, b), eps, 1 - eps))

        def step(self, action):
            """One decision: the front car may start braking, then highway-env simulates 1 s; observation and r_A
            as the JAX world's."""
            prev = self.observation()
            if not self.front.braking:
                if "onset" in self._replay:
                    self.front.braking = self.decisions >= int(self._replay["onset"])
                else:
                    h = float(onset_hazard(np.int32(self.decisions), self.params))
                    self.front.braking = bool(self.np_random.random() < h)
            _, _, _, truncated, info = super().step(action)
            self.decisions += 1
            obs = self.observation()
            if self._recording:
                self.frames.append(self.render())
            reward = float(_reward(prev, np.int32(action), obs, self.params))
            info.update(grip=self.vehicle.grip, braking=self.front.braking)
            # the horizon ends the task, as in the JAX world (world.py: "The horizon is terminal")
            return obs, reward, bool(self.vehicle.crashed or truncated), False, info

        def _reward(self, action) -> float:
            return 0.0  # r_A is computed in step, from the observations

        def observation(self) -> np.ndarray:
            """The JAX world's observation of the current scene (:func:`~mindgap.envs.driving.world.observe`)."""
            from .params import LANE_WIDTH
            from .world import DIST_SCALE, SPEED_SCALE

            ego, p = self.vehicle, self.params
            head = [
                ego.position[1] / LANE_WIDTH,
                ego.heading,
                ego.speed / SPEED_SCALE,
                float(ego.target_lane_index[2]),
                ego.target_speed / SPEED_SCALE,
                self.decisions / int(p.horizon),
                float(ego.crashed),
                float(self.front.braking),
            ]
            others = [
                ((v.position[0] - ego.position[0]) / DIST_SCALE, v.position[1] / LANE_WIDTH, v.speed / SPEED_SCALE)
                for v in self.road.vehicles[1:]
            ]
            return np.asarray(head + [x for o in others for x in o], np.float32)

        def ego_state(self) -> np.ndarray:
            """[4] the ego's x (from its start), y [m], heading [rad] and speed [m/s], in float64."""
            v = self.vehicle
            return np.array([v.position[0] - START_X, v.position[1], v.heading, v.speed])

        def record(self, on: bool = True) -> None:
            """Keep a frame of every integration step in ``frames`` (from the next reset or step on)."""
            if on and self.render_mode != "rgb_array":
                raise ValueError("recording frames needs render_mode='rgb_array'")
            self._recording = on

        def _automatic_rendering(self) -> None:
            if self._recording:
                self.frames.append(self.render())

        def render(self):
            if self.render_mode == "rgb_array" and self.viewer is not None:
                self.viewer.enabled = True  # highway-env turns drawing off under SDL's dummy driver
            elif self.render_mode == "rgb_array":
                from highway_env.envs.common.graphics import EnvViewer

                self.viewer = EnvViewer(self)
                self.viewer.enabled = True
            return super().render()

    return SleetyVehicle, BrakingVehicle, SleetHighwayEnv


_CLASSES = ("SleetyVehicle", "BrakingVehicle", "SleetHighwayEnv")


def __getattr__(name):
    # the classes need highway-env (mindgap's driving extra); build them only when asked for
    if name in _CLASSES:
        try:
            classes = _make_classes()
        except ImportError as e:
            raise ImportError(f"{name} needs highway-env: pip install 'mindgap[driving]' ({e})") from None
        globals().update(zip(_CLASSES, classes))
        return globals()[name]
    raise AttributeError(name)


def save_animation(frames, path: str | Path, fps: int = SIMULATION_FREQUENCY) -> Path:
    """Write ``frames`` ([H, W, 3] uint8 each) as a looping GIF at ``fps`` frames a second; returns the path."""
    from PIL import Image

    if not len(frames):
        raise ValueError("no frames to animate")
    path = Path(path)
    images = [Image.fromarray(np.asarray(f, np.uint8)) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return path


def segment_frames(obs, act, mask, **scenario) -> list[np.ndarray]:
    """highway-env's pictures of a recorded segment of the JAX world (a study item, §4.4.2, Fig. 33).

    ``obs [L, d]``, ``act [L]`` or ``[L, 1]`` (meta-action indices) and ``mask [L]`` are one segment
    (:class:`~mindgap.data.segments.Segments`' layout); ``next_obs`` is not needed: each real step's
    arrival is drawn by highway-env. ``scenario`` are the world's :func:`make_params` arguments
    (``sleet``, ``traffic``, ...).

    Exactness: at the start of every decision the highway-env scene is set to the recorded
    observation — the ego's lateral position, heading, speed and set-points (target lane, target
    speed), the other cars' positions relative to the ego and speeds, the front car's braking
    flag, the decision counter — so each decision's first frame shows the recorded state; the
    decision's 15 integration steps are then highway-env's own simulation of the recorded
    meta-action, with the braking factor μ recovered from the recorded speeds
    (:func:`~mindgap.envs.driving.sleet.factor_of_speed`, the sleet model's inverse) and the
    front car starting to brake where the record says it did, so the in-between frames follow
    the JAX world's step (the two agree within about a centimetre over an episode:
    ``tests/envs/test_driving_highway.py``). Only the ego's position along the road is carried
    over from highway-env's simulation (the observation holds none; the camera follows the ego).

    Returns:
        1 + 15 · n frames ([H, W, 3] uint8) for n real steps: the start, then every integration
        step of each decision.
    """
    from .params import LANE_WIDTH, SUBSTEPS
    from .sleet import factor_of_speed
    from .world import DIST_SCALE, SPEED_SCALE

    obs = np.asarray(obs, np.float64)
    act = np.asarray(act).reshape(len(obs), -1)[:, 0]
    n = int(np.asarray(mask, bool).sum())
    if obs.ndim != 2 or obs.shape[1] < EGO_OBS + 3:
        raise ValueError(f"a driving segment's observations must be [L, 8 + 3 M], got shape {obs.shape}")
    env = __getattr__("SleetHighwayEnv")(render_mode="rgb_array", **scenario)  # the class is built on first use
    try:
        env.record()
        env.reset(seed=0, options={"onset": 10**6})  # the front car brakes only where the record says

        def sync(o: np.ndarray, braking_next: bool) -> None:
            ego = env.vehicle
            x = ego.position[0]
            ego.position = np.array([x, o[0] * LANE_WIDTH])
            ego.heading, ego.speed = float(o[1]), float(o[2] * SPEED_SCALE)
            lane = int(round(o[3]))
            ego.target_lane_index = ("0", "1", lane)
            ego.target_speed = float(o[4] * SPEED_SCALE)
            ego.speed_index = ego.speed_to_index(ego.target_speed)
            ego.crashed = bool(o[6] > 0.5)
            ego.on_state_update()
            others = o[EGO_OBS:].reshape(-1, 3)
            for v, (dx, oy, ov) in zip(env.road.vehicles[1:], others):
                v.position = np.array([x + dx * DIST_SCALE, oy * LANE_WIDTH])
                v.speed = float(ov * SPEED_SCALE)
            env.front.braking = bool(o[7] > 0.5) or braking_next
            env.decisions = int(round(o[5] * int(env.params.horizon)))

        nxt = np.concatenate([obs[1:], obs[-1:]])
        sync(obs[0], False)
        env.frames = [env.render()]
        for t in range(n):
            # the next observation's set-point is the one the meta-action chose; its speed gives μ
            v, target = obs[t, 2] * SPEED_SCALE, nxt[t, 4] * SPEED_SCALE
            mu = 1.0
            if t + 1 < len(obs) and v - target > BRAKING_MARGIN:
                mu = float(factor_of_speed(v, target, nxt[t, 2] * SPEED_SCALE, SUBSTEPS)[0])
            eps = float(np.finfo(np.float32).eps)
            env._grips = [float(np.clip(mu, eps, 1 - eps)) if np.isfinite(mu) else 1.0]
            if t > 0:
                sync(obs[t], False)
            starts_braking = t + 1 < len(obs) and obs[t, 7] < 0.5 and nxt[t, 7] > 0.5
            env.front.braking = env.front.braking or starts_braking
            env.step(int(act[t]))
        return list(env.frames)
    finally:
        env.close()
