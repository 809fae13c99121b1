"""Grid tasks: the ``grid7`` world of :mod:`mindgap.envs.grid` with reward corners picked by planning.

The corner pair is chosen among those for which the person's belief misleads an
unaware learner (dissertation §2.3.1); finding them needs value iteration, so task building
sits here, above the world pieces in :mod:`mindgap.envs.grid`.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..envs.grid import (
    CORNERS,
    belief_transitions,
    corner_cells,
    corner_features,
    moves_to_transitions,
    parse_belief,
    true_move_probs,
)
from ..envs.tabular import TabularMDP
from .value_iteration import q_values


class GridTask(NamedTuple):
    """A grid world, the person's reward weights and the person's believed dynamics."""

    mdp: TabularMDP
    human_transitions: jnp.ndarray
    true_weights: jnp.ndarray
    corners: tuple[int, int]
    size: int
    belief: str


def informative_pairs(size: int, true_t: np.ndarray, human_t: np.ndarray, weights=(5.0, -5.0), discount=0.9):
    """Corner pairs ``(reward, penalty)`` for which the belief misleads an unaware learner.

    The person's greedy actions under their belief, executed by the real robot, move
    it down the reward gradient (mean one-step reward change below zero): a learner
    that assumes the true dynamics then infers the wrong reward. Returns the most
    misleading pairs (within half of the strongest effect); empty when none misleads.
    Under ``reversed`` these are the pairs in one column, under ``rotated`` the
    anti-diagonal (dissertation §2.3.1).
    """
    corners = corner_cells(size)
    pairs = list(itertools.permutations(range(4), 2))
    rewards = np.stack([corner_features(size, corners[[i, j]]) @ np.asarray(weights) for i, j in pairs])
    greedy = np.asarray(q_values(jnp.asarray(human_t), jnp.asarray(rewards, jnp.float32), discount)).argmax(-1)
    gains = {}
    for k, pair in enumerate(pairs):
        moved = true_t[np.arange(size * size), greedy[k]] @ rewards[k]
        gains[pair] = float((moved - rewards[k]).mean())
    worst = min(gains.values())
    if worst >= 0:
        return []
    return [pair for pair, g in gains.items() if g <= 0.5 * worst]


def make_grid(
    size: int = 7,
    belief="reversed",
    *,
    seed: int = 0,
    corners: tuple[int, int] | None = None,
    weights=(5.0, -5.0),
    slip: float = 0.1,
    discount: float = 0.9,
) -> GridTask:
    """Build a grid task: true world, the person's belief and reward weights.

    Args:
        size: grid side (``grid7`` is 7).
        belief: see :func:`mindgap.envs.grid.parse_belief`.
        seed: picks the corner pair among the informative ones for this belief (all
            pairs when none is informative) unless ``corners`` is given.
        corners: ``(reward_corner, penalty_corner)`` as indices into
            :data:`mindgap.envs.grid.CORNERS`.
        weights: reward weights of the two corner features.
        slip: probability of an unintended move.
        discount: ``λ``.

    Raises:
        ValueError: a size below 2, an invalid belief or invalid corners.
    """
    if size < 2:
        raise ValueError(f"grid size must be at least 2, got {size}")
    true_t = moves_to_transitions(true_move_probs(slip), size)
    name, tensor, perm = parse_belief(belief)
    human_t = belief_transitions(true_t, tensor, perm)
    if corners is None:
        pairs = informative_pairs(size, true_t, human_t, weights, discount) or list(itertools.permutations(range(4), 2))
        corners = pairs[np.random.default_rng(seed).integers(len(pairs))]
    if len(corners) != 2 or corners[0] == corners[1] or not all(0 <= c < 4 for c in corners):
        raise ValueError(f"corners must be two different indices into {CORNERS}, got {corners}")
    feats = corner_features(size, corner_cells(size)[list(corners)])
    n = size * size
    mdp = TabularMDP(
        transitions=jnp.asarray(true_t, jnp.float32),
        features=jnp.asarray(feats, jnp.float32),
        discount=jnp.asarray(discount, jnp.float32),
        initial=jnp.full((n,), 1.0 / n, jnp.float32),
    )
    return GridTask(
        mdp=mdp,
        human_transitions=jnp.asarray(human_t, jnp.float32),
        true_weights=jnp.asarray(weights, jnp.float32),
        corners=(int(corners[0]), int(corners[1])),
        size=size,
        belief=name,
    )
