"""Fixtures of the env tests."""

import numpy as np
import pytest

from mindgap.envs.gym_world import gym_world_from_spec


def _rollout(spec, actions, seed):
    """Run ``actions`` on a fresh env of ``spec`` reset with ``seed``, stopping at the episode's end:
    (the world, observations [T+1, d], gymnasium's rewards [T])."""
    world = gym_world_from_spec(spec)
    env, obs = world.make(seed)
    out, rewards = [obs], []
    try:
        for a in actions:
            o, r, term, trunc, _ = env.step(world.to_env(a))
            out.append(np.asarray(o, np.float32)), rewards.append(r)
            if term or trunc:
                break
    finally:
        env.close()
    return world, np.stack(out), np.asarray(rewards)


@pytest.fixture
def gym_rollout():
    """:func:`_rollout`: one episode of given actions on a gym world."""
    return _rollout
