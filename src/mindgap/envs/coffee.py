"""Boutilier's coffee robot (§2.3.2, Fig. 8) as a factored tabular MDP.

Six binary variables give 64 states, ``s = Σ_i v_i · 2^i`` in the order of
:data:`VARIABLES`: robot in the café (else in the office), robot wet, robot holds an
umbrella, raining, robot holds coffee, user has coffee. Actions: 0 Go, 1 BuyCoffee,
2 DeliverCoffee, 3 GetUmbrella.

The dynamics, with the probabilities the dissertation leaves open chosen here:

- **Go** always reaches the other place. Arriving in the rain without an umbrella the
  robot is wet (probability :attr:`CoffeeParams.wet`, 1 by default); otherwise it
  arrives dry. Holding the coffee *and* the umbrella it spills the coffee (the robot
  no longer holds it) with probability :attr:`CoffeeParams.spill`, the only quantity
  that depends on the robot type: :data:`TRUE_SPILL` (the humanoid spills *less*
  than the mobile robot, the truth the study's participants misjudge).
- **BuyCoffee** in the café without coffee: the robot holds coffee (always).
- **DeliverCoffee** in the office holding coffee: the user has the coffee (for good).
- **GetUmbrella**: the robot holds an umbrella from now on (there is a stand in the
  office and in the café; it cannot put it down).
- Any action other than Go happens indoors: the robot dries off. An action whose
  precondition fails changes nothing else.
- Rain is fixed for an episode; an episode starts in the office, dry, without
  umbrella or coffee, raining with probability 1/2.

Reward features (§2.3.2): ``φ = (user has coffee, robot wet)``; a person's reward
is ``w_coffee · φ_0 + w_wet · φ_1`` with ``w_coffee > 0`` and ``w_wet ≤ 0``.

The believed dynamics that matter are few: a person's belief is this world with
another spill (or wet) probability, :func:`coffee_transitions`, and
:func:`factored_layout` gives the layout of a belief that learns just those factor
probabilities (:func:`mindgap.models.belief.factored` builds GeReL's belief from it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .tabular import TabularMDP

VARIABLES = ("in_cafe", "wet", "umbrella", "raining", "robot_coffee", "user_coffee")
IN_CAFE, WET, UMBRELLA, RAINING, ROBOT_COFFEE, USER_COFFEE = range(6)
N_STATES = 2 ** len(VARIABLES)
ACTIONS = ("Go", "BuyCoffee", "DeliverCoffee", "GetUmbrella")
GO, BUY, DELIVER, GET_UMBRELLA = range(4)
FEATURES = ("user_coffee", "wet")
ROBOTS = ("mobile", "humanoid")
TRUE_SPILL = {"mobile": 0.4, "humanoid": 0.1}
"""True probability that Go spills the coffee while the robot holds coffee and umbrella."""
FACTORS = ("spill", "wet")
"""Factors of the dynamics a belief may change: ``spill`` (Go holding coffee and
umbrella), ``wet`` (Go in the rain without an umbrella)."""


@dataclass(frozen=True)
class CoffeeParams:
    """The probabilities of the coffee world (a person's belief is another instance).

    Attributes:
        spill: P(coffee spilled | Go while holding coffee and umbrella).
        wet: P(robot wet | Go in the rain without an umbrella).
    """

    spill: float
    wet: float = 1.0

    def __post_init__(self):
        for name in FACTORS:
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name} probability must lie in [0, 1], got {p}")


def bits(state) -> np.ndarray:
    """``[..., 6]`` the variables of state ids, in :data:`VARIABLES` order."""
    return (np.asarray(state)[..., None] >> np.arange(len(VARIABLES))) & 1


def state_id(**values) -> int:
    """The id of the state with the given variables (unnamed ones are 0), e.g. ``state_id(raining=1)``."""
    unknown = set(values) - set(VARIABLES)
    if unknown:
        raise ValueError(f"unknown variable(s) {sorted(unknown)}; the variables are {VARIABLES}")
    return int(sum(int(bool(values.get(v, 0))) << i for i, v in enumerate(VARIABLES)))


def _with(b: np.ndarray, **changes) -> int:
    b = b.copy()
    for name, value in changes.items():
        b[VARIABLES.index(name)] = value
    return int((b << np.arange(len(VARIABLES))).sum())


def _outcomes(s: int, a: int):
    """``(factor or None, [(next state, 'event'|'no-event'|None)])`` of one state-action pair.

    The event outcome (spill, wet) comes first; ``factor`` names which probability
    governs the pair (``None``: deterministic).
    """
    b = bits(s)
    if a == GO:
        moved = dict(in_cafe=1 - b[IN_CAFE], wet=0)
        if b[ROBOT_COFFEE] and b[UMBRELLA]:
            return "spill", [_with(b, **moved, robot_coffee=0), _with(b, **moved)]
        if b[RAINING] and not b[UMBRELLA]:
            return "wet", [_with(b, **{**moved, "wet": 1}), _with(b, **moved)]
        return None, [_with(b, **moved)]
    dry = dict(wet=0)
    if a == BUY and b[IN_CAFE] and not b[ROBOT_COFFEE]:
        return None, [_with(b, **dry, robot_coffee=1)]
    if a == DELIVER and not b[IN_CAFE] and b[ROBOT_COFFEE]:
        return None, [_with(b, **dry, robot_coffee=0, user_coffee=1)]
    if a == GET_UMBRELLA:
        return None, [_with(b, **dry, umbrella=1)]
    return None, [_with(b, **dry)]


def coffee_transitions(params: CoffeeParams) -> np.ndarray:
    """``[64, 4, 64]`` transition tensor of the coffee world under ``params``."""
    t = np.zeros((N_STATES, len(ACTIONS), N_STATES))
    for s in range(N_STATES):
        for a in range(len(ACTIONS)):
            factor, nxt = _outcomes(s, a)
            if factor is None:
                t[s, a, nxt[0]] = 1.0
            else:
                p = getattr(params, factor)
                t[s, a, nxt[0]] += p
                t[s, a, nxt[1]] += 1.0 - p
    return t


def coffee_features() -> np.ndarray:
    """``[64, 2]`` features ``(user has coffee, robot wet)``."""
    b = bits(np.arange(N_STATES))
    return np.stack([b[:, USER_COFFEE], b[:, WET]], -1).astype(np.float32)


def start_distribution() -> np.ndarray:
    """``[64]``: in the office, dry, empty-handed; raining with probability 1/2."""
    p = np.zeros(N_STATES)
    p[state_id()] = 0.5
    p[state_id(raining=1)] = 0.5
    return p


def make_coffee(robot: str = "mobile", *, spill: float | None = None, discount: float = 0.9) -> TabularMDP:
    """The true coffee world of a robot type (or of an explicit spill probability).

    Args:
        robot: ``mobile`` or ``humanoid``; picks :data:`TRUE_SPILL`.
        spill: overrides the robot's spill probability.
        discount: ``λ``.
    """
    if robot not in ROBOTS:
        raise ValueError(f"unknown robot type {robot!r}: use one of {', '.join(ROBOTS)}")
    p = CoffeeParams(TRUE_SPILL[robot] if spill is None else spill)
    return TabularMDP(
        transitions=jnp.asarray(coffee_transitions(p), jnp.float32),
        features=jnp.asarray(coffee_features()),
        discount=jnp.asarray(discount, jnp.float32),
        initial=jnp.asarray(start_distribution(), jnp.float32),
    )


class FactorPairs(NamedTuple):
    """Where a factor acts: its ``(s, a)`` pairs and the next state of its event and non-event."""

    states: np.ndarray
    actions: np.ndarray
    event: np.ndarray
    no_event: np.ndarray


def factor_pairs(name: str) -> FactorPairs:
    """The state-action pairs governed by factor ``name`` (``spill`` or ``wet``)."""
    if name not in FACTORS:
        raise ValueError(f"unknown factor {name!r}: use one of {', '.join(FACTORS)}")
    rows = []
    for s in range(N_STATES):
        for a in range(len(ACTIONS)):
            factor, nxt = _outcomes(s, a)
            if factor == name:
                rows.append((s, a, nxt[0], nxt[1]))
    return FactorPairs(*(np.array(c) for c in zip(*rows)))


def event_probability(transitions, name: str = "spill") -> float:
    """Mean probability of a factor's event under ``transitions`` ``[64, 4, 64]`` (e.g. the spill belief).

    Reads any tensor (truth, a person's belief, a per-(s,a) or factored posterior
    mean), averaging over the pairs the factor governs.
    """
    t = np.asarray(transitions)
    pairs = factor_pairs(name)
    return float(t[pairs.states, pairs.actions, pairs.event].mean())


class FactoredLayout(NamedTuple):
    """A factored belief over the coffee world: the arguments of :func:`mindgap.models.belief.factored`.

    Attributes:
        factor: ``[64, 4]`` int32, the learned factor governing each ``(s, a)``, or ``-1``
            for a pair fixed to its true next state.
        targets: ``[64, 4, 2]`` int32, next state of the event and the non-event outcome
            of a learned pair; a fixed pair's true next state in both slots.
        n_outcomes: ``[F]`` int, outcomes of each learned factor (2: a Beta each).
    """

    factor: np.ndarray
    targets: np.ndarray
    n_outcomes: np.ndarray


def factored_layout(learn: tuple[str, ...] = ("spill",), truth: CoffeeParams | None = None) -> FactoredLayout:
    """The layout of GeReL's per-factor belief: one Beta per learned factor, the rest of the world as it is.

    ``mindgap.models.belief.factored(*factored_layout(learn, truth))`` builds the belief space.

    Args:
        learn: factors whose probability the belief learns (:data:`FACTORS`).
        truth: the true probabilities; every pair not governed by a learned factor
            must be deterministic under them (the default truth's wet probability
            is 1, so only ``spill`` needs learning).

    Raises:
        ValueError: an unknown factor, or a stochastic pair left out of ``learn``.
    """
    truth = truth or CoffeeParams(spill=TRUE_SPILL["mobile"])
    learn = tuple(learn)
    for name in learn:
        if name not in FACTORS:
            raise ValueError(f"unknown factor {name!r}: use one of {', '.join(FACTORS)}")
    for name in FACTORS:
        if name not in learn and 0.0 < getattr(truth, name) < 1.0:
            raise ValueError(
                f"the true {name} probability is {getattr(truth, name)}; a factored belief that does not "
                f"learn {name!r} can only hold deterministic dynamics there (learn it too)"
            )
    factor = np.full((N_STATES, len(ACTIONS)), -1, np.int32)
    targets = np.zeros((N_STATES, len(ACTIONS), 2), np.int32)
    for s in range(N_STATES):
        for a in range(len(ACTIONS)):
            name, nxt = _outcomes(s, a)
            if name in learn:
                factor[s, a] = learn.index(name)
                targets[s, a] = nxt
            else:
                # a fixed pair: its true next state (0 and 1 are the two outcomes when stochastic)
                p = 1.0 if name is None else getattr(truth, name)
                targets[s, a] = nxt[0] if p == 1.0 else nxt[-1]
    return FactoredLayout(factor, targets, np.full(len(learn), 2))
