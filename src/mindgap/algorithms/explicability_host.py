"""The policy explicability score (Eq. 4.4) on gymnasium worlds, from rollouts stepped on the host.

The estimator is :mod:`~mindgap.algorithms.explicability`'s: over the agent's stochastic
rollouts in the true world,

    −KL(p_A ‖ p_A^H) = −E Σ_t [log T_A − log T_H](s_{t+1}|s_t,a_t) + [log π_θ − log π_H](a_t|s_t).

What differs on a gym world is where the two densities come from. Neither the truth nor the
belief has an exact ``log_prob``, so both are learned models of the same family
(:mod:`~mindgap.teachers.learned_belief`): T_H the person's (the world's belief), T_A a model
of the true env fitted the same way. The rollouts step every seed's episodes in lockstep on
gymnasium envs; the log-densities are then computed in one jitted batch. The policy terms are
the pre-tanh Gaussians' log densities at the drawn pre-tanh action, as there.

The estimate is of the KL between the two *models*. Where the physics is deterministic they
are sharp, so the few steps one model expects and the other does not dominate the sum; and
where the models are poorly fitted (the ``--fast`` preset's) the "dynamics part" can even come
out negative, which the KL between the true densities never is.

Written by hand: a few lines around gymnasium's ``step`` and the models' densities.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..envs.gym_world import GymWorld
from ..models.actor import actor_dist
from ..models.squashed import gaussian_log_prob
from ..teachers.learned_belief import LearnedBelief, learned_log_prob


@jax.jit
def _dists(actors, obs):
    return jax.vmap(actor_dist)(actors, obs)


def rollouts(world: GymWorld, actors, episodes: int, seed: int, progress: bool = False):
    """Stochastic rollouts of every seed's actor: a dict of ``obs, mean, log_std, u, nxt [S, E, T, ·]``
    and ``alive [S, E, T]``, and the returns [S, E].

    ``mean, log_std``: the actor's pre-tanh Gaussian at ``obs``; ``u`` the pre-tanh action drawn
    from it (the env receives tanh u, scaled to its bounds).
    ``progress``: a bar over the episodes' steps (all seeds and episodes advance together).
    """
    seeds = jax.tree.leaves(actors)[0].shape[0]
    n = seeds * episodes
    rng = np.random.default_rng(seed)
    envs, first = zip(*(world.make(seed + i) for i in range(n)), strict=True)
    obs = np.stack(first)
    done = np.zeros(n, bool)
    cols = {"obs": [], "mean": [], "log_std": [], "u": [], "nxt": [], "alive": []}
    returns = np.zeros(n)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=world.horizon, desc=f"explicability rollouts ({n})", unit="step")
    try:
        for _ in range(world.horizon):
            if done.all():
                break
            if bar is not None:
                bar.update()
            mean, log_std = (
                np.asarray(x).reshape(n, -1) for x in _dists(actors, jnp.asarray(obs.reshape(seeds, episodes, -1)))
            )
            u = (mean + np.exp(log_std) * rng.standard_normal(mean.shape)).astype(np.float32)
            nxt = obs.copy()
            alive = ~done
            for i in np.flatnonzero(alive):
                o, r, term, trunc, _ = envs[i].step(world.to_env(np.tanh(u[i])))
                nxt[i], done[i] = np.asarray(o, np.float32).reshape(-1), term or trunc
                returns[i] += r
            for k, v in (("obs", obs), ("mean", mean), ("log_std", log_std), ("u", u), ("nxt", nxt), ("alive", alive)):
                cols[k].append(v)
            obs = nxt
    finally:
        for e in envs:
            e.close()
        if bar is not None:
            bar.close()
    out = {k: np.stack(v, 1).reshape(seeds, episodes, len(v), *v[0].shape[1:]) for k, v in cols.items()}
    return out, returns.reshape(seeds, episodes)


@jax.jit
def _log_ratios(expected_actor, truth: LearnedBelief, belief, obs, mean, log_std, u, nxt, alive):
    a = jnp.tanh(u)
    log_t = learned_log_prob(obs, a, nxt, truth) - learned_log_prob(obs, a, nxt, belief)
    h_mean, h_log_std = actor_dist(expected_actor, obs)
    log_pi = gaussian_log_prob(mean, log_std, u) - gaussian_log_prob(h_mean, h_log_std, u)
    return jnp.sum(jnp.where(alive, log_t, 0.0), -1), jnp.sum(jnp.where(alive, log_pi, 0.0), -1)


def explicability_scores_host(
    world: GymWorld, person, truth: LearnedBelief, actors, episodes: int = 100, seed: int = 20_000, progress=False
) -> list[dict]:
    """:func:`~mindgap.algorithms.explicability.explicability_scores` on a gym world (module docstring).

    Args:
        person: the simulated person (its learned ``belief`` and expected policy ``policy``).
        truth: a learned model of the true env (:func:`~mindgap.teachers.learned_belief.fit_learned_belief`
            of the world itself), standing for T_A.
        actors: SAC actors with a leading seed axis.
    """
    r, returns = rollouts(world, actors, episodes, seed, progress)
    cols = (r["obs"], r["mean"], r["log_std"], r["u"], r["nxt"], r["alive"])
    log_t, log_pi = (np.asarray(x) for x in _log_ratios(person.policy, truth, person.belief, *cols))
    out = []
    for s in range(log_t.shape[0]):
        per = -(log_t[s] + log_pi[s])
        out.append(
            {
                "score": float(per.mean()),
                "stderr": float(per.std() / np.sqrt(max(episodes - 1, 1))),
                "dynamics_part": float(log_t[s].mean()),
                "policy_part": float(log_pi[s].mean()),
                "stochastic_return": float(returns[s].mean()),
            }
        )
    return out
