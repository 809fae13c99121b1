import numpy as np

from mindgap import rng
from mindgap.algorithms.maxent_irl import fit_maxent_irl
from mindgap.algorithms.serd import SERDConfig, fit_serd
from mindgap.envs.grid import move_targets
from mindgap.feedback.demos import policy_demonstrations, random_demonstrations
from mindgap.metrics import reward_correlation
from mindgap.models.belief import tied
from mindgap.planning.grid_task import make_grid
from mindgap.teachers.rating import RatingTeacher


def test_maxent_irl_recovers_reward_under_a_correct_belief():
    task = make_grid(5, "true", seed=0, corners=(0, 3))
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    demos = policy_demonstrations(rng.key(0), task.mdp, teacher.policy(), 500, 10)
    res = fit_maxent_irl(task.mdp, demos, key=rng.key(1), progress=False)
    assert reward_correlation(task.mdp, res.weights, task.true_weights) > 0.9


def test_maxent_irl_is_misled_by_a_reversed_belief():
    task = make_grid(5, "reversed", seed=0, corners=(0, 2))
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    demos = policy_demonstrations(rng.key(0), task.mdp, teacher.policy(), 500, 10)
    res = fit_maxent_irl(task.mdp, demos, key=rng.key(1), progress=False)
    assert reward_correlation(task.mdp, res.weights, task.true_weights) < 0


def test_serd_fits_ratings_with_a_learned_belief():
    task = make_grid(4, "reversed", seed=0, corners=(0, 2))
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    rated = teacher.rate(rng.key(0), random_demonstrations(rng.key(1), task.mdp, 800, 10))
    cfg = SERDConfig(restarts=8, keep=2, screen_iter=200, max_iter=500)
    res = fit_serd(task.mdp, rated, tied(move_targets(4), 4), cfg, key=rng.key(2), progress=False)
    np.testing.assert_allclose(res.transitions.sum(-1), 1.0, atol=1e-5)
    assert np.isfinite(res.objective).all()
    assert reward_correlation(task.mdp, res.weights, task.true_weights) > 0.5
