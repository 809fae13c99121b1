"""Planning on a reward table: the world's own reward gives the world's plan; terminal values and policy values are exact."""

import jax.numpy as jnp
import numpy as np
from test_terrain_planning import CORRIDOR  # a straight corridor from the start to the goal

from mindgap.envs.terrain import world_from_dict
from mindgap.planning.reward_plan import plan_rewards, policy_values, state_id
from mindgap.planning.terrain import discretise, plan


def test_the_worlds_own_reward_gives_the_worlds_plan():
    w = world_from_dict(CORRIDOR)
    p = plan(w.params, n=2)
    own = plan_rewards(p.grid, p.grid.rewards, None, 0.99)
    np.testing.assert_allclose(np.asarray(own.q), np.asarray(p.q), atol=1e-3)
    # the plan's own value, evaluated as a fixed policy, is its optimum
    v = policy_values(p.grid, p.grid.rewards, own.policy, None, 0.99)
    np.testing.assert_allclose(np.asarray(v), np.asarray(own.q.max(-1)), atol=1e-3)


def test_terminal_values_and_a_policy_that_stays():
    w = world_from_dict(CORRIDOR)
    d = discretise(w.params, n=2)
    n, k = d.rewards.shape
    # a reward of −1 everywhere, the goal's sub-cells worth +50: the optimum walks right
    tv = jnp.where(d.terminal, 50.0, 0.0)
    own = plan_rewards(d, -jnp.ones((n, k)), tv, 0.9)
    start = state_id(d, jnp.array([1.5, 1.5]))
    right = int(jnp.argmax(d.actions[:, 0]))
    assert int(own.policy[start]) == right
    # every sub-cell that pushes into the west wall stays put at −1 a step: worth −1/(1 − γ) = −10
    west = int(jnp.argmin(d.actions[:, 0]))
    v = policy_values(d, -jnp.ones((n, k)), jnp.full(n, west), tv, 0.9)
    np.testing.assert_allclose(float(v[state_id(d, jnp.array([1.25, 1.25]))]), -10.0, atol=1e-2)
    assert np.asarray(v)[np.asarray(d.terminal)].min() == 50.0
