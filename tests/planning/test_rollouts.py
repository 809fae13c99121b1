import jax.numpy as jnp
import numpy as np

from mindgap import rng
from mindgap.envs.tabular import rollout
from mindgap.planning import state_visitation


def test_rollouts_follow_policy_and_dynamics():
    # deterministic cycle 0 -> 1 -> 2 -> 0 under action 1; action 0 stays
    t = np.zeros((3, 2, 3), np.float32)
    for s in range(3):
        t[s, 0, s] = 1.0
        t[s, 1, (s + 1) % 3] = 1.0
    policy = jnp.asarray([[0.0, 1.0]] * 3)
    states, actions = rollout(rng.key(0), jnp.asarray(t), policy, jnp.asarray([1.0, 0, 0]), 5, 4)
    np.testing.assert_array_equal(states, np.tile([0, 1, 2, 0], (5, 1)))
    np.testing.assert_array_equal(actions, 1)


def test_state_visitation_counts_steps():
    t = jnp.full((4, 2, 4), 0.25)
    d = state_visitation(t, jnp.full((4, 2), 0.5), jnp.asarray([1.0, 0, 0, 0]), horizon=5)
    assert np.isclose(float(d.sum()), 5.0)
    np.testing.assert_allclose(d, [1 + 4 * 0.25, 1.0, 1.0, 1.0], atol=1e-6)
