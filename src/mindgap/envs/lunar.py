"""The lunar lander with the dissertation's invisible solar wind (§3.4.2.2), and its reward in JAX.

True dynamics: "there is invisible solar wind blowing from left to right. Wind is simulated
by changing a percentage of the left action to no-op and reinforcing the right action."
:class:`SolarWindLander` is gymnasium's continuous ``LunarLander-v3`` where

* a side-engine firing that pushes the lander left (gymnasium's left booster, lateral
  throttle < −0.5) is dropped — the side engine stays off that step — with probability
  ``share``;
* one that pushes it right (lateral throttle > 0.5) acts with ``gain`` times its impulse.

A wrapper could drop an action but not push the side engine past its cap (|throttle| ≤ 1),
hence a subclass. The extra (gain − 1) share of the impulse is applied just before the
engine's own, at the point gymnasium's ``step`` fires it from (its constants, read from
gymnasium's module), without the small random dispersion gymnasium adds to the engine's own
share. The wind's draws come from a generator of their own, seeded with the episode, so the
lander's other randomness (terrain, initial push, engine dispersion) is that of the same
seed in a vacuum. The person's belief is the vacuum: gymnasium's ``LunarLander-v3`` with
``continuous=True`` (``gym:LunarLander-v3,continuous=True``). gymnasium's own
``enable_wind`` (a force plus turbulence on every step) is a different wind; it stays
available on both through the env's keyword arguments.

The id ``mindgap/SolarWindLander-v0`` is registered with gymnasium (:func:`register`),
so ``--env gym:mindgap/SolarWindLander-v0,share=0.5,gain=2.0`` runs it.

:func:`lander_reward` is gymnasium's per-step reward in JAX, for the simulated person:
the change of the shaping potential, minus fuel, and −100 on leaving the screen sideways
(|x| ≥ 1). Its two other terminal cases — a crash (the body touching the ground) and coming
to rest (Box2D putting the body to sleep) — are not in the observation, so the person does
not score them; their +100 / −100 are in the SAC oracle's reward, which is the env's own.
"""

from __future__ import annotations

import math

import gymnasium
import jax.numpy as jnp
import numpy as np

ENV_ID = "mindgap/SolarWindLander-v0"
"""The solar-wind lander's gymnasium id (registered by :func:`register`)."""
SIDE_OFFSET = 17
"""The height gymnasium's ``step`` fires a side engine from, in its pixels: the literal 17 of its code
(``SIDE_ENGINE_HEIGHT`` is 14; gymnasium notes the discrepancy and keeps it)."""


def _lander_module():
    from gymnasium.envs.box2d import lunar_lander

    return lunar_lander


def register() -> None:
    """Register :data:`ENV_ID` with gymnasium (once; later calls do nothing)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(ENV_ID, entry_point=f"{__name__}:SolarWindLander", max_episode_steps=1000)


def _make_class():
    m = _lander_module()

    class SolarWindLander(m.LunarLander):
        """gymnasium's lunar lander (continuous by default) under an invisible wind from the left.

        Args:
            share: probability that a left-pushing side-engine firing is dropped.
            gain: factor on the impulse of a right-pushing one (≥ 1).
        """

        def __init__(self, share: float = 0.5, gain: float = 2.0, continuous: bool = True, **kwargs):
            if not 0.0 <= share <= 1.0:
                raise ValueError(f"share must be in [0, 1], got {share}")
            if not gain >= 1.0:
                raise ValueError(f"gain must be at least 1, got {gain}")
            super().__init__(continuous=continuous, **kwargs)
            self.share, self.gain = float(share), float(gain)
            self._wind = np.random.default_rng()

        def reset(self, *, seed=None, options=None):
            out = super().reset(seed=seed, options=options)
            if seed is not None:
                self._wind = np.random.default_rng([int(seed), 0x5017A2])
            return out

        def _lateral(self, action) -> tuple[int, float]:
            """(direction, throttle) of the side engine this action fires: direction −1 pushes left,
            +1 right, 0 fires none."""
            if self.continuous:
                lat = float(np.clip(action[1], -1.0, 1.0))
                return (int(np.sign(lat)), float(np.clip(abs(lat), 0.5, 1.0))) if abs(lat) > 0.5 else (0, 0.0)
            return {1: (-1, 1.0), 3: (1, 1.0)}.get(int(action), (0, 0.0))

        def step(self, action):
            direction, power = self._lateral(action)
            if direction < 0 and self._wind.random() < self.share:
                action = np.array([action[0], 0.0], np.float32) if self.continuous else 0
            elif direction > 0 and self.gain > 1.0 and self.lander is not None:
                self._push(direction, power * (self.gain - 1.0))
            return super().step(action)

        def _push(self, direction: int, power: float) -> None:
            """The side engine's impulse times ``power``, where and as gymnasium's ``step`` applies it."""
            scale, away = m.SCALE, m.SIDE_ENGINE_AWAY
            tip = (math.sin(self.lander.angle), math.cos(self.lander.angle))
            side = (-tip[1], tip[0])
            ox, oy = side[0] * direction * away / scale, -side[1] * direction * away / scale
            pos = self.lander.position
            at = (pos[0] + ox - tip[0] * SIDE_OFFSET / scale, pos[1] + oy + tip[1] * m.SIDE_ENGINE_HEIGHT / scale)
            p = m.SIDE_ENGINE_POWER * power
            self.lander.ApplyLinearImpulse((-ox * p, -oy * p), at, True)

    return SolarWindLander


def __getattr__(name):
    # the class needs Box2D (gymnasium's box2d extra); build it only when asked for
    if name == "SolarWindLander":
        cls = _make_class()
        globals()[name] = cls
        return cls
    raise AttributeError(name)


def _shaping(obs):
    """gymnasium's shaping potential of an observation (its ``step``)."""
    return (
        -100.0 * jnp.sqrt(obs[0] ** 2 + obs[1] ** 2)
        - 100.0 * jnp.sqrt(obs[2] ** 2 + obs[3] ** 2)
        - 100.0 * jnp.abs(obs[4])
        + 10.0 * obs[6]
        + 10.0 * obs[7]
    )


def lander_reward(obs, act, next_obs, params):
    """gymnasium's continuous lunar-lander reward of a step, for the agent's ``act`` in [−1, 1]² (module docstring).

    Φ(s') − Φ(s) − 0.3 m − 0.03 s, with m the main engine's power (0.5–1 when its throttle is
    positive, else 0) and s the side engine's (0.5–1 when |lateral| > 0.5); −100 instead where
    the lander leaves the screen (|x'| ≥ 1). ``params`` is unused (the action bounds are ±1).
    """
    del params
    main = jnp.where(act[0] > 0.0, (jnp.clip(act[0], 0.0, 1.0) + 1.0) * 0.5, 0.0)
    side = jnp.where(jnp.abs(act[1]) > 0.5, jnp.clip(jnp.abs(act[1]), 0.5, 1.0), 0.0)
    r = _shaping(next_obs) - _shaping(obs) - 0.3 * main - 0.03 * side
    return jnp.where(jnp.abs(next_obs[0]) >= 1.0, -100.0, r)
