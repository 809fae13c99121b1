"""Sampling trajectories and computing state visitation in tabular MDPs."""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


@partial(jax.jit, static_argnames=("n_episodes", "length"))
def rollout(key, transitions, policy, initial, n_episodes: int, length: int):
    """Sample ``n_episodes`` trajectories of ``length`` steps.

    Args:
        key: PRNG key.
        transitions: ``[S, A, S]`` dynamics the trajectories follow.
        policy: ``[S, A]`` action probabilities.
        initial: ``[S]`` start distribution.
        n_episodes, length: static sizes.

    Returns:
        ``(states, actions)``, each ``[n_episodes, length]`` int32: the state-action
        pairs ``(s_t, a_t)`` of each demonstration.
    """
    k0, k_steps = jax.random.split(key)
    s0 = jax.random.categorical(k0, jnp.log(initial), shape=(n_episodes,))
    log_pi = jnp.log(policy)
    log_t = jnp.log(transitions)

    def step(s, k):
        ka, ks = jax.random.split(k)
        a = jax.random.categorical(ka, log_pi[s])
        s_next = jax.random.categorical(ks, log_t[s, a])
        return s_next, (s, a)

    _, (states, actions) = jax.lax.scan(step, s0, jax.random.split(k_steps, length))
    return states.T.astype(jnp.int32), actions.T.astype(jnp.int32)


@partial(jax.jit, static_argnames=("horizon",))
def state_visitation(transitions, policy, start, horizon: int, discount=1.0):
    """Expected (discounted) state visitation counts ``Σ_t λ^t p_t(s)`` over ``horizon`` steps.

    Args:
        transitions: ``[..., S, A, S]``.
        policy: ``[..., S, A]``.
        start: ``[..., S]`` distribution of the first state.
        horizon: number of steps counted (static).
        discount: ``λ``; 1 gives plain expected counts of a length-``horizon`` trajectory.

    Returns:
        ``[..., S]`` visitation counts.
    """
    p_next = jnp.einsum("...sa,...sat->...st", policy, transitions)

    def body(carry, _):
        p, w = carry
        return (jnp.einsum("...s,...st->...t", p, p_next), w * discount), w * p

    _, visits = jax.lax.scan(body, (start, jnp.asarray(1.0, start.dtype)), None, length=horizon)
    return visits.sum(0)
