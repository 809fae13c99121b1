"""mindgap: learn what a person wants when that person misjudges how the agent works.

The learners from preferences are one module each: :mod:`mindgap.sac`, :mod:`mindgap.pebble`,
:mod:`mindgap.drlhp`, :mod:`mindgap.prefbias`, :mod:`mindgap.eps` (``full()``/``fast()`` presets
and ``train``); they run on any :class:`World` (:func:`load_world`, or your own).
"""

from . import rng as rng
from .algorithms.gerel import GeReLConfig as GeReLConfig
from .algorithms.gerel import fit_gerel as fit_gerel
from .envs.coffee import make_coffee as make_coffee
from .envs.grid import move_targets as move_targets
from .envs.interface import Box as Box
from .envs.interface import Discrete as Discrete
from .envs.interface import Env as Env
from .envs.interface import Step as Step
from .envs.interface import World as World
from .envs.resolve import resolve_env as load_world  # noqa: F401 (the public name of resolve_env)
from .envs.tabular import TabularMDP as TabularMDP
from .feedback.demos import random_demonstrations as random_demonstrations
from .metrics import all_metrics as all_metrics
from .models.belief import factored as factored
from .models.belief import per_state_action as per_state_action
from .models.belief import tied as tied
from .planning.grid_task import make_grid as make_grid
from .teachers.rating import RatingTeacher as RatingTeacher

__version__ = "0.1.0"

__all__ = [
    "all_metrics",
    "Box",
    "Discrete",
    "Env",
    "factored",
    "fit_gerel",
    "GeReLConfig",
    "load_world",
    "make_coffee",
    "make_grid",
    "move_targets",
    "per_state_action",
    "random_demonstrations",
    "RatingTeacher",
    "rng",
    "Step",
    "TabularMDP",
    "tied",
    "World",
]
