import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.models import dirichlet
from mindgap.models.belief import factored


def tiny():
    # 3 states, 2 actions; factor 0 governs (0, 0) and (1, 0): move right or stay; the rest is fixed
    factor = np.array([[0, -1], [0, -1], [-1, -1]])
    targets = np.array([[[1, 0], [0, 0]], [[2, 1], [2, 2]], [[2, 2], [0, 0]]])
    return factored(factor, targets, [2])


def test_factored_space_expands_and_its_fixed_factor_is_a_point_mass():
    space = tiny()
    theta = jnp.asarray([[0.3, 0.7], [1.0, 0.0]])
    t = np.asarray(space.to_transitions(theta))
    np.testing.assert_allclose(t.sum(-1), 1.0, atol=1e-6)
    np.testing.assert_allclose(t[0, 0], [0.7, 0.3, 0.0])
    np.testing.assert_allclose(t[1, 0], [0.0, 0.7, 0.3])
    np.testing.assert_allclose(t[2, 1], [1.0, 0.0, 0.0])
    alpha = jnp.asarray([[2.0, 5.0], [3.0, 1.0]])
    # the fixed row contributes nothing to the ELBO's belief terms and always samples probability 1
    assert float(dirichlet.entropy(alpha, space.mask)[1]) == 0.0
    assert float(dirichlet.cross_entropy_term(alpha, jnp.ones_like(alpha), space.mask)[1]) == 0.0
    np.testing.assert_allclose(dirichlet.mean(alpha, space.mask)[1], [1.0, 0.0])
    np.testing.assert_allclose(dirichlet.score(jnp.zeros((2, 2)), alpha, space.mask)[1], 0.0)  # never moved


@pytest.mark.parametrize(
    "factor,targets,n,msg",
    [
        (np.zeros((3, 2)), np.zeros((3, 3, 2)), [2], "do not match"),
        (np.full((3, 2), 2), np.zeros((3, 2, 2)), [2], "factor ids"),
        (np.zeros((3, 2)), np.zeros((3, 2, 2)), [3], "outcomes"),
        (np.full((3, 2), -1), np.zeros((3, 2, 2)), [2], "govern no"),
        (np.zeros((3, 2)), np.full((3, 2, 2), 3), [2], "state ids"),
    ],
)
def test_bad_factored_spaces_are_named(factor, targets, n, msg):
    with pytest.raises(ValueError, match=msg):
        factored(factor, targets, n)
