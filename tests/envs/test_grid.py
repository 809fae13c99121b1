import numpy as np
import pytest

from mindgap.envs.grid import (
    NAMED_BELIEFS,
    moves_to_transitions,
    parse_belief,
    true_move_probs,
)
from mindgap.planning.grid_task import informative_pairs, make_grid


def test_true_dynamics_are_as_specified():
    task = make_grid(7, "true", seed=0)
    t = np.asarray(task.mdp.transitions)
    np.testing.assert_allclose(t.sum(-1), 1.0, atol=1e-6)
    centre = 3 * 7 + 3
    assert np.isclose(t[centre, 0, centre - 7], 0.9)  # Up
    assert np.isclose(t[centre, 0, centre + 7], 0.1 / 3)  # Up slips down
    assert np.isclose(t[centre, 3, centre + 1], 0.9)  # Right
    assert t[centre, 0, centre] == 0.0
    # the top-left corner: Up and Left hit walls and stay
    assert np.isclose(t[0, 0, 0], 0.9 + 0.1 / 3)


@pytest.mark.parametrize("name", ["reversed", "rotated"])
def test_named_beliefs_permute_actions(name):
    task = make_grid(5, name, seed=1)
    perm = NAMED_BELIEFS[name]
    t = np.asarray(task.mdp.transitions)
    np.testing.assert_allclose(task.human_transitions, t[:, list(perm)])


def test_informative_pairs_follow_the_spec():
    t = moves_to_transitions(true_move_probs(), 7)
    col = lambda c: c % 2  # noqa: E731 - corner index -> column (0 left, 1 right)
    rev = informative_pairs(7, t, t[:, [1, 0, 2, 3]])
    assert rev and all(col(i) == col(j) for i, j in rev)  # reward and penalty in one column
    rot = informative_pairs(7, t, t[:, [2, 3, 0, 1]])
    assert sorted(rot) == [(1, 2), (2, 1)]  # the anti-diagonal
    assert informative_pairs(7, t, t) == []


def test_any_permutation_and_size():
    task = make_grid(11, "1,0,3,2", seed=3)
    assert task.mdp.n_states == 121 and task.belief == "perm-1032"
    task = make_grid(4, [3, 2, 1, 0], seed=0, corners=(0, 3))
    assert task.corners == (0, 3)


@pytest.mark.parametrize(
    "spec,msg",
    [
        ("1,1,2,3", "not a permutation"),
        ("0,1,2", "not a permutation"),
        ("sideways", "unknown belief"),
        ("missing.npy", "does not exist"),
    ],
)
def test_bad_beliefs_are_named(spec, msg):
    with pytest.raises(ValueError, match=msg):
        parse_belief(spec)


def test_bad_tensor_belief():
    with pytest.raises(ValueError, match="sums to"):
        make_grid(3, np.ones((9, 4, 9)), seed=0)
    with pytest.raises(ValueError, match="corners"):
        make_grid(3, "true", corners=(1, 1))
