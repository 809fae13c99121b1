"""The pytrees a terrain world is made of: dynamics table, rewards, world parameters, state.

Everything a jitted function needs is an array leaf, so many worlds (or many beliefs of
one world) stack along a leading axis and ``jax.vmap`` steps them together.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .layout import PIT, TERRAINS, Layout, geodesic_distance

FAR = 1e6  # stands in for "no pit" and "unreachable" so that no inf − inf reaches a gradient
WALL_RULES = ("bump", "slide")


class Dynamics(NamedTuple):
    """A dynamics table: the true one of a world, or a person's belief about it (§3.2).

    Per terrain (rows in the order of :data:`~mindgap.envs.terrain.layout.TERRAINS`:
    floor, ice, sand, pit, goal):

    Attributes:
        speed: [5] the intended displacement is ``0.5 · speed · action`` (cells).
        noise: [5] standard deviation of the Gaussian noise added to the displacement.
        stuck: [5] probability that the step does not move at all.
        pit_noise: extra noise ``pit_noise · exp(−d / pit_scale)`` at distance ``d`` (cells)
            from the nearest pit; 0 switches it off.
        pit_scale: length scale of that extra noise (cells, > 0).
        slide: 1 if a move that would end in a wall ends at the wall's face instead
            (``walls = "slide"``: the Gaussian truncated to the open cells), 0 if it bumps
            and stays put (``walls = "bump"``, the default). See
            :mod:`~mindgap.envs.terrain.dynamics`.
    """

    speed: jax.Array
    noise: jax.Array
    stuck: jax.Array
    pit_noise: jax.Array
    pit_scale: jax.Array
    slide: jax.Array = np.float64(0.0)

    @classmethod
    def from_dict(cls, table: dict, base: Dynamics | None = None) -> Dynamics:
        """Build a table from ``{terrain: {speed, noise, stuck}, pit_noise, pit_scale, walls}``.

        Entries missing from ``table`` are taken from ``base`` (a belief usually changes a
        few numbers of the true table); without a base every terrain defaults to
        ``speed 1, noise 0.05, stuck 0``, the pit term to off and ``walls`` to ``"bump"``.
        """
        if base is None:
            n = len(TERRAINS)
            base = cls(np.ones(n), np.full(n, 0.05), np.zeros(n), np.float64(0.0), np.float64(0.5), np.float64(0.0))
        speed, noise, stuck = (np.array(x, dtype=np.float64) for x in (base.speed, base.noise, base.stuck))
        known = set(TERRAINS) | {"pit_noise", "pit_scale", "walls"}
        for name, value in table.items():
            if name not in known:
                raise ValueError(f"unknown dynamics entry {name!r}: expected one of {', '.join(sorted(known))}")
            if name in TERRAINS:
                if not isinstance(value, dict):
                    raise ValueError(f"dynamics entry {name!r} must be a table of speed, noise, stuck")
                i = TERRAINS.index(name)
                for field, arr in (("speed", speed), ("noise", noise), ("stuck", stuck)):
                    if field in value:
                        arr[i] = float(value[field])
                extra = set(value) - {"speed", "noise", "stuck"}
                if extra:
                    raise ValueError(f"dynamics entry {name!r}: unknown field(s) {', '.join(sorted(extra))}")
        pit_noise = float(table.get("pit_noise", base.pit_noise))
        pit_scale = float(table.get("pit_scale", base.pit_scale))
        slide = float(base.slide)
        if "walls" in table:
            if table["walls"] not in WALL_RULES:
                raise ValueError(f"walls must be one of {', '.join(WALL_RULES)}, got {table['walls']!r}")
            slide = float(table["walls"] == "slide")
        dyn = cls(speed, noise, stuck, np.float64(pit_noise), np.float64(pit_scale), np.float64(slide))
        dyn.check()
        return dyn

    def check(self) -> None:
        """Raise ValueError on values no transition model can have."""
        speed, noise, stuck = (np.asarray(x) for x in (self.speed, self.noise, self.stuck))
        for i, name in enumerate(TERRAINS):
            if not 0 <= speed[i] <= 1:
                raise ValueError(f"{name}: speed must be in [0, 1], got {speed[i]}")
            if not noise[i] > 0:
                raise ValueError(f"{name}: noise must be positive (the density needs it), got {noise[i]}")
            if not 0 <= stuck[i] < 1:
                raise ValueError(f"{name}: stuck must be in [0, 1), got {stuck[i]}")
        if float(self.pit_noise) < 0 or not float(self.pit_scale) > 0:
            raise ValueError("pit_noise must be ≥ 0 and pit_scale > 0")

    def as_dict(self) -> dict:
        out = {
            name: {"speed": float(self.speed[i]), "noise": float(self.noise[i]), "stuck": float(self.stuck[i])}
            for i, name in enumerate(TERRAINS)
        }
        out.update(pit_noise=float(self.pit_noise), pit_scale=float(self.pit_scale))
        if float(self.slide):  # only when on, so records of bump worlds stay as they were
            out["walls"] = "slide"
        return out


class Rewards(NamedTuple):
    """The task's reward, in one of two forms.

    * transition form (``state_form`` = 0, the dissertation's worlds):
      r(s, a, s') = step + progress · (Φ(s) − Φ(s')) + goal·[enter goal] + pit·[enter pit].
      Φ is the geodesic distance to the goal (cells), so ``progress`` rewards how far a step
      brings the agent toward the goal (ch. 4 worlds). Φ is 0 in the goal and in pits, which
      makes the term potential-based shaping: it never changes which episodes are better.
    * state form (``state_form`` = 1): r(s) = step − distance·Φ(s) + goal·[s in the goal] +
      pit·[s in a pit] (Φ taken as 0 in the goal and in pits), a function of where the step starts only. A learner's r_w(s, a) can
      represent it, so a person's preferences separate it from their belief
      (docs/experiments/identifiability.md). ``distance`` makes it dense: every step closer to the goal is
      better, so segments that never reach the goal still differ in reward.
    """

    goal: jax.Array
    pit: jax.Array
    step: jax.Array
    progress: jax.Array
    state_form: jax.Array = np.float32(0.0)
    distance: jax.Array = np.float32(0.0)


class TerrainParams(NamedTuple):
    """Everything the functional API needs about one world.

    Attributes:
        grid: [H, W] int32 terrain codes.
        potential: [H, W] geodesic distance of each cell centre to the goal (FAR where none).
        pits: [P, 2] (row, col) of pit cells, at least one row (FAR when the world has none).
        starts: [n, 2] (row, col) of start cells.
        dynamics: the transition table (swap it for a belief).
        rewards: the reward specification.
        horizon: episode length (steps).
        start_jitter: a start position is the centre of a start cell ± this much per axis.
        fixed_horizon: 0 if entering the goal or a pit ends the episode; 1 for a fixed horizon,
            where the goal is a region the agent may stay in and a pit traps it until the horizon.
    """

    grid: jax.Array
    potential: jax.Array
    pits: jax.Array
    starts: jax.Array
    dynamics: Dynamics
    rewards: Rewards
    horizon: jax.Array
    start_jitter: jax.Array
    fixed_horizon: jax.Array = np.float32(0.0)

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.grid.shape[-2:])

    def with_dynamics(self, dynamics: Dynamics) -> TerrainParams:
        """The same world under another dynamics table (e.g. a person's belief)."""
        return self._replace(dynamics=as_arrays(dynamics))


class TerrainState(NamedTuple):
    """pos: [2] (x, y) in cells; t: steps taken; done: the episode has ended."""

    pos: jax.Array
    t: jax.Array
    done: jax.Array


def as_arrays(dyn: Dynamics) -> Dynamics:
    return Dynamics(*(jnp.asarray(x, dtype=jnp.float32) for x in dyn))


def make_params(
    layout: Layout,
    dynamics: Dynamics,
    rewards: Rewards,
    horizon: int,
    start_jitter: float = 0.2,
    fixed_horizon: bool = False,
) -> TerrainParams:
    """Assemble the arrays of a world from its parsed layout (host side, once)."""
    dynamics.check()
    if horizon < 1:
        raise ValueError(f"horizon must be at least 1, got {horizon}")
    if not 0 <= start_jitter < 0.5:
        raise ValueError(f"start_jitter must be in [0, 0.5), got {start_jitter}")
    pot = geodesic_distance(layout.grid)
    pits = layout.cells(PIT).astype(np.float32)
    if len(pits) == 0:
        pits = np.full((1, 2), -FAR, np.float32)
    return TerrainParams(
        grid=jnp.asarray(layout.grid, jnp.int32),
        potential=jnp.asarray(np.where(np.isfinite(pot), pot, FAR), jnp.float32),
        pits=jnp.asarray(pits),
        starts=jnp.asarray(layout.starts, jnp.int32),
        dynamics=as_arrays(dynamics),
        rewards=Rewards(*(jnp.asarray(float(x), jnp.float32) for x in rewards)),
        horizon=jnp.asarray(horizon, jnp.int32),
        start_jitter=jnp.asarray(start_jitter, jnp.float32),
        fixed_horizon=jnp.asarray(float(fixed_horizon), jnp.float32),
    )
