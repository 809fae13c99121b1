"""The policy explicability score −KL(p_A(τ) ‖ p_A^H(τ)) of Eq. 4.4, by Monte Carlo over agent rollouts.

Eq. 4.3 defines the two trajectory distributions over the same start distribution ρ:

    p_A(τ)   = ρ(s₀) Π_t T_A(s_{t+1}|s_t, a_t)   π_θ(a_t|s_t)   — the agent, in the true world;
    p_A^H(τ) = ρ(s₀) Π_t T_A^H(s_{t+1}|s_t, a_t) π_A^H(a_t|s_t) — what the person expects:
               their believed dynamics and their expected policy π_H.

ρ cancels, so with τ ~ p_A (the agent's own rollouts in the true world)

    KL(p_A ‖ p_A^H) = E_{p_A} Σ_t [log T_A − log T_H](s_{t+1}|s_t,a_t) + [log π_θ − log π_H](a_t|s_t),

summed over the steps the episode lasts. Both models end an episode at the same place
(goal, pit: a function of the position) or at the horizon, so the stopping time is the
same under both and adds nothing. Both log T come from the world's exact ``log_prob`` under
its true params and under the person's (for the terrain worlds
:func:`~mindgap.envs.terrain.log_prob_pos`, the same mixed measure — a point mass when the
agent stays, a density per cell² otherwise — under both tables), and the agent and π_H
are tanh-Gaussian, so each policy term is the difference of the pre-tanh Gaussian log
densities at the drawn pre-tanh action u: the tanh Jacobian is common to both and cancels
exactly, which keeps saturated actions (|a| → 1) finite.

The agent acts with its stochastic policy: a deterministic policy against a density has
an infinite KL. Written by hand: the estimator is a few lines around the world's own
``step`` and ``log_prob``.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..envs.interface import World, check_env
from ..models.actor import actor_dist
from ..models.squashed import gaussian_log_prob


class Explicability(NamedTuple):
    """A Monte Carlo estimate over E episodes.

    Attributes:
        score: −KL(p_A ‖ p_A^H), the mean of ``per_episode``.
        stderr: its standard error.
        dynamics: E Σ_t [log T_A − log T_H] (the part due to the person's belief).
        policy: E Σ_t [log π_θ − log π_H] (the part due to the person's expected policy).
        per_episode: [E] −Σ_t of both log ratios along each rollout.
        returns: [E] the rollouts' returns under the true reward.
    """

    score: jax.Array
    stderr: jax.Array
    dynamics: jax.Array
    policy: jax.Array
    per_episode: jax.Array
    returns: jax.Array


def explicability(
    key: jax.Array,
    world: World,
    belief,
    agent,
    expected_actor,
    episodes: int = 100,
    agent_dist: Callable = actor_dist,
) -> Explicability:
    """−KL(p_A(τ) ‖ p_A^H(τ)) (Eq. 4.4) from ``episodes`` rollouts of the agent in ``world``.

    Args:
        world: the true world (T_A, ρ, reward, horizon); its env needs ``log_prob``.
        belief: the world's params under the person's dynamics (T_H).
        agent: parameters of the agent's policy, read by ``agent_dist``.
        expected_actor: SAC actor parameters of π_H
            (:func:`~mindgap.algorithms.expected_policy.expected_policy`).
        agent_dist: ``agent_dist(agent, obs [d]) → (mean [a], log_std [a])`` of the agent's
            pre-tanh Gaussian; SAC's actor by default, a shaped policy's
            (:func:`~mindgap.algorithms.policy_shaping.shaped_dist`) for Policy Shaping. A
            module-level function, so the compiled program is reused.
    """
    check_env(world.env, density=True, who="the explicability score")
    args = (world.env, episodes, world.horizon, agent_dist)
    return _explicability(key, world.params, belief, agent, expected_actor, *args)


@partial(jax.jit, static_argnums=(5, 6, 7, 8))
def _explicability(key, params, belief, agent, expected_actor, env, episodes, horizon, agent_dist):
    models = jax.tree.map(lambda t, h: jnp.stack([t, h]), params, belief)  # T_A and T_H

    def episode(k):
        k0, k1 = jax.random.split(k)

        def body(carry, kk):
            s, done = carry
            k_act, k_env = jax.random.split(kk)
            obs = env.observe(s, params)
            mean, log_std = agent_dist(agent, obs)
            u = mean + jnp.exp(log_std) * jax.random.normal(k_act, mean.shape, mean.dtype)
            a = jnp.tanh(u)
            out = env.step(k_env, s, a, params)
            nxt = env.observe(out.state, params)
            both = jax.vmap(env.log_prob, (None, None, None, 0))(obs, a, nxt, models)  # one program for both
            log_t = both[0] - both[1]
            h_mean, h_log_std = actor_dist(expected_actor, obs)
            log_pi = gaussian_log_prob(mean, log_std, u) - gaussian_log_prob(h_mean, h_log_std, u)
            alive = ~done
            state = jax.tree.map(lambda x, y: jnp.where(done, x, y), s, out.state)
            ended = done | out.terminated | out.truncated
            r = jnp.where(alive, out.reward, 0.0)
            return (state, ended), (jnp.where(alive, log_t, 0.0), jnp.where(alive, log_pi, 0.0), r)

        start = (env.reset(k0, params), jnp.zeros((), bool))
        _, (log_t, log_pi, rew) = jax.lax.scan(body, start, jax.random.split(k1, horizon))
        return log_t.sum(), log_pi.sum(), rew.sum()

    log_t, log_pi, returns = jax.vmap(episode)(jax.random.split(key, episodes))
    per_episode = -(log_t + log_pi)
    stderr = jnp.std(per_episode) / jnp.sqrt(jnp.maximum(episodes - 1, 1))
    return Explicability(per_episode.mean(), stderr, log_t.mean(), log_pi.mean(), per_episode, returns)


def explicability_scores(key, world, person, actors, episodes: int = 100, agent_dist=actor_dist):
    """Explicability score (Eq. 4.4) of each seed's policy over ``episodes`` stochastic rollouts.

    Args:
        person: the simulated person (its ``belief`` params and expected policy ``policy``; a
            :class:`~mindgap.teachers.expectation.ExpectationTeacher`).
        actors: the policies' parameters with a leading seed axis: SAC actors, or what
            ``agent_dist`` reads (e.g. a :class:`~mindgap.algorithms.policy_shaping.ShapedPolicy`
            with :func:`~mindgap.algorithms.policy_shaping.shaped_dist`).

    Returns:
        one dict per seed: score, its standard error, its dynamics and policy parts
        (see :class:`Explicability`) and the mean return
        of those rollouts.
    """
    seeds = jax.tree.leaves(actors)[0].shape[0]
    out = []
    for s, k in enumerate(jax.random.split(key, seeds)):
        actor = jax.tree.map(lambda a: a[s], actors)
        e = explicability(k, world, person.belief, actor, person.policy, episodes, agent_dist)
        out.append(
            {
                "score": float(e.score),
                "stderr": float(e.stderr),
                "dynamics_part": float(e.dynamics),
                "policy_part": float(e.policy),
                "stochastic_return": float(jnp.mean(e.returns)),
            }
        )
    return out
