"""Hopper and half-cheetah a bit noisier than the person believes (§3.4.2.3), on gymnasium's MuJoCo envs.

"The dynamics is a bit more stochastic by applying a small amount of noise to some of the
transitions"; the person believes "the agent is operating reliably". :class:`HiddenNoise`
wraps gymnasium's ``Hopper-v5`` / ``HalfCheetah-v5``: after a step, with probability
``share``, every joint velocity (MuJoCo's ``qvel``, each in its own units) is perturbed by
N(0, ``scale``²), MuJoCo's derived quantities are recomputed (``mj_forward``) and the
observation is read again. The noise draws from a generator of its own, seeded with the
episode. The dissertation gives no amounts: ``share`` = 0.2 and ``scale`` = 0.5 are this
package's defaults, small beside the joints' typical speeds (a few units; gymnasium clips
the hopper's to ±10 in its observation).

Registered ids (:func:`register`): ``mindgap/NoisyHopper-v0`` and
``mindgap/NoisyHalfCheetah-v0``; the belief is the plain env with the same observation,
``gym:Hopper-v5,exclude_current_positions_from_observation=False``. Observations include the
x position, so that the person's reward — whose forward term is gymnasium's
(x' − x) / dt — is a function of the observations (:func:`hopper_reward`,
:func:`cheetah_reward`); the learners see it too.

This is the host-loop version of these domains; the pure-JAX one on MuJoCo's JAX backend
(MJX) is :mod:`~mindgap.envs.mjx_locomotion`.
"""

from __future__ import annotations

import gymnasium
import jax.numpy as jnp
import numpy as np

IDS = {"mindgap/NoisyHopper-v0": "Hopper-v5", "mindgap/NoisyHalfCheetah-v0": "HalfCheetah-v5"}
"""Registered id → the gymnasium env it wraps."""
POSITIONS = "exclude_current_positions_from_observation"


class HiddenNoise(gymnasium.Wrapper):
    """A MuJoCo env whose joint velocities are perturbed after a share of its steps (module docstring)."""

    def __init__(self, env, share: float = 0.2, scale: float = 0.5):
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"share must be in [0, 1], got {share}")
        if not scale >= 0.0:
            raise ValueError(f"scale must be non-negative, got {scale}")
        super().__init__(env)
        self.share, self.scale = float(share), float(scale)
        self._noise = np.random.default_rng()

    def reset(self, *, seed=None, options=None):
        out = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._noise = np.random.default_rng([int(seed), 0x401])
        return out

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._noise.random() < self.share:
            import mujoco

            base = self.env.unwrapped
            base.data.qvel[:] += self.scale * self._noise.standard_normal(base.model.nv)
            mujoco.mj_forward(base.model, base.data)
            obs = base._get_obs()
        return obs, reward, terminated, truncated, info


def _maker(base_id: str):
    def make(share: float = 0.2, scale: float = 0.5, **kwargs):
        kwargs.setdefault(POSITIONS, False)
        return HiddenNoise(gymnasium.make(base_id, **kwargs).unwrapped, share=share, scale=scale)

    return make


def register() -> None:
    """Register :data:`IDS` with gymnasium (once; later calls do nothing)."""
    for env_id, base in IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=_maker(base), max_episode_steps=1000)


def cheetah_reward(obs, act, next_obs, params):
    """HalfCheetah-v5's reward: ``w_f (x' − x) / dt − w_c Σ a²``, from observations that hold x (obs[0])."""
    forward = (next_obs[0] - obs[0]) / params["dt"]
    return params["forward_weight"] * forward - params["ctrl_weight"] * jnp.sum(jnp.square(act))


def hopper_reward(obs, act, next_obs, params):
    """Hopper-v5's reward: ``w_f (x' − x) / dt + h · healthy(s') − w_c Σ a²``, from observations that hold x.

    Healthy: height ``s'[1]`` above 0.7, torso angle ``s'[2]`` within ±0.2 and every later
    element within ±100 (gymnasium reads unclipped velocities there; the observation's are
    clipped to ±10, well inside).
    """
    forward = (next_obs[0] - obs[0]) / params["dt"]
    healthy = (next_obs[1] > 0.7) & (jnp.abs(next_obs[2]) < 0.2) & jnp.all(jnp.abs(next_obs[2:]) < 100.0)
    return (
        params["forward_weight"] * forward
        + jnp.where(healthy, 1.0, 0.0)
        - params["ctrl_weight"] * jnp.sum(jnp.square(act))
    )


def reward_params(base_timestep: float, frame_skip: int, ctrl_weight: float, excluded_by_default: bool):
    """The ``REWARDS`` entry's params of :func:`hopper_reward` / :func:`cheetah_reward` for an env made with
    ``kwargs``: dt = frame_skip × the model's timestep, the weights; None where the observation leaves x out
    (the forward velocity is then not a function of the observations)."""

    def extra(kwargs):
        if kwargs.get(POSITIONS, excluded_by_default):
            return None
        return {
            "dt": base_timestep * int(kwargs.get("frame_skip", frame_skip)),
            "forward_weight": float(kwargs.get("forward_reward_weight", 1.0)),
            "ctrl_weight": float(kwargs.get("ctrl_cost_weight", ctrl_weight)),
        }

    return extra


HOPPER = dict(base_timestep=0.002, frame_skip=4, ctrl_weight=1e-3)
CHEETAH = dict(base_timestep=0.01, frame_skip=5, ctrl_weight=0.1)
