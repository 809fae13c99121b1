"""The grid navigation domain of §2.3.1 (``grid7``) and its belief variants.

States are cells ``s = row * size + col`` with row 0 at the top. Actions are
0 Up, 1 Down, 2 Left, 3 Right. The robot makes the intended move with probability
0.9 and one of the other three moves uniformly otherwise; a move into the border
leaves the state unchanged. One reward cell and one penalty cell sit at two corners;
``φ_k(s) = 1 / (1 + manhattan(s, c_k))`` and ``R_H(s) = w · φ(s)``.

A belief is "the same world with other parameters": an action permutation
(``T_H[:, a] = T_A[:, perm[a]]``, i.e. the person thinks action ``a`` does what
``perm[a]`` really does) or any explicit ``[S, A, S]`` tensor.

Building a whole task (picking informative reward corners needs value iteration)
lives in :mod:`mindgap.planning.grid_task`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .tabular import check_transitions

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


def belief_transitions(true_t: np.ndarray, tensor, perm) -> np.ndarray:
    """``[S, A, S]`` dynamics the person believes, from :func:`parse_belief`'s output.

    Args:
        true_t: ``[S, A, S]`` true transitions.
        tensor: explicit belief tensor, used when ``perm`` is None.
        perm: action permutation; ``T_H[:, a] = T_A[:, perm[a]]``.

    Raises:
        ValueError: the tensor is not a valid transition tensor of the world's shape.
    """
    if perm is not None:
        return true_t[:, list(perm), :]
    tensor = check_transitions(tensor, name="belief tensor")
    if tensor.shape != true_t.shape:
        raise ValueError(f"belief tensor has shape {tensor.shape}, the world needs {true_t.shape}")
    return tensor
