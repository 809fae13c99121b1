import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.grid import move_targets
from mindgap.models.belief import per_state_action, tied
from mindgap.planning import q_values, sparse_q_values, sparse_state_values
from mindgap.planning.grid_task import make_grid
from mindgap.planning.sparse_value_iteration import adjoint_solve, sparse_form, sweeps_used


def test_two_state_mdp_matches_hand_solution():
    # States 0, 1; action 0 stays, action 1 switches; R = [1, 0]; λ = 0.5. By hand:
    # V(0) = 1 / (1 - 0.5) = 2 (stay forever); V(1) = 0 + 0.5 * V(0) = 1 (switch).
    t = np.zeros((2, 2, 2), np.float32)
    t[0, 0, 0] = t[1, 0, 1] = t[0, 1, 1] = t[1, 1, 0] = 1.0
    probs, successors = sparse_form(t)
    assert probs.shape == (2, 2, 2) and successors.shape == (2, 2)
    q = sparse_q_values(probs, successors, jnp.asarray([1.0, 0.0]), 0.5, 200)
    np.testing.assert_allclose(q, [[2.0, 1.5], [0.5, 1.0]], atol=1e-6)


def test_sparse_form_keeps_every_transition():
    t = np.asarray(make_grid(4, "reversed", seed=0).human_transitions)
    probs, successors = sparse_form(t)
    assert probs.shape == (16, 4, 4)  # the four neighbours; walls merge some into the cell itself
    dense = np.zeros_like(t)
    np.add.at(dense, (np.arange(16)[:, None, None], np.arange(4)[None, :, None], successors[:, None]), probs)
    np.testing.assert_array_equal(dense, t)


def random_belief(key, size=3, batch=(2,), concentration=1.0):
    """Tied belief factors ``θ [*batch, 4, 5]`` and rewards ``[*batch, S]`` on a grid."""
    k1, k2 = jax.random.split(key)
    theta = jax.random.dirichlet(k1, jnp.full(5, concentration), batch + (4,))
    reward = 3.0 * jax.random.normal(k2, batch + (size * size,))
    return tied(move_targets(size), 4), theta, reward


@pytest.mark.parametrize("form", ["tied", "per-sa", "by action"])
def test_matches_dense_value_iteration(form):
    space, theta, reward = random_belief(jax.random.key(0), size=4)
    dense = q_values(space.to_transitions(theta), reward, 0.9, 1000)
    probs, successors = space.successor_form(theta)  # [2, 1, A, K] on [S, K]
    if form == "per-sa":
        probs = jnp.broadcast_to(probs, (2, 16, 4, 5))
    elif form == "by action":
        probs, successors = space.to_sparse(theta), space.targets  # [S, A, K] successors
    np.testing.assert_allclose(sparse_q_values(probs, successors, reward, 0.9, 1000), dense, atol=1e-4)


def test_per_state_action_belief_matches_dense():
    task = make_grid(3, "rotated", seed=0)
    space = per_state_action(task.mdp.transitions)
    alpha = jnp.where(space.mask, 1.0, 1e-3)
    theta = jnp.where(space.mask, jax.random.dirichlet(jax.random.key(1), alpha), 0.0)
    reward = task.mdp.reward(task.true_weights)
    dense = q_values(space.to_transitions(theta), reward, 0.9, 1000)
    probs, successors = space.successor_form(theta)
    assert successors.shape == (9, space.mask.shape[1])
    np.testing.assert_allclose(sparse_q_values(probs, successors, reward, 0.9, 1000), dense, atol=1e-4)


@pytest.mark.parametrize("n_iter", [5, 20, 60])
def test_stop_is_certified_and_never_later_than_the_plain_sweeps(n_iter):
    # The answer lies within λ^N ‖R‖∞ / (1 − λ) of V*, the a-priori error of N plain
    # sweeps from zero, and takes at most N sweeps.
    with jax.enable_x64(True):
        space, theta, reward = random_belief(jax.random.key(2), size=5, batch=(8,), concentration=0.5)
        theta, reward = theta.astype(jnp.float64), reward.astype(jnp.float64)
        probs, successors = space.successor_form(theta)
        exact = sparse_state_values(probs, successors, reward, 0.9, 2000)
        v = sparse_state_values(probs, successors, reward, 0.9, n_iter)
        bound = 0.9**n_iter * np.abs(reward).max(-1) / 0.1
        err = np.abs(v - exact).max(-1)
        assert np.all(err <= bound * (1 + 1e-9))
        assert err.max() > 1e-3 * bound.max()  # not trivially exact: the bound is what is checked
        assert int(sweeps_used(probs, successors, reward, 0.9, n_iter)) <= n_iter


def test_fewer_sweeps_than_plain_value_iteration_on_a_concentrated_belief():
    task = make_grid(7, "reversed", seed=0)
    space = tied(move_targets(7), 4)
    theta = jnp.asarray(space.from_transitions(task.human_transitions))
    probs, successors = space.successor_form(theta)
    reward = task.mdp.reward(task.true_weights)
    assert int(sweeps_used(probs, successors, reward, 0.9, 100)) < 50


def scalar_of_q(q_fn, weights):
    return lambda theta, reward: (q_fn(theta, reward) * weights).sum()


def test_implicit_gradient_matches_the_dense_solver():
    # The same fixed point and the same implicit gradient as planning.q_values, converged.
    with jax.enable_x64(True):
        space, theta, reward = random_belief(jax.random.key(3), size=3)
        theta, reward = theta.astype(jnp.float64), reward.astype(jnp.float64)
        weights = jax.random.normal(jax.random.key(4), (2, 9, 4), jnp.float64)
        sparse = scalar_of_q(lambda th, r: sparse_q_values(*space.successor_form(th), r, 0.9, 400), weights)
        dense = scalar_of_q(lambda th, r: q_values(space.to_transitions(th), r, 0.9, 400), weights)
        for a, b in zip(jax.grad(sparse, (0, 1))(theta, reward), jax.grad(dense, (0, 1))(theta, reward), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
        assert np.abs(jax.grad(sparse)(theta, reward)).max() > 1.0


def test_implicit_gradient_matches_finite_differences():
    with jax.enable_x64(True):
        space, theta, reward = random_belief(jax.random.key(5), size=3)
        theta, reward = theta.astype(jnp.float64), reward.astype(jnp.float64)
        weights = jax.random.normal(jax.random.key(6), (2, 9, 4), jnp.float64)

        @jax.jit
        def f(theta, reward, discount):
            return (sparse_q_values(*space.successor_form(theta), reward, discount, 400) * weights).sum()

        args = (theta, reward, jnp.asarray(0.9, jnp.float64))
        grads = jax.grad(f, (0, 1, 2))(*args)
        eps = 1e-6
        for arg, grad in enumerate(grads):
            fd = np.zeros(args[arg].shape)
            for idx in np.ndindex(fd.shape):
                e = jnp.zeros_like(args[arg]).at[idx].set(eps)
                hi = [x + e if i == arg else x for i, x in enumerate(args)]
                lo = [x - e if i == arg else x for i, x in enumerate(args)]
                fd[idx] = (f(*hi) - f(*lo)) / (2 * eps)
            np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6)


def test_gradient_at_the_default_accuracy_is_close_to_the_converged_one():
    space, theta, reward = random_belief(jax.random.key(7), size=4)
    weights = jax.random.normal(jax.random.key(8), (2, 16, 4))
    approx = jax.grad(scalar_of_q(lambda th, r: sparse_q_values(*space.successor_form(th), r, 0.9), weights), (0, 1))
    exact = jax.grad(scalar_of_q(lambda th, r: q_values(space.to_transitions(th), r, 0.9, 1000), weights), (0, 1))
    for a, b in zip(approx(theta, reward), exact(theta, reward), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-3 * np.abs(b).max())


def greedy_chain(key, size=3, batch=4):
    """A belief's greedy-policy weights ``w [A, K, S, B]`` on ``successors [S, K]``, and ``P_π [B, S, S]``."""
    k1, k2 = jax.random.split(key)
    space, theta, _ = random_belief(k1, size=size, batch=(batch,))
    theta = theta.astype(jnp.float64)
    probs, successors = space.successor_form(theta)  # [B, 1, A, K]
    n = size * size
    pi = jax.random.randint(k2, (batch, n), 0, 4)
    p = np.asarray(probs)[:, 0]  # [B, A, K]
    w = np.zeros((4, 5, n, batch))
    for b in range(batch):
        w[pi[b], :, np.arange(n), b] = p[b, pi[b]]
    t = np.asarray(space.to_transitions(theta))  # [B, S, A, S']
    chain = np.stack([t[b, np.arange(n), pi[b]] for b in range(batch)])
    return jnp.asarray(w), successors, chain


def test_adjoint_solve_matches_a_dense_solve():
    with jax.enable_x64(True):
        w, successors, chain = greedy_chain(jax.random.key(9))
        v_bar = np.asarray(jax.random.normal(jax.random.key(11), (9, 4), jnp.float64))
        u = adjoint_solve(w, successors, jnp.asarray(v_bar), 0.9, 400)
        exact = np.stack([np.linalg.solve(np.eye(9) - 0.9 * chain[b].T, v_bar[:, b]) for b in range(4)], -1)
        np.testing.assert_allclose(u, exact, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("n_iter", [5, 20, 60])
def test_adjoint_stop_is_certified(n_iter):
    # ‖u − u*‖₁ ≤ λ^N ‖V̄‖₁ / (1 − λ), whichever of its two estimates the solver returns.
    with jax.enable_x64(True):
        w, successors, chain = greedy_chain(jax.random.key(12), size=5, batch=8)
        v_bar = np.asarray(jax.random.normal(jax.random.key(13), (25, 8), jnp.float64))
        u = np.asarray(adjoint_solve(w, successors, jnp.asarray(v_bar), 0.9, n_iter))
        exact = np.stack([np.linalg.solve(np.eye(25) - 0.9 * chain[b].T, v_bar[:, b]) for b in range(8)], -1)
        err = np.abs(u - exact).sum(0)
        bound = 0.9**n_iter * np.abs(v_bar).sum(0) / 0.1
        assert np.all(err <= bound * (1 + 1e-9))
        assert err.max() > 1e-6 * bound.max()


def test_broadcasting_batching_and_vmap():
    space, theta, reward = random_belief(jax.random.key(12), size=3, batch=(3,))
    probs, successors = space.successor_form(theta)
    batched = sparse_q_values(probs, successors, reward, 0.9)
    one = jax.jit(lambda p, r: sparse_q_values(p, successors, r, 0.9))
    for i in range(3):
        np.testing.assert_allclose(batched[i], one(probs[i], reward[i]), atol=1e-5)
    # one belief, many rewards
    shared = sparse_q_values(probs[0], successors, reward, 0.9)
    np.testing.assert_allclose(shared[2], one(probs[0], reward[2]), atol=1e-5)
    vm = jax.vmap(lambda p, r: sparse_q_values(p, successors, r, 0.9))(probs, reward)
    np.testing.assert_allclose(vm, batched, atol=1e-5)
    g_vm = jax.vmap(jax.grad(lambda p, r: sparse_q_values(p, successors, r, 0.9).sum()))(probs, reward)
    g = jax.grad(lambda p: sparse_q_values(p, successors, reward, 0.9).sum())(probs)
    np.testing.assert_allclose(g_vm, g, rtol=1e-4, atol=1e-4)


def test_rejects_mismatched_shapes():
    space, theta, reward = random_belief(jax.random.key(13), size=3)
    probs, successors = space.successor_form(theta)
    with pytest.raises(ValueError, match="do not match"):
        sparse_q_values(probs, successors[:4], reward, 0.9)
    with pytest.raises(ValueError, match="successors must be"):
        sparse_q_values(probs, successors[..., None, None], reward, 0.9)
