"""EPS's configuration and presets (Algorithm 3's knobs on the engine's schedule).

The run itself is :mod:`~mindgap.algorithms.eps`; the reasons behind defaults the
dissertation leaves open are in docs/methods/eps.md.
"""

from __future__ import annotations

import dataclasses

from ..feedback.queries import check_sampler
from ..models.gaussian_dynamics import DynamicsConfig
from ..models.reward_ensemble import ABSORBING_STATES, RewardConfig
from .engine import FAST_SCHEDULE, Schedule
from .eps_reward import eps_sac_config
from .sac import SACConfig

METHODS = ("eps", "drlhp")
SURROGATES = ("learned", "exact")
OFFSETS = ("cost", "centred", "none")
JUDGED = ("transitions", "decisions")
POLICY_ENTROPY = ("lambda", "sac")
DRLHP_ALPHA = ("sac", "nats")


@dataclasses.dataclass(frozen=True)
class EPSConfig(Schedule):
    """One EPS (or expectation-DRLHP) run; all seeds share it (hashable, a static jit argument).

    The schedule's fields (steps, chunks, evaluation, SAC, budget, teacher knobs) are
    :class:`~mindgap.algorithms.engine.Schedule`'s; for EPS the SAC's α is replaced by
    λ·reward_scale/nats_per_unit.
    """

    method: str = "eps"
    """eps (Algorithm 3) or drlhp (u_H alone, the baseline of §4.4.1.1)."""
    lam: float = 2.0
    """λ, the reconciliation factor of Eq. 4.6 (the dissertation tunes it in [2.0, 2.8])."""
    total_steps: int = 60_000
    """Environment steps per seed."""
    reward: RewardConfig = RewardConfig()
    """The ensemble that learns u_H."""
    dynamics: DynamicsConfig = DynamicsConfig()
    """T_A, the agent's Gaussian dynamics model (H_T)."""
    per_round: int = 80
    """Queries per feedback round."""
    sampler: str = "disagreement"
    """uniform, disagreement or entropy (uncertainty sampling, §4.3.3)."""
    candidates: int = 10
    """Pairs drawn per query kept (score-based samplers)."""
    nats_per_unit: float = 7.0
    """s_H: the per-step spread, in nats, of the person's log T_H + log π_H that one unit of the
    standardised u_H stands for; the policy entropy and H_T are weighted λ/s_H (α = λ·reward_scale/s_H)
    so that u_H + H_T + H_π keeps the balance of the KLs it comes from. One value for every world
    (docs/methods/eps.md)."""
    offset: str = "cost"
    """The constant of the λ-term per step, which standardising u_H leaves open
    (:mod:`~mindgap.algorithms.eps_reward`, docs/methods/eps.md). ``cost``: the term is ≤ 0 on every
    step of the buffer, as the −KL of Eqs. 4.2–4.4 it stands for, so holding still never pays.
    ``centred``: u_H and H_T centred over the buffer (zero-mean: a bonus wherever the person's model
    rates a step above average; the previous default). ``none``: u_H centred, H_T as Eq. 4.6 writes it."""

    judged: str = "transitions"
    """What the person's expectation covers. ``transitions``: state and action (Eq. 4.3 as §4.3.1 assumes),
    u_H standing for log T_H + log π_H and H_T the dynamics half of the KL. ``decisions``: the
    actions alone — §4.3.1's remark that "only the observable part needs to be considered", for a
    person who judges what the agent decided and not the world's answer (the driving study's
    participants): u_H stands for log π_H, the KL is the policy's, and H_T is not part of it (T_A is
    not fitted)."""
    policy_entropy: str = "lambda"
    """SAC's entropy coefficient. ``lambda``: λ/s_H alone, fixed — Eq. 4.6 as written, where the policy
    entropy is inside λ(…), so at λ = 0 the agent has none. ``sac``: SAC's own tuned α plus λ/s_H — the
    policy optimiser of Algorithm 3 keeps its MaxEnt term, so that at λ = 0 EPS is SAC on r_A ("the
    lower the λ, the closer the behavior is to the SAC agent", §4.4.1.4). Measured beside each other in
    docs/experiments/eps.md, "What λ = 0 means"."""
    drlhp_alpha: str = "sac"
    """DRLHP's entropy coefficient (EPS's is λ/s_H, ``policy_entropy``). ``sac``: SAC's own, as
    ``sac`` configures it (tuned to its target entropy unless fixed). ``nats``: fixed at reward_scale/s_H, so that one unit of the standardised u_H
    weighs what it stands for, s_H nats of the person's log π_H (+ log T_H), against one nat of the
    policy's entropy — the objective whose optimum is the person's expected policy (Eq. 4.4's KL
    with r_A left out), and Christiano et al. (2017)'s recipe of a reward normalised to a fixed spread
    under a fixed entropy bonus. The presets set ``nats``; the field's default keeps earlier run
    folders' meaning (docs/experiments/driving.md, "Why DRLHP brakes first in fewer seeds than EPS")."""
    absorbing: str | None = None
    """Absorbing states for u_H (Kostrikov et al. 2019, as :mod:`~mindgap.algorithms.pbrl`'s): None (the
    default), or ``single`` / ``terminal``. With them the queried segments keep the steps after an
    episode's end, u_H learns what the rest of an ended clip is worth, and an ended episode's
    λ-term goes on at that value (``γ x_abs / (1 − γ)``, :func:`~.eps_reward.eps_absorbing`), so that
    the λ-term's constant per step, which preferences leave open, is paid on every step of the
    horizon and no longer decides whether ending an episode early pays (docs/methods/eps.md)."""

    surrogate: str = "learned"
    """``learned``: u_H is the ensemble fitted to the person's answers (Algorithm 3). ``exact``:
    u_H is the person's own per-step log T_H + log π_H (:class:`~.eps_reward.ExactSurrogate`),
    standardised over the buffer the same way; no query is asked (the rounds still come on the
    same schedule, refit T_A and relabel, and count their budget as shown). An oracle
    ablation, not a method: it needs the person's models, which only a simulation has."""

    def check(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r}: choose from {', '.join(METHODS)}")
        if self.surrogate not in SURROGATES:
            raise ValueError(f"unknown surrogate {self.surrogate!r}: choose from {', '.join(SURROGATES)}")
        if self.offset not in OFFSETS:
            raise ValueError(f"unknown offset {self.offset!r}: choose from {', '.join(OFFSETS)}")
        if self.judged not in JUDGED:
            raise ValueError(f"judged must be one of {', '.join(JUDGED)}, got {self.judged!r}")
        if self.policy_entropy not in POLICY_ENTROPY:
            raise ValueError(f"policy_entropy must be one of {', '.join(POLICY_ENTROPY)}, got {self.policy_entropy!r}")
        if self.drlhp_alpha not in DRLHP_ALPHA:
            raise ValueError(f"drlhp_alpha must be one of {', '.join(DRLHP_ALPHA)}, got {self.drlhp_alpha!r}")
        if self.method == "drlhp" and self.drlhp_alpha == "nats" and self.sac.alpha is not None:
            raise ValueError("DRLHP's α is 1/s_H (drlhp_alpha nats): set drlhp_alpha to sac to fix it at sac.alpha")
        if self.absorbing is not None and self.absorbing not in ABSORBING_STATES:
            raise ValueError(f"absorbing must be one of {', '.join(ABSORBING_STATES)} or None, got {self.absorbing!r}")
        check_sampler(self.sampler, belief=False)
        if self.lam < 0:
            raise ValueError(f"λ must be non-negative, got {self.lam}")
        if not self.nats_per_unit > 0:
            raise ValueError(f"nats_per_unit must be positive, got {self.nats_per_unit}")
        self.check_schedule()
        if self.queries < 1 or self.per_round < 1:
            raise ValueError("queries and per_round must be at least 1")

    def as_dict(self) -> dict:
        d = super().as_dict()
        if self.surrogate == "learned":  # recorded only when set, so earlier run folders still resume
            del d["surrogate"]
        if self.absorbing is None:
            del d["absorbing"]
        if self.judged == "transitions":
            del d["judged"]
        if self.policy_entropy == "lambda":
            del d["policy_entropy"]
        if self.drlhp_alpha == "sac":
            del d["drlhp_alpha"]
        return d

    def agent_sac(self) -> SACConfig:
        """The SAC the agent runs: :func:`eps_agent_sac` for EPS, :func:`drlhp_agent_sac` for DRLHP."""
        return eps_agent_sac(self) if self.method == "eps" else drlhp_agent_sac(self)


def eps_agent_sac(cfg: EPSConfig) -> SACConfig:
    """EPS's SAC: Eq. 4.6's λ·H_π as the entropy coefficient (:func:`~.eps_reward.eps_sac_config`)."""
    return eps_sac_config(cfg.sac, cfg.lam, cfg.nats_per_unit, cfg.policy_entropy)


def drlhp_agent_sac(cfg: EPSConfig) -> SACConfig:
    """DRLHP's SAC: as configured, with α fixed at reward_scale/s_H when ``cfg.drlhp_alpha`` is ``nats``
    (its survival entropy stays as configured: u_H has no λ-term constant to carry it)."""
    if cfg.drlhp_alpha == "sac":
        return cfg.sac
    return dataclasses.replace(cfg.sac, alpha=cfg.sac.reward_scale / cfg.nats_per_unit)


_PRESET = dict(drlhp_alpha="nats")
"""What both presets set on top of the fields' defaults (a default kept for earlier run folders)."""

_FAST = dict(
    **FAST_SCHEDULE,
    reward=RewardConfig(members=2, hidden=(8, 8), updates=10, batch_size=8),
    dynamics=DynamicsConfig(hidden=(8, 8), max_epochs=3, steps_per_epoch=5, batch_size=32),
)
PRESETS = ("full", "fast")


def eps_config(preset: str = "full", **overrides) -> EPSConfig:
    """A preset with ``overrides`` applied, checked (``fast``: tiny networks, 1500 steps; for tests)."""
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}: choose from {', '.join(PRESETS)}")
    cfg = EPSConfig(**{**_PRESET, **(_FAST if preset == "fast" else {}), **overrides})
    cfg.check()
    return cfg
