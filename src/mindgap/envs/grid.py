"""The grid navigation domain of §2.3.1 (``grid7``) and its belief variants (SPEC §3.1).

States are cells ``s = row * size + col`` with row 0 at the top. Actions are
0 Up, 1 Down, 2 Left, 3 Right. The robot makes the intended move with probability
0.9 and one of the other three moves uniformly otherwise; a move into the border
leaves the state unchanged. One reward cell and one penalty cell sit at two corners;
``φ_k(s) = 1 / (1 + manhattan(s, c_k))`` and ``R_H(s) = w · φ(s)``.

A belief is "the same world with other parameters": an action permutation
(``T_H[:, a] = T_A[:, perm[a]]``, i.e. the person thinks action ``a`` does what
``perm[a]`` really does) or any explicit ``[S, A, S]`` tensor.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..planning import q_values
from .tabular import TabularMDP, check_transitions

ACTIONS = ("Up", "Down", "Left", "Right")
MOVES = ((-1, 0), (1, 0), (0, -1), (0, 1), (0, 0))
"""Relative moves (row, col): up, down, left, right, stay; action ``a`` intends ``MOVES[a]``."""
MOVE_NAMES = ("up", "down", "left", "right", "stay")
CORNERS = ("top-left", "top-right", "bottom-left", "bottom-right")
NAMED_BELIEFS = {
    "true": (0, 1, 2, 3),
    "reversed": (1, 0, 2, 3),
    "rotated": (2, 3, 0, 1),
}
"""``reversed`` swaps Up and Down; ``rotated`` is Up→Left, Down→Right, Left→Up, Right→Down."""


class GridTask(NamedTuple):
    """A grid world, the person's reward weights and the person's believed dynamics."""

    mdp: TabularMDP
    human_transitions: jnp.ndarray
    true_weights: jnp.ndarray
    corners: tuple[int, int]
    size: int
    belief: str


def move_targets(size: int) -> np.ndarray:
    """``[S, 5]`` next state of each relative move in :data:`MOVES` (walls keep the state)."""
    rows, cols = np.divmod(np.arange(size * size), size)
    out = np.empty((size * size, len(MOVES)), dtype=np.int32)
    for m, (dr, dc) in enumerate(MOVES):
        r = rows + dr
        c = cols + dc
        inside = (r >= 0) & (r < size) & (c >= 0) & (c < size)
        out[:, m] = np.where(inside, r * size + c, rows * size + cols)
    return out


def true_move_probs(slip: float = 0.1) -> np.ndarray:
    """``[A, 5]`` probability of each relative move per action under the true dynamics."""
    probs = np.full((4, len(MOVES)), slip / 3.0)
    probs[:, 4] = 0.0
    probs[np.arange(4), np.arange(4)] = 1.0 - slip
    return probs


def moves_to_transitions(move_probs: np.ndarray, size: int) -> np.ndarray:
    """Expand ``[A, 5]`` move probabilities shared by all cells into ``[S, A, S]``."""
    targets = move_targets(size)
    n = size * size
    t = np.zeros((n, move_probs.shape[0], n))
    for a in range(move_probs.shape[0]):
        for m in range(len(MOVES)):
            np.add.at(t[:, a], (np.arange(n), targets[:, m]), move_probs[a, m])
    return t


def corner_cells(size: int) -> np.ndarray:
    """State index of each corner in :data:`CORNERS` order."""
    last = size - 1
    return np.array([0, last, last * size, last * size + last])


def corner_features(size: int, cells) -> np.ndarray:
    """``[S, K]`` features ``φ_k(s) = 1 / (1 + manhattan(s, c_k))`` for the given cells."""
    rows, cols = np.divmod(np.arange(size * size), size)
    feats = []
    for c in cells:
        cr, cc = divmod(int(c), size)
        feats.append(1.0 / (1.0 + np.abs(rows - cr) + np.abs(cols - cc)))
    return np.stack(feats, axis=-1)


def parse_belief(spec, n_actions: int = 4) -> tuple[str, np.ndarray | None, tuple[int, ...] | None]:
    """Turn a belief given by name, permutation or tensor into ``(name, tensor, perm)``.

    Accepted: a name in :data:`NAMED_BELIEFS`; a comma-separated permutation such as
    ``"1,0,3,2"`` or a sequence of ints; a path to a ``.npy`` file or an array holding
    an ``[S, A, S]`` tensor.

    Raises:
        ValueError: unknown name, a list that is not a permutation of the actions, or
            an unreadable tensor.
    """
    if isinstance(spec, np.ndarray) or hasattr(spec, "shape"):
        return "tensor", np.asarray(spec), None
    if isinstance(spec, str):
        if spec in NAMED_BELIEFS:
            return spec, None, NAMED_BELIEFS[spec]
        if spec.endswith(".npy"):
            path = Path(spec)
            if not path.is_file():
                raise ValueError(f"belief file {spec!r} does not exist")
            return path.stem, np.load(path), None
        try:
            perm = tuple(int(x) for x in spec.split(","))
        except ValueError:
            raise ValueError(
                f"unknown belief {spec!r}: use one of {sorted(NAMED_BELIEFS)}, an action "
                "permutation such as 1,0,3,2, or a .npy file with an [S, A, S] tensor"
            ) from None
    else:
        perm = tuple(int(x) for x in spec)
    if sorted(perm) != list(range(n_actions)):
        raise ValueError(f"belief {','.join(map(str, perm))} is not a permutation of the actions 0..{n_actions - 1}")
    name = next((k for k, v in NAMED_BELIEFS.items() if v == perm), "perm-" + "".join(map(str, perm)))
    return name, None, perm


def _human_tensor(true_t: np.ndarray, tensor, perm) -> np.ndarray:
    if perm is not None:
        return true_t[:, list(perm), :]
    tensor = check_transitions(tensor, name="belief tensor")
    if tensor.shape != true_t.shape:
        raise ValueError(f"belief tensor has shape {tensor.shape}, the world needs {true_t.shape}")
    return tensor


def informative_pairs(size: int, true_t: np.ndarray, human_t: np.ndarray, weights=(5.0, -5.0), discount=0.9):
    """Corner pairs ``(reward, penalty)`` for which the belief misleads an unaware learner.

    The person's greedy actions under their belief, executed by the real robot, move
    it down the reward gradient (mean one-step reward change below zero): a learner
    that assumes the true dynamics then infers the wrong reward. Returns the most
    misleading pairs (within half of the strongest effect); empty when none misleads.
    Under ``reversed`` these are the pairs in one column, under ``rotated`` the
    anti-diagonal (SPEC §3.1).
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
        belief: see :func:`parse_belief`.
        seed: picks the corner pair among the informative ones for this belief (all
            pairs when none is informative) unless ``corners`` is given.
        corners: ``(reward_corner, penalty_corner)`` as indices into :data:`CORNERS`.
        weights: reward weights of the two corner features.
        slip: probability of an unintended move.
        discount: ``λ``.
    """
    if size < 2:
        raise ValueError(f"grid size must be at least 2, got {size}")
    true_t = moves_to_transitions(true_move_probs(slip), size)
    name, tensor, perm = parse_belief(belief)
    human_t = _human_tensor(true_t, tensor, perm)
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
