"""Robotics formalism (issue 13): multi-body machines described in modified Denavit–Hartenberg
parameters (SYMORO's tables), their geometric, kinematic and dynamic models (numpy)."""

from .base import BaseParameters, base_parameters
from .codegen import symbolic_export
from .dynamics import (direct_dynamics, inertia_matrix, inverse_dynamics, inverse_dynamics_batch, regressor,
                       regressor_batch)
from .dynamics import inertia_matrix_batch
from .geometry import jacobian, transform, transforms
from .symbolic import SymbolicModel, SymbolicModels, symbolic_models
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
    "symbolic_models",
    "SymbolicModels",
    "SymbolicModel",
    "symbolic_export",
]
