"""Expected state visitation in tabular MDPs (sampling trajectories: :func:`mindgap.envs.tabular.rollout`)."""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


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
