"""The restart loop shared by the rating-based learners: screening keeps the best and compiles one chunk."""

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.algorithms._restarts import _compiled_chunk, _in_groups, run_restarts


def _step(state, key, data):
    """Noisy gradient ascent on −(x − target)²: restart i settles at its own start's basin value."""
    x = state + 0.1 * (data - state) + 0.01 * jax.random.normal(key, state.shape)
    return x, -jnp.sum((x - data) ** 2) - jnp.sum(state**2)


def test_groups_give_the_results_of_one_call():
    chunk = _compiled_chunk(_step)
    states = jnp.arange(10.0).reshape(5, 2)
    keys = jax.random.split(jax.random.key(0), (5, 7))
    whole = chunk(states, keys, jnp.ones(2))
    for size in (2, 3, 5):  # padded, padded, one call
        grouped = _in_groups(chunk, states, keys, jnp.ones(2), size)
        np.testing.assert_allclose(np.asarray(grouped[0]), np.asarray(whole[0]), rtol=1e-6)
        np.testing.assert_allclose(np.asarray(grouped[1]), np.asarray(whole[1]), rtol=1e-6)


def test_screening_keeps_the_best_and_compiles_one_chunk():
    def step(state, key, data):  # a step of its own, so that its chunk's compiled programs are this test's
        return _step(state, key, data)

    init = jnp.asarray([[3.0, 0.0], [0.1, 0.0], [-2.0, 0.0], [0.0, 0.2], [5.0, 5.0]])
    run = run_restarts(
        step, init, jax.random.key(1), jnp.zeros(2), max_iter=100, check_every=10, tol=0.0, n_obs=1,
        progress=False, keep=2, screen_iter=20,
    )  # fmt: skip
    assert sorted(run.ids.tolist()) == [1, 3]  # the two starts nearest the optimum survive
    assert set(run.dropped) == {0, 2, 4} and run.iterations == 100
    assert _compiled_chunk(step)._cache_size() == 1  # 5 restarts screened in groups of 2: the survivors' program
