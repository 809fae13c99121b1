import numpy as np
import pytest

from mindgap.data.demos import RatedDemonstrations, make_demonstrations
from mindgap.feedback.normalise import normalise_ratings
from mindgap.feedback.ratings_file import (
    ParticipantRatings,
    RatingsFileError,
    read_participant_ratings,
    read_ratings,
    write_participant_ratings,
)

CATALOGUE = {"walk": ((0, 1), (1, 1)), "wait": ((2,), (0,))}
HEAD = "participant,robot,demo,step,state,action,rating,q1,q2\n"


def person(pid, ratings, robot="mobile", answers=None):
    demos = make_demonstrations(
        [[0, 1], [2, 0]], [[1, 1], [0, 0]], [[True, True], [True, False]], n_states=3, n_actions=2
    )
    return ParticipantRatings(
        pid, RatedDemonstrations(demos, np.asarray(ratings)), ("walk", "wait"), answers or {}, robot
    )


def read(path, **kw):
    return read_participant_ratings(
        path, n_states=3, n_actions=2, catalogue=CATALOGUE, robots=("mobile", "humanoid"), **kw
    )


def test_round_trip_with_participants_and_answers(tmp_path):
    path = tmp_path / "study.csv"
    people = [person("ann", [7.0, 2.5], "mobile", {"q1": 2, "q2": 5}), person("bob", [3.0, 9.0], "humanoid", {"q1": 4})]
    write_participant_ratings(path, people)
    back = read(path)
    assert [p.participant for p in back] == ["ann", "bob"]
    assert back[0].answers == {"q1": 2, "q2": 5} and back[1].answers == {"q1": 4}  # q2 left blank by bob
    assert [p.robot for p in back] == ["mobile", "humanoid"]
    for a, b in zip(people, back):
        assert b.demos == a.demos
        np.testing.assert_allclose(b.rated.ratings, a.rated.ratings)
        np.testing.assert_array_equal(b.rated.demos.mask, a.rated.demos.mask)
    # the single-person reader pools every row: two people's ratings of one demonstration conflict there
    with pytest.raises(RatingsFileError, match="two ratings"):
        read_ratings(path, n_states=3, n_actions=2)


def test_a_file_without_participant_column_is_one_person(tmp_path):
    path = tmp_path / "alice.csv"
    path.write_text("demo,step,state,action,rating\nwalk,0,0,1,6\nwalk,1,1,1,6\nwait,0,2,0,1\n")
    (p,) = read(path)
    assert p.participant == "alice" and p.robot is None and p.answers == {}
    np.testing.assert_allclose(p.rated.ratings, [6.0, 1.0])


@pytest.mark.parametrize(
    "rows,msg",
    [
        (",mobile,walk,0,0,1,5,3,3\n", "line 2: missing participant"),
        ("a,mobile,walk,0,0,1,11,3,3\n", "outside"),
        ("a,mobile,walk,0,0,1,-0.5,3,3\n", "outside"),
        ("a,mobile,run,0,0,1,5,3,3\n", "unknown demonstration 'run'"),
        ("a,mobile,walk,0,0,1,5,3,3\na,mobile,walk,1,2,1,5,3,3\n", "step 1"),
        ("a,mobile,walk,0,0,1,5,3,3\n", "has 1 steps; the study's has 2"),
        ("a,mobile,wait,0,2,0,5,6,3\n", "q1='6'"),
        ("a,mobile,wait,0,2,0,5,x,3\n", "not an integer"),
        ("a,mobile,wait,0,2,0,5,3,3\na,mobile,walk,0,0,1,4,2,3\n", "two answers to q1"),
        ("a,drone,wait,0,2,0,5,3,3\n", "unknown robot"),
        ("a,mobile,wait,0,2,0,5,3,3\na,humanoid,walk,0,0,1,4,3,3\n", "two robots"),
        ("a,mobile,wait,0,2,0,5,3,3\na,mobile,wait,0,2,0,4,3,3\n", "two ratings"),
    ],
)
def test_malformed_study_files_are_named(tmp_path, rows, msg):
    path = tmp_path / "bad.csv"
    path.write_text(HEAD + rows)
    with pytest.raises(RatingsFileError, match=msg):
        read(path)


def test_ratings_of_two_people_for_one_demo_are_not_a_conflict(tmp_path):
    path = tmp_path / "two.csv"
    path.write_text(HEAD + "a,mobile,wait,0,2,0,5,3,3\nb,mobile,wait,0,2,0,9,3,3\n")
    assert [float(p.rated.ratings[0]) for p in read(path)] == [5.0, 9.0]


def test_minmax_normalisation():
    np.testing.assert_allclose(normalise_ratings([2.0, 4.0, 6.0]), [0.0, 5.0, 10.0])
    np.testing.assert_allclose(normalise_ratings([2.0, 4.0], "none"), [2.0, 4.0])
    with pytest.raises(ValueError, match="same rating"):
        normalise_ratings([3.0, 3.0])
    with pytest.raises(ValueError, match="unknown normalisation"):
        normalise_ratings([1.0, 2.0], "zscore")
