"""The simulated person who rates demonstrations (§2.2.1, §2.3.1)."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from ..data.demos import Demonstrations, RatedDemonstrations
from ..envs.tabular import TabularMDP
from ..models.rating import expected_rating
from ..planning import boltzmann_policy


@dataclass(frozen=True)
class RatingTeacher:
    """Rates a demonstration by how well it matches what they expect the robot to do.

    ``rating = γ_max · (Π π̃_H(a_i|s_i))^{1/n} + N(0, σ²)``, clipped to ``[0, γ_max]``,
    with ``π̃_H`` the softmax policy (rationality ``β``) of value iteration under the
    person's reward ``R_H = w · φ`` and believed dynamics ``T_H``.

    Attributes:
        mdp: the world (features, discount; its transitions are the truth).
        weights: ``[K]`` the person's reward weights ``w``.
        belief: ``[S, A, S]`` the person's believed dynamics ``T_H``.
        beta: rationality ``β``.
        gamma_max: highest rating.
        noise: rating noise ``σ``.
    """

    mdp: TabularMDP
    weights: jnp.ndarray
    belief: jnp.ndarray
    beta: float = 1.0
    gamma_max: float = 10.0
    noise: float = 0.5

    def __post_init__(self):
        if self.noise < 0 or self.gamma_max <= 0 or self.beta < 0:
            raise ValueError("noise and beta must be non-negative and gamma_max positive")

    def policy(self) -> jnp.ndarray:
        """``[S, A]`` the person's expected policy ``π̃_H`` for the robot."""
        reward = self.mdp.reward(self.weights)
        return boltzmann_policy(self.belief, reward, self.mdp.discount, self.beta)

    def mean_ratings(self, demos: Demonstrations) -> jnp.ndarray:
        """Noise-free ratings ``[N]``."""
        return expected_rating(jnp.log(self.policy()), demos, self.gamma_max)

    def rate(self, key, demos: Demonstrations) -> RatedDemonstrations:
        """Noisy, clipped ratings of ``demos``."""
        mean = self.mean_ratings(demos)
        noisy = mean + self.noise * jax.random.normal(key, mean.shape)
        return RatedDemonstrations(demos, jnp.clip(noisy, 0.0, self.gamma_max))
