"""The autonomous-driving scenario of §4.4.2 (Figs. 32–36): a front car brakes hard on a sleety highway.

Pure JAX (:mod:`.world`, :mod:`.kinematics`, :mod:`.sleet`, :mod:`.reward`), and the same
scenario in highway-env as the reference that draws it (:mod:`.highway`, imported only when used;
``pip install mindgap[driving]``).
"""

from .params import ACTIONS as ACTIONS
from .params import FEATURES as FEATURES
from .params import STUDY_IMPORTANCE as STUDY_IMPORTANCE
from .params import DrivingParams as DrivingParams
from .params import DrivingState as DrivingState
from .params import Grip as Grip
from .params import RewardParams as RewardParams
from .params import make_params as make_params
from .reward import importance_weights as importance_weights
from .world import DRIVING_ENV as DRIVING_ENV
from .world import DrivingWorld as DrivingWorld
from .world import advance as advance
from .world import driving_env as driving_env
from .world import log_prob as log_prob
from .world import make_world as make_world
from .world import observe as observe
from .world import reset as reset
from .world import reward as reward
from .world import step as step

__all__ = [
    "ACTIONS",
    "advance",
    "DRIVING_ENV",
    "driving_env",
    "DrivingParams",
    "DrivingState",
    "DrivingWorld",
    "FEATURES",
    "Grip",
    "importance_weights",
    "log_prob",
    "make_params",
    "make_world",
    "observe",
    "reset",
    "reward",
    "RewardParams",
    "step",
    "STUDY_IMPORTANCE",
]
