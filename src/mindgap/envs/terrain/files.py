"""Terrain worlds from TOML files; the six worlds of the dissertation ship as such files.

A world file::

    name = "corridors"
    description = "what it tests"
    horizon = 100                 # steps per episode
    episode_ends = true           # optional: false for a fixed horizon (the goal a region to stay
                                  # in, a pit a trap until the horizon; equal-length episodes)
    start_jitter = 0.2            # optional, cells
    layout = '''
    #######
    #S.~.G#
    #######
    '''

    [rewards]                     # r = step + progress·(Φ(s) − Φ(s')) + goal/pit on entry
    form = "transition"           # or "state": r(s) = step − distance·Φ(s) + goal·[s in goal] + pit·[s in pit]
    goal = 10.0
    pit = -10.0
    step = -1.0
    progress = 0.0

    [dynamics]                    # the true table; unspecified entries: speed 1, noise 0.05, stuck 0
    sand = { speed = 0.5, noise = 0.05, stuck = 0.5 }
    pit_noise = 0.0
    pit_scale = 0.5
    walls = "bump"                # or "slide": a push into a wall ends at its face (dynamics.py)

    [beliefs.human]               # a person's table: entries not given are the true ones
    ice = { speed = 0.3, noise = 0.3 }

    [expect]                      # optional: what the planning check must show
    true_prefers = "ice"          # the optimal route spends more steps on ice than on sand
    belief_prefers = "sand"       # the route the person expects: more on sand
    wider_berth = 0.5             # the expected route keeps ≥ 0.5 cell farther from pits
    person_prefers = "expected"   # the person's Σ[r + log T_H] favours the expected route as driven
    eps_route = "sand"            # the route EPS should take (ch. 4): ice, sand or detour
                                  # (a berth around the pit wider than the optimal route's);
                                  # judged by `mindgap reproduce eps`, not the planning check

Wherever a world is named (``--world NAME``), a path to such a file works too.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from .layout import LayoutError, parse_layout
from .params import Dynamics, Rewards, make_params
from .world import TerrainWorld

NAMED_WORLDS = ("nav1", "nav2", "d1", "d2", "d3", "d4", "nav1-v1", "nav2-v1", "d3-v1")
_KEYS = {
    "name",
    "description",
    "horizon",
    "episode_ends",
    "start_jitter",
    "layout",
    "rewards",
    "dynamics",
    "beliefs",
    "expect",
}
REWARD_FORMS = ("transition", "state")
EXPECT_KEYS = {"true_prefers", "belief_prefers", "wider_berth", "eps_route", "person_prefers", "obeying"}
EPS_ROUTES = ("ice", "sand", "detour")


def world_from_dict(spec: dict, source: str | None = None) -> TerrainWorld:
    """Build a world from the parsed contents of a world file."""
    where = f"{source}: " if source else ""
    unknown = set(spec) - _KEYS
    if unknown:
        raise ValueError(f"{where}unknown key(s) {', '.join(sorted(unknown))}; expected {', '.join(sorted(_KEYS))}")
    for key in ("layout", "horizon"):
        if key not in spec:
            raise ValueError(f"{where}missing {key!r}")
    try:
        layout = parse_layout(spec["layout"])
    except LayoutError as e:
        raise LayoutError(f"{where}layout: {e}") from None
    rw = dict(spec.get("rewards", {}))
    form = rw.pop("form", "transition")
    bad = set(rw) - (set(Rewards._fields) - {"state_form"})
    if bad:
        raise ValueError(f"{where}[rewards]: unknown key(s) {', '.join(sorted(bad))}")
    if form not in REWARD_FORMS:
        raise ValueError(f"{where}[rewards] form must be one of {', '.join(REWARD_FORMS)}, got {form!r}")
    if form == "state" and float(rw.get("progress", 0.0)) != 0.0:
        raise ValueError(f"{where}[rewards] progress depends on the next state; a state-form reward cannot have it")
    if form != "state" and float(rw.get("distance", 0.0)) != 0.0:
        raise ValueError(f'{where}[rewards] distance is a term of the state form (form = "state"); use progress')
    ends = spec.get("episode_ends", True)
    if not isinstance(ends, bool):
        raise ValueError(f"{where}episode_ends must be true or false, got {ends!r}")
    rewards = Rewards(
        goal=float(rw.get("goal", 0.0)),
        pit=float(rw.get("pit", 0.0)),
        step=float(rw.get("step", 0.0)),
        progress=float(rw.get("progress", 0.0)),
        state_form=float(form == "state"),
        distance=float(rw.get("distance", 0.0)),
    )
    try:
        true = Dynamics.from_dict(spec.get("dynamics", {}))
        beliefs = {name: Dynamics.from_dict(table, base=true) for name, table in spec.get("beliefs", {}).items()}
        params = make_params(
            layout,
            true,
            rewards,
            horizon=int(spec["horizon"]),
            start_jitter=float(spec.get("start_jitter", 0.2)),
            fixed_horizon=not ends,
        )
    except ValueError as e:
        raise ValueError(f"{where}{e}") from None
    expect = dict(spec.get("expect", {}))
    bad = set(expect) - EXPECT_KEYS
    if bad:
        raise ValueError(
            f"{where}[expect]: unknown key(s) {', '.join(sorted(bad))}; known: {', '.join(sorted(EXPECT_KEYS))}"
        )
    for key in ("true_prefers", "belief_prefers"):
        if key in expect and expect[key] not in ("ice", "sand"):
            raise ValueError(f"{where}[expect] {key} must be 'ice' or 'sand', got {expect[key]!r}")
    if "person_prefers" in expect and expect["person_prefers"] != "expected":
        raise ValueError(f"{where}[expect] person_prefers must be 'expected', got {expect['person_prefers']!r}")
    if "obeying" in expect and expect["obeying"] not in ("arrives", "fails"):
        raise ValueError(f"{where}[expect] obeying must be 'arrives' or 'fails', got {expect['obeying']!r}")
    if "eps_route" in expect and expect["eps_route"] not in EPS_ROUTES:
        raise ValueError(
            f"{where}[expect] eps_route must be one of {', '.join(EPS_ROUTES)}, got {expect['eps_route']!r}"
        )
    name = spec.get("name") or (Path(source).stem if source else "world")
    return TerrainWorld(name, layout, params, beliefs, spec.get("description", "").strip(), source, expect)


def load_world(name_or_path: str | Path) -> TerrainWorld:
    """A named world (``nav1`` … ``d4``) or a world file.

    Raises:
        ValueError: neither a named world nor a readable world file, or a malformed file.
    """
    text = str(name_or_path)
    if text in NAMED_WORLDS:
        ref = resources.files("mindgap.envs.terrain") / "worlds" / f"{text}.toml"
        return world_from_dict(tomllib.loads(ref.read_text()), source=f"{text}.toml")
    path = Path(text)
    if not path.is_file():
        raise ValueError(f"unknown world {text!r}: not one of {', '.join(NAMED_WORLDS)} and no such file")
    try:
        spec = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: not valid TOML: {e}") from None
    return world_from_dict(spec, source=str(path))
