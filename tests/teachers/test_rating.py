import jax.numpy as jnp
import numpy as np

from mindgap import rng
from mindgap.data.demos import Demonstrations
from mindgap.feedback.demos import random_demonstrations
from mindgap.planning.grid_task import make_grid
from mindgap.teachers.rating import RatingTeacher


def test_ratings_are_geometric_mean_of_policy_and_clipped():
    task = make_grid(7, "reversed", seed=0)
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    pi = np.asarray(teacher.policy())
    demos = Demonstrations(jnp.asarray([[0, 1, 2]]), jnp.asarray([[0, 1, 3]]), jnp.ones((1, 3), bool))
    expected = 10 * (pi[0, 0] * pi[1, 1] * pi[2, 3]) ** (1 / 3)
    np.testing.assert_allclose(teacher.mean_ratings(demos), [expected], rtol=1e-5)
    rated = teacher.rate(rng.key(0), random_demonstrations(rng.key(1), task.mdp, 2000, 10))
    r = np.asarray(rated.ratings)
    assert r.min() >= 0 and r.max() <= 10 and (r == 0).any()  # censored at 0


def test_random_demonstrations_are_weak_evidence():
    # noise-free ratings of random demonstrations average about 0.6–1.0
    task = make_grid(7, "reversed", seed=0)
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    mean = np.asarray(teacher.mean_ratings(random_demonstrations(rng.key(2), task.mdp, 5000, 10)))
    assert 0.5 < mean.mean() < 1.1
    assert 0.2 < mean.std() < 0.8
