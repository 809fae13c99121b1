"""A gymnasium ``Env`` around a terrain world, so gymnasium-based libraries can use it.

Each ``step`` calls one jitted JAX function (sample, reward, termination, observation in
one dispatch). For many environments at once, use the functional API with ``jax.vmap``
instead: it is orders of magnitude faster (see ``benchmarks/terrain_step.py``).
:func:`terrain_image`, the picture of the map under the rendered frames, is also the
map of :mod:`mindgap.plotting.terrain`'s figures.
"""

from __future__ import annotations

import gymnasium as gym
import jax
import numpy as np
from matplotlib.colors import to_rgb

from ... import rng
from .files import load_world
from .layout import FLOOR, GOAL, ICE, PIT, SAND, WALL
from .params import TerrainParams
from .world import TerrainWorld, observe, reset, step

COLOURS = {
    WALL: "#4d4d4d",
    FLOOR: "#f5f2ea",
    ICE: "#a9d8f2",
    PIT: "#7b4a26",
    GOAL: "#5cb85c",
}
"""Colour of each terrain code in the map picture; sand is shaded between ``SAND_EASY`` and ``SAND_HARD``."""
SAND_EASY, SAND_HARD = np.array(to_rgb("#d4a72c")), np.array(to_rgb("#f6e3a1"))


def terrain_image(params) -> np.ndarray:
    """[H, W, 3] RGB picture of the map; sand is darker the easier it is (as in Fig. 27)."""
    grid = np.asarray(params.grid)
    img = np.zeros(grid.shape + (3,))
    for code, col in COLOURS.items():
        img[grid == code] = to_rgb(col)
    dyn = params.dynamics
    ease = float(np.asarray(dyn.speed)[SAND] * (1 - np.asarray(dyn.stuck)[SAND]))
    img[grid == SAND] = SAND_HARD + (SAND_EASY - SAND_HARD) * np.clip(ease, 0, 1)
    return img


@jax.jit
def _jit_step(key, state, action, params):
    key, sub = jax.random.split(key)
    out = step(sub, state, action, params)
    return key, out, observe(out.state, params)


@jax.jit
def _jit_reset(key, params):
    key, sub = jax.random.split(key)
    state = reset(sub, params)
    return key, state, observe(state, params)


class TerrainEnv(gym.Env):
    """Gymnasium view of a terrain world.

    Observation: the position scaled to [−1, 1]² (float32). Action: a displacement
    command in [−1, 1]². ``terminated`` on pit or goal, ``truncated`` at the horizon.
    ``info`` carries the position in cells and the terrain code.

    Args:
        world: a :class:`TerrainWorld`, a world name (``nav1`` … ``d4``) or a world file.
        belief: step under this belief's table instead of the true one (a simulated
            person's imagined world).
        render_mode: ``"rgb_array"`` for frames of the map with the agent drawn on it.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 8}

    def __init__(self, world: TerrainWorld | str = "nav1", belief: str | None = None, render_mode: str | None = None):
        self.world = world if isinstance(world, TerrainWorld) else load_world(world)
        self.params: TerrainParams = self.world.belief(belief) if belief else self.world.params
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._key = rng.key(0)
        self._state = None

    def reset(self, *, seed: int | None = None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._key = rng.key(seed)
        self._key, self._state, obs = _jit_reset(self._key, self.params)
        return np.asarray(obs), self._info()

    def step(self, action):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, np.float32).reshape(2)
        self._key, out, obs = _jit_step(self._key, self._state, a, self.params)
        self._state = out.state
        obs, reward, term, trunc, pos, t = jax.device_get(
            (obs, out.reward, out.terminated, out.truncated, out.state.pos, out.state.t)
        )  # one transfer instead of six
        return obs, float(reward), bool(term), bool(trunc), {"pos": pos, "t": int(t)}

    def _info(self) -> dict:
        return {"pos": np.asarray(self._state.pos), "t": int(self._state.t)}

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        k = 16
        img = np.repeat(np.repeat(terrain_image(self.params), k, 0), k, 1)
        x, y = np.asarray(self._state.pos) * k if self._state is not None else (-10, -10)
        yy, xx = np.mgrid[: img.shape[0], : img.shape[1]]
        img[(xx - x) ** 2 + (yy - y) ** 2 <= (k * 0.3) ** 2] = (0.84, 0.15, 0.16)
        return (img * 255).astype(np.uint8)


def register_named_worlds() -> None:
    """Register ``mindgap/NAME-v0`` for the named worlds with gymnasium (done on import)."""
    from .files import NAMED_WORLDS

    for name in NAMED_WORLDS:
        env_id = f"mindgap/{name}-v0"
        if env_id not in gym.registry:
            gym.register(env_id, entry_point="mindgap.envs.terrain.gym_env:TerrainEnv", kwargs={"world": name})


register_named_worlds()
