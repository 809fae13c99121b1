"""A minibatch of transitions, as the critic's update reads it."""

from __future__ import annotations

from typing import NamedTuple

import jax


class Batch(NamedTuple):
    """Transitions: obs [B, d], act [B, a], reward [B], next_obs [B, d], terminal [B] (no bootstrap).

    ``discount [B]``, when given, replaces γ in the target: γ^m for a transition that sums the
    rewards of m steps (see :func:`~mindgap.data.replay.replay_sample`).
    """

    obs: jax.Array
    act: jax.Array
    reward: jax.Array
    next_obs: jax.Array
    terminal: jax.Array
    discount: jax.Array | None = None
