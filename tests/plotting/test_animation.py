"""Animated GIFs of rollouts: thinned to a frame budget, the clip's duration kept."""

import numpy as np
import pytest
from PIL import Image

from mindgap.plotting.animation import save_gif


def test_frames_are_thinned_to_the_budget_and_keep_the_clip_s_duration(tmp_path):
    frames = [np.full((20, 30, 3), i % 256, np.uint8) for i in range(400)]
    n = save_gif(tmp_path / "a.gif", frames, fps=20.0, scale=1.0, max_frames=150)
    assert n == 134  # every 3rd frame of 400
    with Image.open(tmp_path / "a.gif") as gif:
        assert gif.n_frames == 134 and gif.size == (30, 20)
        assert gif.info["duration"] == 150  # 3 frames of 1/20 s each
    assert save_gif(tmp_path / "b.gif", frames[:10], scale=0.5) == 10
    with Image.open(tmp_path / "b.gif") as gif:
        assert gif.size == (15, 10)


def test_no_frames_is_one_line(tmp_path):
    with pytest.raises(ValueError, match="no frames to animate"):
        save_gif(tmp_path / "c.gif", [])
    assert not (tmp_path / "c.gif").exists()


def test_a_mujoco_env_draws_itself_headless():
    import jax

    from mindgap.envs.gym_world import gym_world_from_spec
    from mindgap.models.mlp import init_mlp
    from mindgap.plotting.animation import rollout_frames

    world = gym_world_from_spec("gym:mindgap/NoisyHopper-v0,max_episode_steps=5")
    actor = init_mlp(jax.random.key(0), (12, 8, 6))
    frames, _ = rollout_frames(world, actor)
    assert len(frames) >= 2 and frames[0].ndim == 3
    assert frames[0].mean() > 10.0  # drawn, not black
