from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.algorithms.gerel import GeReLConfig, RatingData, fit_gerel
from mindgap.algorithms.gerel_model import believed_q_values, pathwise_elbo, score_gradient
from mindgap.data.demos import RatedDemonstrations
from mindgap.envs.coffee import factored_layout, make_coffee
from mindgap.envs.grid import move_targets
from mindgap.feedback.demos import random_demonstrations
from mindgap.metrics import all_metrics
from mindgap.models.belief import factored, per_state_action, tied
from mindgap.planning import q_values
from mindgap.planning.grid_task import make_grid
from mindgap.teachers.rating import RatingTeacher


def rated_grid(size, belief, n, length=10, seed=0, corners=None):
    task = make_grid(size, belief, seed=seed, corners=corners)
    k1, k2 = jax.random.split(rng.key(seed))
    teacher = RatingTeacher(task.mdp, task.true_weights, task.human_transitions)
    return task, teacher.rate(k2, random_demonstrations(k1, task.mdp, n, length))


def test_score_and_pathwise_gradients_agree_in_expectation():
    task, rated = rated_grid(3, "reversed", 30, length=4, corners=(0, 2))
    space = tied(move_targets(3), 4)
    data = RatingData.build(task.mdp, space, rated)
    cfg = GeReLConfig(n_samples=64)
    mu = jnp.asarray([1.0, -1.0])
    alpha = jnp.asarray([[3.0, 1.0, 2.0, 1.5, 1.0]] * 4) * jnp.arange(1.0, 5.0)[:, None]
    keys = jax.random.split(rng.key(5), 400)
    # jitted: one program each, where vmapped op by op every operation compiled its own
    path = jax.jit(jax.vmap(lambda k: jax.grad(pathwise_elbo, argnums=(0, 1))(mu, alpha, k, data, cfg)))(keys)
    score = jax.jit(jax.vmap(lambda k: score_gradient(mu, alpha, k, data, cfg)[1:]))(keys)
    for p, s in zip(path, score, strict=True):
        p_mean, s_mean = np.asarray(p.mean(0)), np.asarray(s.mean(0))
        s_err = np.asarray(s.std(0)) / np.sqrt(len(keys))  # standard error of the noisier estimator
        assert np.all(np.abs(p_mean - s_mean) < 4 * s_err + 0.05 * np.abs(p_mean).max())
        assert np.linalg.norm(p_mean) > 0.1  # a real gradient, not zero against zero


def world_and_space(param):
    """A small world, rated random demonstrations and a belief space of the given kind."""
    if param == "factored":
        mdp = make_coffee("mobile")
        rated = RatedDemonstrations(random_demonstrations(rng.key(0), mdp, 20, 4), jnp.full(20, 5.0))
        return mdp, rated, factored(*factored_layout(("spill",)))
    task, rated = rated_grid(3, "reversed", 20, length=4, corners=(0, 2))
    if param == "tied":
        return task.mdp, rated, tied(move_targets(3), 4)
    return task.mdp, rated, per_state_action(task.mdp.transitions, full=param == "full")


@pytest.mark.parametrize("param", ["tied", "per-sa", "full", "factored", "frozen"])
def test_believed_q_values_and_gradients_match_dense_value_iteration(param):
    # Each belief parameterisation plans on its successor form (full: dense); the Q-values
    # and their gradients in (w, θ) are those of dense value iteration on T(θ), converged.
    mdp, rated, space = world_and_space(param)
    cfg = GeReLConfig(n_samples=2, vi_iterations=400, freeze_belief=param == "frozen")
    with jax.enable_x64(True):
        mdp = jax.tree_util.tree_map(lambda x: jnp.asarray(x, jnp.float64), mdp)
        data = RatingData.build(mdp, space, rated)
        k1, k2, k3 = jax.random.split(rng.key(3), 3)
        w = jax.random.normal(k1, (2, mdp.n_features), jnp.float64)
        alpha = jnp.where(space.mask, 1.0, 1e-3).astype(jnp.float64)
        theta = jnp.where(space.mask, jax.random.dirichlet(k2, alpha, (2, alpha.shape[0])), 0.0)
        weights = jax.random.normal(k3, (2, mdp.n_states, mdp.n_actions), jnp.float64)

        def ours(w, theta):
            return (believed_q_values(w, None if cfg.freeze_belief else theta, data, cfg) * weights).sum()

        def dense(w, theta):
            t = mdp.transitions if cfg.freeze_belief else space.to_transitions(theta)
            return (q_values(t, mdp.reward(w), mdp.discount, 400) * weights).sum()

        np.testing.assert_allclose(ours(w, theta), dense(w, theta), rtol=1e-10)
        grads = jax.grad(ours, (0, 1))(w, theta)
        for a, b in zip(grads, jax.grad(dense, (0, 1))(w, theta), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8)
        assert np.abs(grads[0]).max() > 0.1


@pytest.fixture(scope="module")
def small_fit():
    task, rated = rated_grid(4, "reversed", 1500, corners=(0, 2))
    space = tied(move_targets(4), 4)
    cfg = GeReLConfig(restarts=16, keep=4, screen_iter=300, max_iter=800)
    res = fit_gerel(task.mdp, rated, space, cfg, key=rng.key(1), progress=False)
    minus = fit_gerel(
        task.mdp, rated, space, replace(cfg, freeze_belief=True, restarts=4, keep=4), key=rng.key(1), progress=False
    )
    return task, res, minus


def test_gerel_recovers_reward_and_belief_on_a_small_grid(small_fit):
    task, res, _ = small_fit
    m = all_metrics(task.mdp, res.mu, res.transitions, task.true_weights, task.human_transitions)
    assert m["corr_R"] > 0.95
    assert m["d_Theta"] < 0.2
    assert m["d_pi"] < 0.1
    # the believed effect of Up is "down"
    theta = res.alpha / res.alpha.sum(-1, keepdims=True)
    assert theta[0].argmax() == 1 and theta[0, 1] > 0.7


def test_gerel_minus_learns_the_opposite_reward(small_fit):
    task, res, minus = small_fit
    m = all_metrics(task.mdp, minus.mu, minus.transitions, task.true_weights, task.human_transitions)
    assert m["corr_R"] < 0
    np.testing.assert_array_equal(minus.transitions, task.mdp.transitions)
    # and its ELBO is worse: the biased belief explains the ratings better
    assert res.elbo[res.best] > minus.elbo[minus.best]


def test_curves_and_restart_record(small_fit):
    _, res, _ = small_fit
    iters, mus, ts = res.curve()
    assert iters[0] == 0 and iters[-1] == res.run.iterations and len(mus) == len(ts) == len(iters)
    assert len(res.restart_estimates()) == 16


def test_score_estimator_runs_and_improves_the_elbo():
    task, rated = rated_grid(3, "reversed", 200, corners=(0, 2))
    cfg = GeReLConfig(estimator="score", n_samples=32, restarts=2, keep=2, max_iter=200, check_every=50)
    res = fit_gerel(task.mdp, rated, tied(move_targets(3), 4), cfg, key=rng.key(2), progress=False)
    elbos = np.array([h[3] for h in res.run.history[1:]])
    assert np.all(elbos[-1] > elbos[0])
    assert np.all(res.alpha > 0)


def test_bad_config_and_ratings():
    with pytest.raises(ValueError, match="estimator"):
        GeReLConfig(estimator="magic")
    with pytest.raises(ValueError, match="restarts"):
        GeReLConfig(restarts=0)
    task, rated = rated_grid(3, "reversed", 10)
    with pytest.raises(ValueError, match="ratings must lie"):
        fit_gerel(task.mdp, rated._replace(ratings=rated.ratings + 20), tied(move_targets(3), 4), key=rng.key(0))
