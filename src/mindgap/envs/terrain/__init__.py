"""Continuous 2-D terrain worlds (§3.4.2.1, §4.4.1): ice, sand, pits, walls; pure JAX, exact densities."""

from ..interface import Step as Step
from .dynamics import log_prob_pos as log_prob_pos
from .dynamics import sample_next as sample_next
from .files import NAMED_WORLDS as NAMED_WORLDS
from .files import load_world as load_world
from .files import world_from_dict as world_from_dict
from .layout import TERRAINS as TERRAINS
from .layout import Layout as Layout
from .layout import LayoutError as LayoutError
from .layout import parse_layout as parse_layout
from .params import Dynamics as Dynamics
from .params import Rewards as Rewards
from .params import TerrainParams as TerrainParams
from .params import TerrainState as TerrainState
from .world import TERRAIN_ENV as TERRAIN_ENV
from .world import TerrainWorld as TerrainWorld
from .world import log_prob as log_prob
from .world import observe as observe
from .world import position as position
from .world import reset as reset
from .world import reward as reward
from .world import step as step

__all__ = [
    "Dynamics",
    "Layout",
    "LayoutError",
    "load_world",
    "log_prob",
    "log_prob_pos",
    "NAMED_WORLDS",
    "observe",
    "parse_layout",
    "position",
    "reset",
    "reward",
    "Rewards",
    "sample_next",
    "step",
    "Step",
    "TERRAIN_ENV",
    "TerrainParams",
    "TERRAINS",
    "TerrainState",
    "TerrainWorld",
    "world_from_dict",
]
