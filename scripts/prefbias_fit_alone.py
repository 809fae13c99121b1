"""Does PrefBias's fit alone recover nav1's belief from the person's answers?

The full nav run showed f_φ widening its Gaussian instead of learning the person's stay
probability on the ice (docs/identifiability.md, "Full runs on the redesigned worlds"). This
takes the loop out: 800 answers simulated exactly as the design check's ML fit does
(planning/belief_fit.simulate_queries), f_ψ trained on their transitions, then
prefbias_inference.fit under config variants, printing f_φ's P(not moving) and move noise on
the ice (person: 0.92 and 0.05 cells; truth: 0.32 and 0.05).

    .venv/bin/python scripts/prefbias_fit_alone.py [VARIANT ...]
"""

import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from mindgap.algorithms.prefbias_inference import PrefBiasConfig, fit, prefbias_init
from mindgap.data.prefs import PrefData
from mindgap.data.segments import Segments
from mindgap.envs.terrain import load_world
from mindgap.envs.terrain.layout import ICE
from mindgap.models.gaussian_dynamics import DynamicsConfig, dynamics_init, fit_norm, train_dynamics
from mindgap.planning.belief_fit import simulate_queries
from mindgap.planning.design_check import ACTIONS, DesignConfig, plan_policies
from mindgap.planning.terrain_maps import belief_noise_map, belief_stay_map

VARIANTS = {
    "default": {},
    "belief_prior_std=0.01": dict(belief_prior_std=0.01),
    "belief_prior_std=0.03": dict(belief_prior_std=0.03),
    "kl_scale=0.1": dict(kl_scale=0.1),
    "kl_scale=0.01": dict(kl_scale=0.01),
    "kl_scale=0.01,lr=3e-3": dict(kl_scale=0.01, lr=3e-3),
    "kl_scale=0": dict(kl_scale=0.0),
}


def flat(x):
    return x.reshape(-1, x.shape[-1])


def main(names):
    world, cfg = load_world("nav1"), DesignConfig()
    belief, floor = world.belief(), cfg.teacher.log_t_floor
    d, _, policies = plan_policies(world, belief, cfg)
    behaviour = [np.asarray(policies["optimal"]), np.asarray(policies["unaware"])]
    q = simulate_queries(
        jax.random.key(1), world.params, belief, behaviour, ACTIONS, d.index, cfg.n,
        beta=1.0, budget=800, segment=10, log_t_floor=floor,
    )  # fmt: skip
    h, w = world.params.grid.shape
    scale = jnp.array([w, h], jnp.float32)
    obs, nxt = 2 * q.pos / scale - 1, 2 * q.nxt / scale - 1  # as envs.terrain.observe
    seg_a = Segments(obs[:, 0], q.act[:, 0], nxt[:, 0], q.live[:, 0])
    seg_b = Segments(obs[:, 1], q.act[:, 1], nxt[:, 1], q.live[:, 1])
    data = PrefData(seg_a, seg_b, q.label.astype(jnp.float32), jnp.asarray(q.label.shape[0], jnp.int32))

    dcfg = DynamicsConfig()  # f_ψ with a stay head, as PrefBias trains it
    valid = q.live.reshape(-1)
    norm = fit_norm(flat(obs), flat(q.act), flat(nxt), valid)
    start = dynamics_init(jax.random.key(3), 2, 2, dcfg, norm, stay=True)
    dyn, _ = train_dynamics(jax.random.key(2), flat(obs), flat(q.act), flat(nxt), valid, dcfg, init=start)
    ice = np.asarray(world.params.grid) == ICE

    def report(name, phi, norm):
        stay = np.asarray(belief_stay_map(phi, norm, world.params))
        noise = np.asarray(belief_noise_map(phi, norm, world.params, dcfg.min_std))
        print(f"{name:40s} stay on ice {np.nanmean(stay[ice]):.3f}  noise on ice {np.nanmean(noise[ice]):.3f} cells")

    report("f_psi", dyn.params, dyn.norm)
    for name in names or VARIANTS:
        pc = PrefBiasConfig(updates=3000, **VARIANTS[name])  # ten rounds of the full preset's 300
        state = prefbias_init(jax.random.key(4), 2, 2, pc, dyn, units=world.obs_units())
        t0 = time.time()
        state, info = jax.jit(fit, static_argnames="cfg")(state, data, jax.random.key(5), cfg=pc)
        label = f"{name} ({time.time() - t0:.0f} s, train accuracy {float(info.accuracy):.2f})"
        report(label, state.belief.mean, state.norm)


if __name__ == "__main__":
    main(sys.argv[1:])
