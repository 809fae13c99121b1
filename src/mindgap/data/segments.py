"""Segments of experience for preference queries, cut from the replay buffer.

A segment is ``length`` consecutive transitions of one episode. Episodes may end inside
a segment (goal, pit, horizon): the steps after the end are masked out, so they count
neither for the simulated person nor for the reward model.

With ``absorbing=True`` the steps after a *terminal* transition (goal or pit; not the
horizon, which only truncates the episode) are kept as steps in an absorbing state
instead (Kostrikov et al. 2019, "Discriminator-Actor-Critic"): once an episode
has terminated the agent stays, in the MDP's own terms, in a state where every step earns
the same reward — truly 0, under a learned model a learned ``r_abs`` (one constant, or one
per terminal state: :mod:`~mindgap.models.reward_ensemble`). Dropping
those steps makes a segment that reaches the goal early *shorter* than one that idles
before it, and a learned return, a sum of bounded per-step rewards, then favours idling
(the termination bias of learned rewards that Kostrikov et al. describe). With absorbing
steps both segments have the same length and the reward model can learn what the end of
an episode is worth. Steps past the end of the buffer's contiguous episode for any other
reason (a horizon truncation, the ring pointer) stay masked out.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .replay import Replay


class Segments(NamedTuple):
    """obs, next_obs [K, L, d]; act [K, L, a]; mask [K, L] (True for real steps); env_reward [K, L] or None.

    A plain ``Segments`` has no absorbing steps; :class:`AbsorbingSegments` adds them.
    ``env_reward`` holds the rewards the env returned, where the segments were cut from a
    buffer (:func:`sample_segments`): the ordinary simulated person of an env without an exact
    reward function sums them (:func:`~mindgap.teachers.preference.segment_scores`). Stored
    answers and segments built by hand have none.
    """

    obs: jax.Array
    act: jax.Array
    next_obs: jax.Array
    mask: jax.Array
    env_reward: jax.Array | None = None


SHOWN = ("obs", "act", "next_obs", "mask")
"""The fields of a segment as it is shown, stored and sent to people: without the env's rewards."""


class AbsorbingSegments(NamedTuple):
    """The fields of :class:`Segments` and ``absorbed [K, L]``: True for the steps after a terminal transition.

    ``mask`` and ``absorbed`` never overlap. A separate type rather than a fifth field of
    :class:`Segments`, so that code building ``Segments`` from its four fields (the study
    app, stored preferences) keeps working unchanged; :func:`absorbed_steps` reads either.
    """

    obs: jax.Array
    act: jax.Array
    next_obs: jax.Array
    mask: jax.Array
    absorbed: jax.Array
    env_reward: jax.Array | None = None


def absorbed_steps(seg) -> jax.Array:
    """The absorbing steps ``[K, L]`` of ``seg``: all False for a plain :class:`Segments`."""
    absorbed = getattr(seg, "absorbed", None)
    return jnp.zeros(jnp.shape(seg.mask), bool) if absorbed is None else absorbed


def terminal_obs(seg) -> jax.Array:
    """The state ``s_T [..., d]`` each segment's last real step ends in: the absorbing state its absorbed steps stay in.

    Meaningful only for segments with absorbing steps (a segment without any simply gives
    its last real step's next observation).
    """
    last = jnp.maximum(seg.mask.sum(-1) - 1, 0)  # [...]
    return jnp.take_along_axis(seg.next_obs, last[..., None, None], axis=-2)[..., 0, :]


def with_absorbing(seg, absorbing: bool):
    """``seg`` as :class:`AbsorbingSegments` (no absorbing steps added) or as plain :class:`Segments` (any dropped),
    in a store's form: without the env's rewards."""
    if absorbing:
        return AbsorbingSegments(seg.obs, seg.act, seg.next_obs, seg.mask, absorbed_steps(seg))
    return Segments(seg.obs, seg.act, seg.next_obs, seg.mask)


def sample_segments(
    buf: Replay, key: jax.Array, count: int, length: int, absorbing: bool = False, from_start: bool = False
):
    """``count`` segments starting at uniformly drawn stored transitions.

    With ``from_start`` they start only at an episode's first transition (``ep_step == 0``), so
    two segments of a world whose episodes begin in one situation show two behaviours from that
    situation; uniformly anywhere when the buffer holds no episode start.

    Returns:
        :class:`Segments`, or with ``absorbing`` :class:`AbsorbingSegments` whose steps after a
        terminal transition are marked ``absorbed`` (the mask is the same either way).
    """
    start = jax.random.randint(key, (count,), 0, jnp.maximum(buf.size, 1))
    if from_start:
        first = (buf.ep_step == 0) & (jnp.arange(buf.capacity) < buf.size)
        start = jnp.where(first.any(), _draw_among(first, key, count), start)
    idx = (start[:, None] + jnp.arange(length)[None, :]) % buf.capacity  # [K, L]
    ep = buf.ep_step[idx]
    contiguous = (ep == ep[:, :1] + jnp.arange(length)[None, :]) & (ep >= 0)
    ended_before = jnp.cumsum(buf.terminal[idx], axis=1) - buf.terminal[idx]  # a terminal earlier in the segment
    mask = jnp.cumprod(contiguous & (ended_before == 0), axis=1).astype(bool)
    if not absorbing:
        return Segments(buf.obs[idx], buf.act[idx], buf.next_obs[idx], mask, buf.env_reward[idx])
    # the last real step was terminal: everything after it is absorbing
    ended = jnp.cumsum(mask & buf.terminal[idx], axis=1) - (mask & buf.terminal[idx]) > 0
    return AbsorbingSegments(buf.obs[idx], buf.act[idx], buf.next_obs[idx], mask, ended & ~mask, buf.env_reward[idx])


def _draw_among(eligible: jax.Array, key: jax.Array, count: int) -> jax.Array:
    """``count`` indices drawn uniformly among the True entries of ``eligible [N]`` (at least one)."""
    cum = jnp.cumsum(eligible.astype(jnp.int32))
    u = jax.random.randint(key, (count,), 0, jnp.maximum(cum[-1], 1))
    return jnp.minimum(jnp.searchsorted(cum, u, side="right"), eligible.shape[0] - 1)


def take(seg, idx: jax.Array):
    """The segments at ``idx``."""
    return jax.tree.map(lambda x: x[idx], seg)
