import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.planning import boltzmann_policy, q_values, soft_q_values, state_values
from mindgap.planning.value_iteration import _sweeps


def two_state_mdp():
    """States 0, 1; action 0 stays, action 1 switches; R = [1, 0]; λ = 0.5."""
    t = np.zeros((2, 2, 2), np.float32)
    t[0, 0, 0] = t[1, 0, 1] = 1.0
    t[0, 1, 1] = t[1, 1, 0] = 1.0
    return jnp.asarray(t), jnp.asarray([1.0, 0.0]), 0.5


def test_value_iteration_matches_hand_solution():
    # By hand: V(0) = 1 / (1 - 0.5) = 2 (stay forever); V(1) = 0 + 0.5 * V(0) = 1 (switch).
    # Q(0, stay) = 1 + 0.5 * 2, Q(0, switch) = 1 + 0.5 * 1, Q(1, stay) = 0.5 * 1, Q(1, switch) = 0.5 * 2.
    t, r, g = two_state_mdp()
    q = q_values(t, r, g, 200)
    np.testing.assert_allclose(q, [[2.0, 1.5], [0.5, 1.0]], atol=1e-5)


def random_mdp(key, s=6, a=3, batch=()):
    k1, k2 = jax.random.split(key)
    t = jax.random.dirichlet(k1, jnp.ones(s), batch + (s, a))
    r = jax.random.normal(k2, batch + (s,))
    return t, r


def naive_soft_values(t, r, g, n_iter):
    t, r = np.asarray(t, np.float64), np.asarray(r, np.float64)
    s, a, _ = t.shape
    v = np.zeros(s)
    for _ in range(n_iter):
        q = np.array([[r[i] + g * sum(t[i, j, k] * v[k] for k in range(s)) for j in range(a)] for i in range(s)])
        v = np.log(np.exp(q).sum(1))
    return v


def test_soft_value_iteration_matches_naive_loop():
    t, r = random_mdp(jax.random.key(1))
    v = state_values(t, r, 0.9, 300, True)
    np.testing.assert_allclose(v, naive_soft_values(t, r, 0.9, 300), rtol=1e-4, atol=1e-4)
    q = soft_q_values(t, r, 0.9, 300)
    np.testing.assert_allclose(jax.nn.logsumexp(q, -1), v, atol=1e-4)


@pytest.mark.parametrize("soft", [False, True])
def test_implicit_gradient_matches_unrolled(soft):
    t, r = random_mdp(jax.random.key(2))

    def implicit(t, r):
        return (state_values(t, r, 0.9, 300, soft) * jnp.arange(6.0)).sum()

    def unrolled(t, r):
        return (_sweeps(t, r, 0.9, 300, soft) * jnp.arange(6.0)).sum()

    gi = jax.grad(implicit, argnums=(0, 1))(t, r)
    gu = jax.grad(unrolled, argnums=(0, 1))(t, r)
    for a, b in zip(gi, gu, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-3)


def test_batched_equals_one_by_one():
    t, r = random_mdp(jax.random.key(3), batch=(4,))
    batched = boltzmann_policy(t, r, 0.9, 2.0)
    for i in range(4):
        np.testing.assert_allclose(batched[i], boltzmann_policy(t[i], r[i], 0.9, 2.0), atol=1e-5)
    # one shared world, many rewards: leading axes broadcast
    shared = q_values(t[0], r, 0.9)
    np.testing.assert_allclose(shared[2], q_values(t[0], r[2], 0.9), atol=1e-5)
    # and it vmaps
    vm = jax.vmap(lambda t, r: q_values(t, r, 0.9))(t, r)
    np.testing.assert_allclose(vm, q_values(t, r, 0.9), atol=1e-5)


def test_gradient_of_shared_transitions_sums_over_batch():
    t, r = random_mdp(jax.random.key(4), batch=(3,))
    g_batched = jax.grad(lambda t0: q_values(t0, r, 0.9).sum())(t[0])
    g_loop = sum(jax.grad(lambda t0, ri=ri: q_values(t0, ri, 0.9).sum())(t[0]) for ri in r)
    np.testing.assert_allclose(g_batched, g_loop, rtol=1e-4, atol=1e-4)
