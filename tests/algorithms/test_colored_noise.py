"""Coloured exploration noise: its statistics, and how the SAC loop uses it."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.algorithms.colored_noise import colored_noise
from mindgap.algorithms.sac import SACConfig, sac_init
from mindgap.algorithms.sac_loop import loop_init, run_chunk
from mindgap.envs.terrain import world_from_dict
from mindgap.models.actor import sample_action


def _sequences(beta, length, n=3000):
    keys = jax.random.split(jax.random.key(0), n)
    return np.asarray(jax.vmap(lambda k: colored_noise(k, beta, length, 2))(keys))


def _lag1(x):
    return float(np.mean(x[:, 1:] * x[:, :-1]))


@pytest.mark.parametrize("length", [64, 51])
def test_every_step_is_unit_variance_and_colour_sets_the_correlation(length):
    lag1 = {}
    for beta in (0.0, 1.0, 2.0):
        x = _sequences(beta, length)
        assert x.shape == (3000, length, 2)
        # N(0, 1) at every step (3000 draws: standard error of a variance ≈ 0.026)
        np.testing.assert_allclose(x.var(axis=0), 1.0, atol=0.15)
        np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=0.15)
        lag1[beta] = _lag1(x)
    assert abs(lag1[0.0]) < 0.03  # white: independent steps
    assert 0.4 < lag1[1.0] < lag1[2.0] < 1.0  # pink, then red, hold a direction for longer
    # the two action dimensions are independent
    x = _sequences(1.0, length)
    assert abs(float(np.mean(x[..., 0] * x[..., 1]))) < 0.05


def test_rejects_too_short_sequences_and_negative_colours():
    with pytest.raises(ValueError, match="at least 2"):
        colored_noise(jax.random.key(0), 1.0, 1, 2)
    with pytest.raises(ValueError, match="non-negative"):
        SACConfig(noise_color=-1.0)
    with pytest.raises(ValueError, match="noise_length"):
        SACConfig(noise_color=1.0, noise_length=1)


def test_given_noise_replaces_the_gaussian_draw():
    cfg = SACConfig(hidden=(8,))
    actor = sac_init(jax.random.key(1), 2, 2, cfg).params.actor
    obs = jnp.array([[0.1, -0.3]])
    key = jax.random.key(2)
    eps = jax.random.normal(key, (1, 2))
    a_key, logp_key = sample_action(actor, obs, key)
    a_eps, logp_eps = sample_action(actor, obs, jax.random.key(99), eps)
    np.testing.assert_allclose(np.asarray(a_eps), np.asarray(a_key), rtol=1e-6)  # same ε, same action
    np.testing.assert_allclose(np.asarray(logp_eps), np.asarray(logp_key), rtol=1e-5)


OPEN = {
    "name": "open",
    "horizon": 40,
    "layout": "###########\n#.........#\n#.........#\n#....S....#\n#.........#\n#........G#\n###########",
    "rewards": {"step": -1.0},
}


def _random_phase_episodes(noise_color):
    """Actions of 600 random-phase steps, split into episodes."""
    world = world_from_dict(OPEN)
    cfg = SACConfig(hidden=(8,), noise_color=noise_color, noise_length=40)
    ls = loop_init(jax.random.key(3), world.env, world.params, cfg, 600)
    ls = run_chunk(ls, world.env, world.params, None, n_steps=600, cfg=cfg, phase="random")
    act, t = np.asarray(ls.replay.act), np.asarray(ls.replay.ep_step)
    assert np.all(np.abs(act) < 1.0)
    return np.split(act, np.flatnonzero(t == 0)[1:])


def _follow(episodes):
    """Correlation of consecutive actions (first dimension) within episodes."""
    a = np.concatenate([e[:-1, 0] for e in episodes])
    b = np.concatenate([e[1:, 0] for e in episodes])
    return float(np.corrcoef(a, b)[0, 1])


def test_the_loop_draws_one_sequence_per_episode():
    white, red = _random_phase_episodes(0.0), _random_phase_episodes(2.0)
    assert len(red) >= 10
    assert abs(_follow(white)) < 0.15  # uniform actions, independent
    assert _follow(red) > 0.6  # red noise: consecutive actions of an episode agree
    # a new episode starts a new sequence: its first action does not follow the last one
    across = np.corrcoef([e[-1, 0] for e in red[:-1]], [e[0, 0] for e in red[1:]])[0, 1]
    assert abs(across) < 0.5
    # red noise travels further in an episode's first 10 steps than uniform actions
    spread = lambda eps: float(np.mean([abs(e[:10, 0].sum()) for e in eps if len(e) >= 10]))  # noqa: E731
    assert spread(red) > 2 * spread(white)


def test_the_state_entropy_bonus_is_centred_favours_rare_states_and_halves():
    from mindgap.algorithms.sac_loop import bonus_weight, novelty_bonus
    from mindgap.data.batch import Batch

    crowd = jax.random.normal(jax.random.key(4), (200, 2)) * 0.05
    next_obs = jnp.concatenate([crowd[:63], jnp.array([[0.9, 0.9]])])  # one state far from the others
    batch = Batch(next_obs, jnp.zeros((64, 2)), jnp.zeros(64), next_obs, jnp.zeros(64))
    bonus = np.asarray(novelty_bonus(batch, crowd, 5, 0.5))
    assert abs(bonus.mean()) < 1e-5
    assert bonus[-1] == bonus.max() and bonus[-1] > 0.5 * 2  # the rare state: several std above the rest
    cfg = SACConfig(entropy_bonus=2.0, entropy_bonus_halflife=1000)
    np.testing.assert_allclose([float(bonus_weight(cfg, jnp.asarray(t))) for t in (0, 1000, 3000)], [2.0, 1.0, 0.25])
    with pytest.raises(ValueError, match="entropy_bonus"):
        SACConfig(entropy_bonus=-1.0)
