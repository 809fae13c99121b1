import jax.numpy as jnp
import numpy as np

from mindgap.envs.grid import move_targets
from mindgap.models.belief import per_state_action, tied
from mindgap.planning.grid_task import make_grid


def test_spaces_expand_to_stochastic_tensors_and_represent_the_truth():
    task = make_grid(4, "reversed", seed=0)
    for space in (
        tied(move_targets(4), 4),
        per_state_action(task.mdp.transitions),
        per_state_action(task.mdp.transitions, full=True),
    ):
        theta = space.from_transitions(task.human_transitions)
        t = space.to_transitions(jnp.asarray(theta))
        np.testing.assert_allclose(t.sum(-1), 1.0, atol=1e-5)
        np.testing.assert_allclose(t, task.human_transitions, atol=1e-5)


def test_tied_factors_read_the_believed_moves():
    task = make_grid(5, "reversed", seed=0)
    theta = tied(move_targets(5), 4).from_transitions(task.human_transitions)
    # the person believes Up (action 0) mostly moves down (move 1), and Down mostly up
    assert theta[0].argmax() == 1 and theta[1].argmax() == 0
    np.testing.assert_allclose(theta[0, 1], 0.9, atol=1e-6)


def test_per_sa_support_is_one_step_reachable_plus_stay():
    task = make_grid(3, "true", seed=0)
    space = per_state_action(task.mdp.transitions)
    centre = 4
    support = set(np.asarray(space.targets[centre, 0])[np.asarray(space.mask[centre * 4])].tolist())
    assert support == {1, 3, 4, 5, 7}
    corner = 0
    assert set(np.asarray(space.targets[corner, 0])[np.asarray(space.mask[corner * 4])].tolist()) == {0, 1, 3}
