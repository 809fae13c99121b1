"""Animations of gymnasium rollouts: frames from the env's own renderer, written as an animated GIF.

A gym world draws itself (``render_mode="rgb_array"``: pygame for Box2D and classic control,
MuJoCo's offscreen renderer for its envs), so a rollout becomes a short clip that a reader or
a study participant watches instead of reading a plot of 8-dimensional observations. Frames
are thinned to at most ``max_frames`` and shrunk by ``scale`` to keep files small; Pillow
writes the GIF (it ships with matplotlib).

A segment shown to a study participant was collected earlier, so its frames are drawn again
from its observations (:func:`observation_frames`): a MuJoCo env's state is its positions and
velocities, which the observations hold when the env keeps every position in them
(``exclude_current_positions_from_observation=False``, as mindgap's noisy hopper and cheetah
do). Envs whose observations do not determine their state (Box2D's lander: its bodies'
contacts and the terrain) cannot be drawn again from a segment.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._io import atomic_write
from ..models.actor import greedy_action


def save_gif(path: Path, frames: list[np.ndarray], fps: float = 25.0, scale: float = 0.5, max_frames: int = 150) -> int:
    """Write ``frames`` (each [H, W, 3] uint8) as an animated GIF, looping; returns the frames written.

    Every k-th frame is kept so that at most ``max_frames`` remain (the clip's duration is kept:
    each frame then shows for k / fps seconds, rounded to the GIF's unit of 10 ms, so that a clip
    lasts exactly its frames times that: two clips of as many frames loop in step).
    """
    from PIL import Image

    if not frames:
        raise ValueError(f"{path}: no frames to animate")
    step = max(1, int(np.ceil(len(frames) / max_frames)))
    kept = frames[::step]
    images = []
    for f in kept:
        im = Image.fromarray(np.asarray(f, np.uint8))
        if scale != 1.0:
            im = im.resize((max(1, int(im.width * scale)), max(1, int(im.height * scale))), Image.Resampling.BILINEAR)
        images.append(im.convert("P", palette=Image.Palette.ADAPTIVE))
    buf = io.BytesIO()
    duration = 10 * max(1, round(100 * step / fps))  # the GIF counts in hundredths of a second
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=duration, loop=0)
    atomic_write(path, buf.getvalue())
    return len(images)


def observation_frames(world, observations) -> list[np.ndarray]:
    """Frames of a gym world in each of ``observations`` ([T, d]) by setting its MuJoCo state from them.

    Raises:
        ValueError: the env is not a MuJoCo env, or its observations do not hold every
            position and velocity (one line, naming the fix).
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    env, _ = world.make(0, render_mode="rgb_array")
    try:
        inner = env.unwrapped
        obs = np.asarray(observations, np.float64)
        nq, nv = _state_sizes(world, inner, obs.shape[-1])
        if obs.ndim != 2:
            raise ValueError(f"{world.name}: observations must be [T, d], got shape {obs.shape}")
        frames = []
        for o in obs:
            inner.set_state(o[:nq], o[nq:])
            frames.append(np.asarray(env.render()))
        return frames
    finally:
        env.close()


def check_observation_frames(world) -> None:
    """Raise the one-line ValueError of :func:`observation_frames` now if ``world``'s segments cannot be drawn."""
    env, obs = world.make(0)
    try:
        _state_sizes(world, env.unwrapped, obs.shape[-1])
    finally:
        env.close()


def _state_sizes(world, inner, width: int) -> tuple[int, int]:
    """(positions, velocities) of a MuJoCo env whose observations of ``width`` numbers are exactly its state."""
    if not hasattr(inner, "set_state") or not hasattr(inner, "model"):
        raise ValueError(
            f"{world.name}: its segments cannot be drawn again from observations "
            "(only MuJoCo envs, whose observations can hold their whole state)"
        )
    nq, nv = inner.model.nq, inner.model.nv
    if width != nq + nv:
        raise ValueError(
            f"{world.name}: an observation of {width} numbers is not the state's {nq} positions and "
            f"{nv} velocities (make it with exclude_current_positions_from_observation=False)"
        )
    return nq, nv


_greedy = jax.jit(greedy_action)


def rollout_frames(world, actor, seed: int = 0, steps: int | None = None) -> tuple[list[np.ndarray], float]:
    """Frames of one greedy episode of ``actor`` (SAC actor parameters) on a gym world: (frames, return).

    MuJoCo envs draw with its headless EGL backend unless ``MUJOCO_GL`` says otherwise (its
    default, GLFW, needs a display).
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    env, obs = world.make(seed, render_mode="rgb_array")
    try:
        frames, ret = [env.render()], 0.0
        for _ in range(steps or world.horizon):
            act = np.asarray(_greedy(actor, jnp.asarray(np.asarray(obs, np.float32).reshape(-1))))
            obs, r, term, trunc, _ = env.step(world.to_env(act))
            frames.append(env.render())
            ret += float(r)
            if term or trunc:
                break
    finally:
        env.close()
    return frames, ret
