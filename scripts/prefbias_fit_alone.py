"""Does PrefBias's fit alone recover nav1's belief from the person's answers?

The full nav run showed f_φ widening its Gaussian instead of learning the person's stay
probability on the ice (docs/experiments/identifiability.md, "Full runs on the redesigned worlds"). This
takes the loop out: 800 answers simulated exactly as the design check's ML fit does
(planning/belief_fit.simulate_queries), f_ψ trained on their transitions, then
prefbias_inference.fit under config variants, printing f_φ's P(not moving) and move noise on
the ice (person: 0.92 and 0.05 cells; truth: 0.32 and 0.05).

    .venv/bin/python scripts/prefbias_fit_alone.py [--unbiased] [--world=NAME_OR_FILE] [VARIANT ...]
"""

import ast
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from mindgap.algorithms.prefbias_inference import PrefBiasConfig, bt_cross_entropy, fit, prefbias_init, preference_prob
from mindgap.data.prefs import PrefData
from mindgap.data.segments import Segments
from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.dynamics import log_prob_pos
from mindgap.envs.terrain.layout import ICE
from mindgap.envs.terrain.params import TerrainState
from mindgap.envs.terrain.world import reward
from mindgap.models.gaussian_dynamics import DynamicsConfig, dynamics_init, fit_norm, train_dynamics
from mindgap.planning.belief_fit import simulate_queries
from mindgap.planning.design_check import ACTIONS, DesignConfig, plan_policies
from mindgap.planning.terrain_maps import belief_noise_map, belief_stay_map

VARIANTS = {
    "default": {},
    "belief_prior_std=0.01": dict(belief_prior_std=0.01),
    "kl_scale=0": dict(kl_scale=0.0),
    "reward_hidden=(16,)": dict(reward_hidden=(16,)),
}
"""Named variants; any other argument ``key=value,key=value`` sets PrefBiasConfig fields (Python literals)."""


def variant(name):
    if name in VARIANTS:
        return VARIANTS[name]
    pairs = (item.split("=", 1) for item in name.split(";"))
    return {k.strip(): ast.literal_eval(v.strip()) for k, v in pairs}


def flat(x):
    return x.reshape(-1, x.shape[-1])


def person_logits(world, belief, floor, q):
    """S(a) − S(b) of each query under the person's own reward and belief (β = 1): [Q]."""

    def score(s, a, s2):
        zero = jnp.zeros((), jnp.int32)
        r = reward(TerrainState(s, zero, False), a, TerrainState(s2, zero, False), world.params)
        return r + jnp.maximum(log_prob_pos(belief, s, a, s2), floor)

    per = jax.vmap(jax.vmap(jax.vmap(score)))(q.pos, q.act, q.nxt)
    s = jnp.sum(jnp.where(q.live, per, 0.0), -1)
    return s[:, 0] - s[:, 1]


def as_data(world, q):
    h, w = world.params.grid.shape
    scale = jnp.array([w, h], jnp.float32)
    obs, nxt = 2 * q.pos / scale - 1, 2 * q.nxt / scale - 1  # as envs.terrain.observe
    seg_a = Segments(obs[:, 0], q.act[:, 0], nxt[:, 0], q.live[:, 0])
    seg_b = Segments(obs[:, 1], q.act[:, 1], nxt[:, 1], q.live[:, 1])
    return PrefData(seg_a, seg_b, q.label.astype(jnp.float32), jnp.asarray(q.label.shape[0], jnp.int32)), obs, nxt


def nll_acc(p, label):
    """Mean Bradley–Terry negative log-likelihood per pair and accuracy, from p(first preferred)."""
    logit = jnp.log(p) - jnp.log1p(-p)
    return float(bt_cross_entropy(logit, label).mean()), float(((p > 0.5) == (label > 0.5)).mean())


def main(names):
    unbiased = "--unbiased" in names  # the person believes the truth: any gap is then the learner's
    names = [n for n in names if n != "--unbiased"]
    world_name = "nav1"
    if names and names[0].startswith("--world="):
        world_name, names = names[0].split("=", 1)[1], names[1:]
    world, cfg = load_world(world_name), DesignConfig()
    belief, floor = world.belief(), cfg.teacher.log_t_floor
    d, _, policies = plan_policies(world, belief, cfg)
    if unbiased:
        belief = world.params
    behaviour = [np.asarray(policies["optimal"]), np.asarray(policies["unaware"])]
    q, held = (
        simulate_queries(
            jax.random.key(k),
            world.params,
            belief,
            behaviour,
            ACTIONS,
            d.index,
            cfg.n,
            beta=1.0,
            budget=800,
            segment=10,
            log_t_floor=floor,
        )  # fmt: skip
        for k in (1, 11)
    )
    data, obs, nxt = as_data(world, q)
    held_data, _, _ = as_data(world, held)
    for name, qq in (("train", q), ("held-out", held)):
        logit = person_logits(world, belief, floor, qq)
        nll, acc = float(bt_cross_entropy(logit, qq.label).mean()), float(((logit > 0) == (qq.label > 0.5)).mean())
        print(f"the person's own model on the {name} answers: NLL {nll:.3f} a pair, accuracy {acc:.2f}")

    dcfg = DynamicsConfig()  # f_ψ with a stay head, as PrefBias trains it
    valid = q.live.reshape(-1)
    norm = fit_norm(flat(obs), flat(q.act), flat(nxt), valid)
    start = dynamics_init(jax.random.key(3), 2, 2, dcfg, norm, stay=True)
    dyn, _ = train_dynamics(jax.random.key(2), flat(obs), flat(q.act), flat(nxt), valid, dcfg, init=start)
    ice = np.asarray(world.params.grid) == ICE

    def report(name, phi, norm):
        stay = np.asarray(belief_stay_map(phi, norm, world.params))
        noise = np.asarray(belief_noise_map(phi, norm, world.params, dcfg.min_std))
        print(f"{name:100s} stay on ice {np.nanmean(stay[ice]):.3f}  noise on ice {np.nanmean(noise[ice]):.3f} cells")

    report("f_psi", dyn.params, dyn.norm)
    for name in names or VARIANTS:
        pc = PrefBiasConfig(**{"updates": 3000, **variant(name)})  # ten rounds of the full preset's 300
        state = prefbias_init(jax.random.key(4), 2, 2, pc, dyn, units=world.obs_units())
        t0 = time.time()
        state, info = jax.jit(fit, static_argnames="cfg")(state, data, jax.random.key(5), cfg=pc)
        p = preference_prob(
            state.reward.mean, state.belief.mean, state.norm, held_data.seg_a, held_data.seg_b, pc, state.log_unit
        )
        nll, acc = nll_acc(jnp.clip(p, 1e-6, 1 - 1e-6), held.label)
        label = f"{name} ({time.time() - t0:.0f} s, train acc {float(info.accuracy):.2f}, held-out NLL {nll:.3f} acc {acc:.2f})"
        spread = float(jnp.mean(jax.nn.softplus(ravel_pytree(state.belief.rho)[0])))
        report(label + f" mean σ of q(φ) {spread:.3f}", state.belief.mean, state.norm)


if __name__ == "__main__":
    main(sys.argv[1:])
