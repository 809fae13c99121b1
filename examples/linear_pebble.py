"""A preference learner of your own in one file: PEBBLE's loop with a linear reward ensemble and a margin sampler.

Registering the method gives it ``mindgap.algorithms.methods.train``, a command and a place in grid
sweeps, with no edit elsewhere:

    MINDGAP_METHODS=examples/linear_pebble.py mindgap linear-pebble --env nav1 --fast --out runs/linear-nav1
    MINDGAP_METHODS=examples/linear_pebble.py mindgap linear-pebble --help   # every config field is a flag

Each member's reward is ``B·tanh(w·φ(s, a)/B)`` with ``φ(s, a) = [s, a, s², 1]``; the members are fitted
to every answer by Bradley–Terry (Eq. 3.1) from their own initialisations; queries are the pairs
whose mean predicted preference is closest to a coin flip (``margin``, registered beside the
built-in samplers).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import optax

from mindgap.algorithms import methods, pbrl
from mindgap.algorithms.engine import FAST_SCHEDULE, Learner, Schedule
from mindgap.envs.interface import action_width
from mindgap.feedback.queries import SAMPLERS, Sampler, check_sampler, select_queries
from mindgap.models.categorical import action_input
from mindgap.models.reward_ensemble import soft_bound


def _margin(model, seg_a, seg_b):
    """Pairs whose mean P(a ≻ b) is nearest ½ first."""
    return -jnp.abs(model.members(seg_a, seg_b).mean(0) - 0.5)


SAMPLERS.setdefault("margin", Sampler(_margin))


@dataclasses.dataclass(frozen=True)
class LinearPebbleConfig(Schedule):
    """PEBBLE's schedule with a linear reward ensemble."""

    method: str = "linear-pebble"
    """This method's name."""
    members: int = 3
    """Members of the ensemble."""
    lr: float = 0.01
    """Adam's step size for the reward weights."""
    updates: int = 200
    """Full-batch Adam steps per feedback round."""
    sampler: str = "margin"
    """Query sampler (any registered one that needs no belief model)."""
    candidates: int = 10
    """Pairs drawn per query kept."""

    def check(self) -> None:
        self.check_schedule()
        check_sampler(self.sampler, belief=False)
        if self.members < 1 or self.updates < 1:
            raise ValueError("members and updates must be at least 1")


def preset(name: str = "full", **overrides) -> LinearPebbleConfig:
    """``full``: PEBBLE's schedule (4000 steps of pre-training, critic reset); ``fast``: the engine's fast one."""
    if name not in ("full", "fast"):
        raise ValueError(f"unknown preset {name!r}: choose from full, fast")
    base = dict(FAST_SCHEDULE, explore_steps=250) if name == "fast" else dict(explore_steps=4000)
    cfg = LinearPebbleConfig(**{**base, "reset_critic": True, **overrides})
    cfg.check()
    return cfg


def _features(obs, act):
    return jnp.concatenate([obs, act, obs**2, jnp.ones(obs.shape[:-1] + (1,))], axis=-1)


def member_rewards(w, obs, act):
    """[E, …] rewards of every member (a discrete action enters one-hot)."""
    width = w.shape[1] - 2 * obs.shape[-1] - 1
    return soft_bound(jnp.einsum("ef,...f->e...", w, _features(obs, action_input(act, width))))


def reward(w, obs, act, next_obs):
    """The members' mean: what SAC optimises."""
    return member_rewards(w, obs, act).mean(0)


def _logits(w, seg_a, seg_b):
    def ret(seg):
        return jnp.where(seg.mask, member_rewards(w, seg.obs, seg.act), 0.0).sum(-1)

    return ret(seg_a) - ret(seg_b)  # [E, K]: each member's R̂_a − R̂_b


def _init(key, env, cfg: LinearPebbleConfig):
    k_loop, k_w, k_run = jax.random.split(key, 3)
    d, a = env.observation_space.dim, action_width(env.action_space)
    return 0.1 * jax.random.normal(k_w, (cfg.members, 2 * d + a + 1)), k_loop, k_run


def _select(w, replay, key, world, env, cfg: LinearPebbleConfig):
    key, k_q, k_t, k_r = jax.random.split(key, 4)
    probs = lambda a, b: jax.nn.sigmoid(_logits(w, a, b))  # noqa: E731
    seg_a, seg_b = select_queries(k_q, replay, probs, cfg.per_round, cfg.segment, cfg.sampler, cfg.candidates)
    return w, seg_a, seg_b, (key, k_t, k_r)


def _learn(w, prefs, replay, key, world, env, cfg: LinearPebbleConfig):
    seen = jnp.arange(prefs.label.shape[0]) < prefs.count
    opt = optax.adam(cfg.lr)

    def loss(w):
        logit = _logits(w, prefs.seg_a, prefs.seg_b)
        ce = -(prefs.label * jax.nn.log_sigmoid(logit) + (1 - prefs.label) * jax.nn.log_sigmoid(-logit))
        return jnp.sum(jnp.where(seen, ce, 0.0)) / jnp.maximum(prefs.count, 1)

    def step(carry, _):
        w, o = carry
        value, g = jax.value_and_grad(loss)(w)
        upd, o = opt.update(g, o, w)
        return (optax.apply_updates(w, upd), o), value

    (w, _), losses = jax.lax.scan(step, (w, opt.init(w)), None, length=cfg.updates)
    hit = (jax.nn.sigmoid(_logits(w, prefs.seg_a, prefs.seg_b)).mean(0) > 0.5) == (prefs.label > 0.5)
    return w, (losses[-1], jnp.sum(hit & seen) / jnp.maximum(prefs.count, 1))


LEARNER = Learner(_init, _select, _learn, lambda w, world, env, cfg: (reward, w, None))

METHOD = methods.register(
    methods.Method(
        name="linear-pebble",
        label="PEBBLE, linear reward",
        config=LinearPebbleConfig,
        preset=preset,
        learner=lambda cfg: LEARNER,
        prepare=pbrl.prepare,
        learned_reward=lambda w: (reward, w),
        answers="preferences",
    )
)
