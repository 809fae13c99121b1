"""Planning in tabular MDPs: value iteration, soft value iteration, policies, state visitation."""

from .sparse_value_iteration import sparse_q_values as sparse_q_values
from .sparse_value_iteration import sparse_state_values as sparse_state_values
from .value_iteration import boltzmann_policy as boltzmann_policy
from .value_iteration import q_values as q_values
from .value_iteration import soft_policy as soft_policy
from .value_iteration import soft_q_values as soft_q_values
from .value_iteration import state_values as state_values
from .visitation import state_visitation as state_visitation
