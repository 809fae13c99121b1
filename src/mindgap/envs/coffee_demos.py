"""The demonstrations of the coffee-robot study (§2.3.2, Fig. 11).

Eight scripted scenarios cover what may happen — a sunny or a rainy day, with or
without the umbrella, spilling the coffee or not — and one sanity-check
demonstration of random actions, which an attentive participant rates lowest. Each
scenario is a list of actions with the outcome of every stochastic step chosen; the
states follow from the true dynamics, so every step has non-zero probability under
both robot types. Spilling needs the umbrella, so the no-umbrella half of the
"spill or not" axis is replaced by the umbrella fetched at the café for the way back.

========================== ===============================================================
demonstration              actions (``!`` the step's event happens: spill or wet)
========================== ===============================================================
sunny-no-umbrella          Go, BuyCoffee, Go, DeliverCoffee
sunny-umbrella             GetUmbrella, Go, BuyCoffee, Go, DeliverCoffee
sunny-umbrella-spill       GetUmbrella, Go, BuyCoffee, Go!, Go, BuyCoffee, Go, DeliverCoffee
sunny-umbrella-back        Go, BuyCoffee, GetUmbrella, Go, DeliverCoffee
rainy-no-umbrella          Go!, BuyCoffee, Go!, DeliverCoffee
rainy-umbrella             GetUmbrella, Go, BuyCoffee, Go, DeliverCoffee
rainy-umbrella-spill       GetUmbrella, Go, BuyCoffee, Go!, Go, BuyCoffee, Go, DeliverCoffee
rainy-umbrella-back        Go!, BuyCoffee, GetUmbrella, Go, DeliverCoffee
sanity-random              8 uniformly random actions (never delivering the coffee)
========================== ===============================================================
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..data.demos import Demonstrations, make_demonstrations
from .coffee import (
    ACTIONS,
    BUY,
    DELIVER,
    GET_UMBRELLA,
    GO,
    N_STATES,
    TRUE_SPILL,
    USER_COFFEE,
    VARIABLES,
    CoffeeParams,
    _outcomes,
    bits,
    state_id,
)

SANITY = "sanity-random"
SCENARIOS: dict[str, tuple[bool, tuple[tuple[int, bool], ...]]] = {
    # name: (raining, ((action, event happens), ...))
    "sunny-no-umbrella": (False, ((GO, False), (BUY, False), (GO, False), (DELIVER, False))),
    "sunny-umbrella": (False, ((GET_UMBRELLA, False), (GO, False), (BUY, False), (GO, False), (DELIVER, False))),
    "sunny-umbrella-spill": (
        False,
        ((GET_UMBRELLA, False), (GO, False), (BUY, False), (GO, True), (GO, False), (BUY, False), (GO, False))
        + ((DELIVER, False),),
    ),
    "sunny-umbrella-back": (False, ((GO, False), (BUY, False), (GET_UMBRELLA, False), (GO, False), (DELIVER, False))),
    "rainy-no-umbrella": (True, ((GO, True), (BUY, False), (GO, True), (DELIVER, False))),
    "rainy-umbrella": (True, ((GET_UMBRELLA, False), (GO, False), (BUY, False), (GO, False), (DELIVER, False))),
    "rainy-umbrella-spill": (
        True,
        ((GET_UMBRELLA, False), (GO, False), (BUY, False), (GO, True), (GO, False), (BUY, False), (GO, False))
        + ((DELIVER, False),),
    ),
    "rainy-umbrella-back": (True, ((GO, True), (BUY, False), (GET_UMBRELLA, False), (GO, False), (DELIVER, False))),
}
"""The eight scenarios of Fig. 8/11: ``(raining, ((action, event happens), ...))``."""


class Trace(NamedTuple):
    """One demonstration as shown to a participant: ``states [n + 1]`` (the last one is where it ends), ``actions [n]``."""

    name: str
    states: tuple[int, ...]
    actions: tuple[int, ...]


def _play(name: str, start: int, script) -> Trace:
    states, actions = [start], []
    for a, event in script:
        factor, nxt = _outcomes(states[-1], a)
        if event is None:  # the likelier outcome under the truth of both robots
            event = factor is not None and getattr(CoffeeParams(max(TRUE_SPILL.values())), factor) > 0.5
        if event and factor is None:
            raise ValueError(f"scenario {name!r}: {ACTIONS[a]} in state {states[-1]} has no event to happen")
        states.append(nxt[0] if event or factor is None else nxt[1])
        actions.append(a)
    return Trace(name, tuple(states), tuple(actions))


def sanity_trace(seed: int = 0, length: int = 8) -> Trace:
    """Random actions from the start (rain or not at random) under the true dynamics.

    Drawn with NumPy's PCG64 from ``seed`` so the same demonstration is shown in every
    run; a draw that happens to deliver the coffee is rejected (the sanity check
    relies on its being the worst demonstration). Stochastic steps take their likelier
    outcome (no spill; wet in the rain without an umbrella).
    """
    rng = np.random.default_rng(seed)
    while True:
        start = state_id(raining=int(rng.integers(2)))
        script = [(int(a), None) for a in rng.integers(len(ACTIONS), size=length)]
        trace = _play(SANITY, start, script)
        if not any(bits(s)[USER_COFFEE] for s in trace.states):
            return trace


def study_traces(sanity_seed: int = 0) -> list[Trace]:
    """The eight scenario demonstrations followed by the sanity check, in the order shown."""
    traces = [_play(name, state_id(raining=int(rain)), script) for name, (rain, script) in SCENARIOS.items()]
    return traces + [sanity_trace(sanity_seed)]


def to_demonstrations(traces: list[Trace]) -> Demonstrations:
    """Pack traces (their ``n`` decisions each) into padded :class:`Demonstrations`."""
    length = max(len(t.actions) for t in traces)
    states = np.zeros((len(traces), length), np.int32)
    actions = np.zeros((len(traces), length), np.int32)
    mask = np.zeros((len(traces), length), bool)
    for i, t in enumerate(traces):
        n = len(t.actions)
        states[i, :n], actions[i, :n], mask[i, :n] = t.states[:-1], t.actions, True
    return make_demonstrations(states, actions, mask, n_states=N_STATES, n_actions=len(ACTIONS))


_PLACE = ("office", "café")


def describe_state(s: int) -> str:
    """A short sentence for a state, e.g. ``"office, raining; dry; holds umbrella, coffee"``."""
    b = dict(zip(VARIABLES, bits(s).tolist()))
    held = [x for x, v in (("umbrella", b["umbrella"]), ("coffee", b["robot_coffee"])) if v]
    parts = [
        f"{_PLACE[b['in_cafe']]}, {'raining' if b['raining'] else 'sunny'}",
        "wet" if b["wet"] else "dry",
        "holds " + (" and ".join(held) if held else "nothing"),
    ]
    if b["user_coffee"]:
        parts.append("you have your coffee")
    return "; ".join(parts)


def _effect(s: int, a: int, s_next: int) -> str:
    b, c = bits(s), bits(s_next)
    if a == GO:
        notes = [f"goes to the {_PLACE[c[0]]}"]
        if c[1]:
            notes.append("gets wet in the rain")
        if b[4] and not c[4]:
            notes.append("SPILLS the coffee")
        return ", ".join(notes)
    if (b == c).all() or (np.delete(b, 1) == np.delete(c, 1)).all():
        return "nothing happens" + (" (dries off)" if b[1] else "")
    return {BUY: "buys a coffee", DELIVER: "hands you the coffee", GET_UMBRELLA: "takes an umbrella"}[a]


def trace_text(trace: Trace, robot: str = "robot") -> str:
    """Step-by-step text of a demonstration, as a participant reads it (Fig. 11)."""
    lines = [f"Demonstration {trace.name} ({robot}): starts in the {describe_state(trace.states[0])}"]
    for k, a in enumerate(trace.actions):
        s, s_next = trace.states[k], trace.states[k + 1]
        lines.append(f"  {k + 1}. {ACTIONS[a]:<13} -> {_effect(s, a, s_next)}  [{describe_state(s_next)}]")
    return "\n".join(lines)
