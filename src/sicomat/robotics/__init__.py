"""Robotics formalism (issue 13): multi-body machines described in modified Denavit–Hartenberg
parameters (SYMORO's tables), their geometric, kinematic and dynamic models (numpy)."""

from .base import BaseParameters, base_parameters
from .dynamics import (direct_dynamics, inertia_matrix, inverse_dynamics, inverse_dynamics_batch, regressor,
                       regressor_batch)
from .dynamics import inertia_matrix_batch
from .elastic import (HybridDynamics, elastic_direct_dynamics, elastic_joints, elastic_torques, hybrid_dynamics,
                      rigid_joints)
from .geometry import jacobian, transform, transforms
from .loops import (active_joints, closed_loop_inertia_matrix, closed_loop_inverse_dynamics, closure_error,
                    constraint_jacobian, loop_frames, loop_jacobian, loop_states, passive_joints, solve_closure)
from .table import FRAME_FIELDS, PARAMETER_FIELDS, MDHRobot

__all__ = [
    "MDHRobot",
    "FRAME_FIELDS",
    "PARAMETER_FIELDS",
    "transform",
    "transforms",
    "jacobian",
    "inverse_dynamics",
    "inverse_dynamics_batch",
    "inertia_matrix",
    "inertia_matrix_batch",
    "direct_dynamics",
    "regressor",
    "regressor_batch",
    "base_parameters",
    "BaseParameters",
    "hybrid_dynamics",
    "HybridDynamics",
    "elastic_direct_dynamics",
    "elastic_torques",
    "elastic_joints",
    "rigid_joints",
    "loop_frames",
    "active_joints",
    "passive_joints",
    "closure_error",
    "loop_jacobian",
    "solve_closure",
    "constraint_jacobian",
    "loop_states",
    "closed_loop_inverse_dynamics",
    "closed_loop_inertia_matrix",
]
