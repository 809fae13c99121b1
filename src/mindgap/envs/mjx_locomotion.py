"""Hopper and half-cheetah with hidden noise (§3.4.2.3) as pure-JAX worlds on MuJoCo's JAX backend (MJX).

"The dynamics is a bit more stochastic by applying a small amount of noise to some of the
transitions", while the person believes "the agent is operating reliably". These are the
same two tasks as :mod:`~mindgap.envs.mujoco_noise` (gymnasium's ``Hopper-v5`` and
``HalfCheetah-v5`` with :class:`~mindgap.envs.mujoco_noise.HiddenNoise`), written against
:mod:`~mindgap.envs.interface` so that a whole run — stepping, SAC, the learned rewards and the
simulated person — is one jitted program, vmapped over seeds (``--env mjx:hopper``). The
dissertation's descriptions (a hopper with 4 actions rewarded for torso height and forward
velocity, a cheetah rewarded linearly in forward velocity up to 10 m/s) are closer to
DeepMind Control's hopper-hop and cheetah-run; these worlds keep gymnasium's v5 tasks, so
that the host-loop versions cross-check them exactly.

MJX gives the physics, on gymnasium's own model files (:mod:`~mindgap.envs.mjx_model`, which
also sets the solver options). Written here by hand, because they are the task, not the
physics, and no small package states them in JAX:

* **reset**: gymnasium's — the model's reference pose plus uniform noise of ±``reset_noise``
  on every position, and on the velocities uniform (hopper, 5e-3) or Gaussian (cheetah, 0.1);
* **step**: the action in [−1, 1]^a is the motors' control (their range); ``frame_skip``
  MJX steps (4 for the hopper, 5 for the cheetah); the reward and, for the hopper, the end of
  the episode (height ≤ 0.7, |torso angle| ≥ 0.2 or any later state element beyond ±100) are
  gymnasium's, of the state the physics reached; then, with probability ``share``, every
  joint velocity is perturbed by N(0, ``scale``²) (drawn with ``jax.random`` from the step's
  key), as the wrapper does. Episodes end at ``horizon`` steps (gymnasium's 1000);
* **observe**: gymnasium's observation with the x position in front
  (``exclude_current_positions_from_observation=False``, as the noisy gym envs have it):
  positions then velocities, the hopper's velocities clipped to ±10;
* **reward**: the person's r_H, :func:`~mindgap.envs.mujoco_noise.hopper_reward` /
  :func:`~mindgap.envs.mujoco_noise.cheetah_reward`, the same functions as the gym worlds'.
  The step's own reward is gymnasium's, read from the state before the noise, where the
  hopper's health test sees unclipped velocities; the two agree unless a velocity passes ±100.
* **log_prob**: the transition law, exact up to what the observation hides (below).

The transition law. The physics is deterministic: f(s, a) = (q̂, v̂). The next state is f(s, a)
with probability 1 − p (p = ``share``) and (q̂, v̂ + ε), ε ~ N(0, σ² I), with probability p: the
noise never moves positions. This law has no density with respect to Lebesgue measure (it
has an atom, and positions are always exact). ``log_prob`` is its density with respect to the
measure μ = δ_{f(s,a)} + δ_{q̂} ⊗ Lebesgue(v) — log(1 − p) at the atom, log p + log N(v′; v̂, σ²I)
on the rest of the fibre q′ = q̂, −∞ elsewhere — computed by stepping the physics again from
``obs``. What it can and cannot be:

* μ depends on (s, a), so the values at the atom (≤ 0) and of the Gaussian (any sign) are not
  on one scale; they are exact as stated, and for the person's belief they need no scale:
  the reliable belief (``share`` = 0, the world's belief ``reliable``) gives 0 to a step that
  went as the physics says and −∞ to any other, which the preference teacher floors
  (``log_t_floor``): "this could not have happened";
* the atom is recognised within :data:`ATOL`: float32 physics, with a solver warm-started
  from what the observation does not hold, repeats a step only to about 1e-4 (on 1,600
  random-action cheetah steps, 4% were off by more than 1e-5, none by more than 1e-3). A
  perturbation smaller than that on every joint is taken for none (probability below
  1e-15 at σ = 0.5);
* the hopper's observation clips velocities to ±10: a clipped next velocity is scored by
  the Gaussian's tail beyond the clip (exact), but from an observation with a clipped
  velocity the physics is stepped from the clipped state, so its prediction, and log_prob,
  are wrong there (no random-action step of 1,600 reached the clip; a fast policy may).

If the physics ever produces a non-finite state, it is replaced by the model's reference
pose at rest, as MuJoCo's C engine resets such a state (with a warning).

The gymnasium host-loop versions (``gym:mindgap/NoisyHopper-v0``) are the cross-check. Without
noise, from the same state and actions and with the same solver options, both simulate the
same trajectory: in float64 (``jax.enable_x64``) within 1e-8 over 25 steps, where chaos in
the contacts has grown the first step's 1e-15 difference; in float32, the worlds' default,
rounding grows the same way (1e-4 after 5 cheetah steps). gymnasium's own options are
``solver="gym"``; the default ``fast`` options differ from them by the table of
:mod:`~mindgap.envs.mjx_model` (``tests/envs/test_mjx_locomotion.py`` checks all of it).

Which runtime. On two CPU cores the host loop is faster: gymnasium's C engine steps one
cheetah 23k times a second, MJX 2-7k times at 1-256 worlds, and SAC (64 × 64, 3,000 steps,
compiled) took 3.4 s on the host against 16.5 s on MJX for one seed, 61 s against 129 s for
eight (``benchmarks/mjx_locomotion.py``, ``--sac``). So ``gym:mindgap/NoisyHopper-v0`` /
``gym:mindgap/NoisyHalfCheetah-v0`` stay the default there; these worlds are for an
accelerator, and for runs that must be one jitted program.

The person's belief is exact here (``reliable``), so these worlds need no learned belief.
The learned-belief path of the gym worlds (:mod:`~mindgap.teachers.learned_belief`) collects
its transitions from gymnasium envs on the host; its fitted model would fit these worlds too
(same observations), but ``--belief-env`` takes gym worlds only.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.stats import norm

from .interface import Box, Env, EnvError, Step, World
from .mjx_model import SOLVERS, load_model, mjx, put_model
from .mujoco_noise import cheetah_reward, hopper_reward

ATOL = 1e-3
"""How far (in each coordinate's own units) a next observation may be from the physics' and still be its atom."""
MIN_SCALE = 0.01
"""The smallest noise scale ``log_prob`` can tell from the float error of the atom (10 × :data:`ATOL`)."""


@dataclasses.dataclass(frozen=True)
class Body:
    """A locomotion task: what differs between the hopper and the cheetah (gymnasium's v5 values).

    Attributes:
        gym_id: the gymnasium env it transcribes.
        frame_skip: MuJoCo steps per env step.
        ctrl_weight: w_c of the control cost.
        reset_noise: gymnasium's ``reset_noise_scale``.
        gaussian_velocity: the reset draws velocities from N(0, reset_noise²), not uniformly.
        vel_clip: the observation clips velocities to ± this (None: not clipped).
        terminates: the episode ends when the body is unhealthy.
        reward: the person's reward from observations.
    """

    gym_id: str
    frame_skip: int
    ctrl_weight: float
    reset_noise: float
    gaussian_velocity: bool
    vel_clip: float | None
    terminates: bool
    reward: Callable


BODIES = {
    "hopper": Body("Hopper-v5", 4, 1e-3, 5e-3, False, 10.0, True, hopper_reward),
    "cheetah": Body("HalfCheetah-v5", 5, 0.1, 0.1, True, None, False, cheetah_reward),
}


class MjxState(NamedTuple):
    """What a step needs: positions [nq], velocities [nv], the solver's warm start [nv], the step count."""

    qpos: jax.Array
    qvel: jax.Array
    warm: jax.Array
    t: jax.Array


def healthy(qpos: jax.Array, qvel: jax.Array) -> jax.Array:
    """Hopper-v5's ``is_healthy``: height above 0.7, torso angle within ±0.2, every state element after
    the first two within ±100 (velocities unclipped)."""
    rest = jnp.concatenate([qpos[2:], qvel])
    return (qpos[1] > 0.7) & (jnp.abs(qpos[2]) < 0.2) & jnp.all(jnp.abs(rest) < 100.0)


def make_env(body: str, solver: str = "fast", horizon: int = 1000) -> Env:
    """The :class:`~mindgap.envs.interface.Env` of ``body`` with ``SOLVERS[solver]``, episodes of ``horizon`` steps.

    One Env per (body, solver, horizon) and JAX's float width, so that jitted learners taking it
    as a static argument compile once. Its params are a dict (:func:`default_params`). Made
    while JAX runs in 64 bits (``jax.enable_x64``), it simulates in float64.
    """
    if body not in BODIES:
        raise EnvError(f"no MJX body {body!r}; there are: {', '.join(BODIES)}")
    return _make_env(body, solver, horizon, bool(jax.config.read("jax_enable_x64")))


@functools.cache
def _make_env(body: str, solver: str, horizon: int, x64: bool) -> Env:
    spec = BODIES[body]
    mj = load_model(body, solver)
    mx, blank = put_model(body, solver)
    mx_step = mjx().step
    nq, nv, nu = mj.nq, mj.nv, mj.nu
    f = blank.qpos.dtype  # float32 unless JAX runs in 64 bits
    qpos0 = jnp.asarray(mj.qpos0, f)
    # [−1, 1] onto the motors' range as mid + a·half: exactly a for the range [−1, 1] both bodies have
    low, high = mj.actuator_ctrlrange[:, 0], mj.actuator_ctrlrange[:, 1]
    ctrl_mid, ctrl_half = jnp.asarray((high + low) / 2, f), jnp.asarray((high - low) / 2, f)
    dim = nq + nv

    def control(action):
        a = jnp.clip(jnp.asarray(action, f), -1.0, 1.0)
        return a, ctrl_mid + a * ctrl_half

    def physics(qpos, qvel, warm, ctrl):
        """``frame_skip`` MJX steps: (positions, velocities, warm start) after them, reset if not finite."""
        d = blank.replace(qpos=qpos, qvel=qvel, qacc_warmstart=warm, ctrl=ctrl)
        d = jax.lax.fori_loop(0, spec.frame_skip, lambda _, d: mx_step(mx, d), d)
        ok = jnp.all(jnp.isfinite(d.qpos)) & jnp.all(jnp.isfinite(d.qvel)) & jnp.all(jnp.isfinite(d.qacc_warmstart))
        zeros = jnp.zeros(nv, f)
        return (jnp.where(ok, d.qpos, qpos0), jnp.where(ok, d.qvel, zeros), jnp.where(ok, d.qacc_warmstart, zeros))

    def observe_qv(qpos, qvel):
        v = qvel if spec.vel_clip is None else jnp.clip(qvel, -spec.vel_clip, spec.vel_clip)
        return jnp.concatenate([qpos, v])

    def reset(key, params) -> MjxState:
        k_q, k_v = jax.random.split(key)
        r = params["reset_noise"]
        qpos = qpos0 + jax.random.uniform(k_q, (nq,), f, minval=-r, maxval=r)
        if spec.gaussian_velocity:
            qvel = r * jax.random.normal(k_v, (nv,), f)
        else:
            qvel = jax.random.uniform(k_v, (nv,), f, minval=-r, maxval=r)
        return MjxState(qpos, qvel, jnp.zeros(nv, f), jnp.zeros((), jnp.int32))

    def step(key, state: MjxState, action, params) -> Step:
        a, ctrl = control(action)
        qpos, qvel, warm = physics(state.qpos, state.qvel, state.warm, ctrl)
        # gymnasium's reward and end, of the state the physics reached (the wrapper's noise comes after)
        before, after = jnp.concatenate([state.qpos, state.qvel]), jnp.concatenate([qpos, qvel])
        reward = spec.reward(before, a, after, params)
        terminated = ~healthy(qpos, qvel) if spec.terminates else jnp.zeros((), bool)
        k_hit, k_eps = jax.random.split(key)
        hit = jax.random.uniform(k_hit) < params["share"]
        qvel = qvel + jnp.where(hit, params["scale"], 0.0) * jax.random.normal(k_eps, (nv,), f)
        t = state.t + 1
        return Step(MjxState(qpos, qvel, warm, t), reward, terminated, ~terminated & (t >= horizon))

    def observe(state: MjxState, params):
        return observe_qv(state.qpos, state.qvel)

    def log_prob(obs, act, next_obs, params):
        """log of the transition law's density with respect to μ (module docstring)."""
        _, ctrl = control(act)
        q_hat, v_hat, _ = physics(obs[:nq], obs[nq:], jnp.zeros(nv, f), ctrl)
        pred = observe_qv(q_hat, v_hat)
        on_fibre = jnp.all(jnp.abs(next_obs[:nq] - q_hat) <= ATOL)
        at_atom = on_fibre & jnp.all(jnp.abs(next_obs[nq:] - pred[nq:]) <= ATOL)
        # a noise of scale 0 changes nothing: every step is then the atom
        p = jnp.where(params["scale"] > 0, params["share"], 0.0)
        sigma = jnp.maximum(params["scale"], 1e-12)
        v = next_obs[nq:]
        dens = norm.logpdf(v, v_hat, sigma)
        if spec.vel_clip is not None:  # a clipped velocity: the Gaussian's mass beyond the clip
            c = spec.vel_clip
            dens = jnp.where(
                v >= c, norm.logsf(c, v_hat, sigma), jnp.where(v <= -c, norm.logcdf(-c, v_hat, sigma), dens)
            )
        fibre = jnp.log(p) + jnp.sum(dens)
        return jnp.where(at_atom, jnp.log1p(-p), jnp.where(on_fibre, fibre, -jnp.inf))

    def reward(obs, act, next_obs, params):
        return spec.reward(obs, act, next_obs, params)

    inf = float("inf")
    return Env(reset, step, observe, Box((dim,), -inf, inf), Box((nu,)), reward=reward, log_prob=log_prob)


def default_params(body: str, share: float = 0.2, scale: float = 0.5) -> dict:
    """The world's numbers: the reward's (``dt``, ``forward_weight``, ``ctrl_weight``), the noise's
    (``share``, ``scale``) and the reset's (``reset_noise``), gymnasium's v5 values, float32."""
    if body not in BODIES:
        raise EnvError(f"no MJX body {body!r}; there are: {', '.join(BODIES)}")
    if not 0.0 <= share <= 1.0:
        raise EnvError(f"share must be in [0, 1], got {share}")
    if not (scale == 0.0 or scale >= MIN_SCALE):
        raise EnvError(f"scale must be 0 or at least {MIN_SCALE} (log_prob cannot tell a smaller noise), got {scale}")
    spec = BODIES[body]
    mj = load_model(body, "gym")
    values = {
        "dt": mj.opt.timestep * spec.frame_skip,
        "forward_weight": 1.0,
        "ctrl_weight": spec.ctrl_weight,
        "share": share,
        "scale": scale,
        "reset_noise": spec.reset_noise,
    }
    return {k: jnp.asarray(v, jnp.float32) for k, v in values.items()}


@dataclasses.dataclass(frozen=True, eq=False)
class MjxWorld(World):
    """A hopper or cheetah on MJX (module docstring); its one belief, ``reliable``, has no noise.

    Attributes:
        body: ``"hopper"`` or ``"cheetah"``.
        solver: the name of its solver options (:data:`~mindgap.envs.mjx_model.SOLVERS`).
    """

    body: str = ""
    solver: str = "fast"

    def fingerprint_tree(self):
        """The params, the beliefs and the solver options (they change the simulation, not the params)."""
        return (self.params, dict(self.beliefs), np.asarray(SOLVERS[self.solver].as_numbers(), np.int32))


def mjx_world(
    body: str, share: float = 0.2, scale: float = 0.5, solver: str = "fast", horizon: int = 1000, **unknown
) -> MjxWorld:
    """The MJX world of ``body`` (``"hopper"``, ``"cheetah"``) with its noise, solver options and horizon."""
    if unknown:
        raise EnvError(
            f"mjx:{body}: unknown argument(s) {', '.join(sorted(unknown))}; it takes share, scale, solver, horizon"
        )
    if solver not in SOLVERS:
        raise EnvError(f"mjx:{body}: no solver options {solver!r}; there are: {', '.join(SOLVERS)}")
    if not isinstance(horizon, int) or horizon < 1:
        raise EnvError(f"mjx:{body}: horizon must be a positive integer, got {horizon!r}")
    params = default_params(body, float(share), float(scale))
    reliable = {**params, "share": jnp.zeros((), jnp.float32)}
    given = {"share": share, "scale": scale, "solver": solver, "horizon": horizon}
    defaults = {"share": 0.2, "scale": 0.5, "solver": "fast", "horizon": 1000}
    name = ",".join([f"mjx:{body}", *(f"{k}={v}" for k, v in given.items() if v != defaults[k])])
    env = make_env(body, solver, horizon)
    return MjxWorld(name, env, params, {"reliable": reliable}, horizon=horizon, source=name, body=body, solver=solver)


def hopper(**kwargs) -> MjxWorld:
    """Hopper-v5 on MJX with hidden noise (:func:`mjx_world`)."""
    return mjx_world("hopper", **kwargs)


def cheetah(**kwargs) -> MjxWorld:
    """HalfCheetah-v5 on MJX with hidden noise (:func:`mjx_world`)."""
    return mjx_world("cheetah", **kwargs)


def mjx_world_from_spec(spec: str) -> MjxWorld:
    """``mjx:BODY,key=value,…`` → :func:`mjx_world` (``mjx:hopper,share=0.1,solver=gym``)."""
    from .resolve import parse_kwargs

    head, _, rest = spec.partition(",")
    body = head[len("mjx:") :].strip()
    if body not in BODIES:
        raise EnvError(f"{spec}: expected mjx:BODY with BODY one of {', '.join(BODIES)}")
    return mjx_world(body, **parse_kwargs(rest))
