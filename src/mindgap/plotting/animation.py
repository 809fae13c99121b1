"""Animations of gymnasium rollouts: frames from the env's own renderer, written as an animated GIF.

A gym world draws itself (``render_mode="rgb_array"``: pygame for Box2D and classic control,
MuJoCo's offscreen renderer for its envs), so a rollout becomes a short clip that a reader or
a study participant watches instead of reading a plot of 8-dimensional observations. Frames
are thinned to at most ``max_frames`` and shrunk by ``scale`` to keep files small; Pillow
writes the GIF (it ships with matplotlib).
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
    each frame then shows for k / fps seconds).
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
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 * step / fps), loop=0)
    atomic_write(path, buf.getvalue())
    return len(images)


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
