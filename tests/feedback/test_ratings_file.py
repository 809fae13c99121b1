import numpy as np
import pytest

from mindgap import rng
from mindgap.feedback.demos import random_demonstrations
from mindgap.feedback.ratings_file import RatingsFileError, read_ratings, write_ratings
from mindgap.planning.grid_task import make_grid
from mindgap.teachers.rating import RatingTeacher


def test_round_trip(tmp_path):
    task = make_grid(5, "reversed", seed=0)
    rated = RatingTeacher(task.mdp, task.true_weights, task.human_transitions).rate(
        rng.key(0), random_demonstrations(rng.key(1), task.mdp, 20, 6)
    )
    path = tmp_path / "r.csv"
    write_ratings(path, rated)
    back = read_ratings(path, n_states=25, n_actions=4)
    np.testing.assert_array_equal(back.demos.states, rated.demos.states)
    np.testing.assert_array_equal(back.demos.actions, rated.demos.actions)
    np.testing.assert_allclose(back.ratings, rated.ratings, atol=1e-4)


def test_variable_lengths_and_unordered_rows(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("demo,step,state,action,rating,participant\na,1,5,2,3\nb,0,7,0,9.5,x\na,0,4,1,3,x\n")
    r = read_ratings(p, n_states=9, n_actions=4)
    np.testing.assert_array_equal(r.demos.states[0, :2], [4, 5])
    np.testing.assert_array_equal(r.demos.mask, [[True, True], [True, False]])
    np.testing.assert_allclose(r.ratings, [3.0, 9.5])


@pytest.mark.parametrize(
    "body,msg",
    [
        ("demo,step,state,action\n0,0,1,1\n", "missing column"),
        ("demo,step,state,action,rating\n0,0,1,1,11\n", "outside"),
        ("demo,step,state,action,rating\n0,0,1,1,-1\n", "outside"),
        ("demo,step,state,action,rating\n0,0,99,1,5\n", "unknown state id 99"),
        ("demo,step,state,action,rating\n0,0,1,7,5\n", "unknown action id 7"),
        ("demo,step,state,action,rating\n0,0,1,1,5\n0,1,2,1,6\n", "two ratings"),
        ("demo,step,state,action,rating\n0,0,1,1,5\n0,0,2,1,5\n", "repeats step"),
        ("demo,step,state,action,rating\n0,zero,1,1,5\n", "line 2"),
        ("demo,step,state,action,rating\n", "no rows"),
    ],
)
def test_malformed_files_are_named(tmp_path, body, msg):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    with pytest.raises(RatingsFileError, match=msg):
        read_ratings(p, n_states=9, n_actions=4)


def test_missing_file(tmp_path):
    with pytest.raises(RatingsFileError, match="does not exist"):
        read_ratings(tmp_path / "nope.csv", n_states=9, n_actions=4)
