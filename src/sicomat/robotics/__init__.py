"""Robotics formalism (issue 13): multi-body machines described in modified Denavit–Hartenberg
parameters (SYMORO's tables), their geometric, kinematic and dynamic models (numpy), and the same
models in SymPy with their code export (imported on first use: SymPy takes ~0.5 s to import)."""

import importlib
from typing import TYPE_CHECKING, Any

from .base import BaseParameters, base_parameters
from .dynamics import (direct_dynamics, inertia_matrix, inverse_dynamics, inverse_dynamics_batch, regressor,
                       regressor_batch)
from .dynamics import inertia_matrix_batch
from .elastic import (HybridDynamics, elastic_direct_dynamics, elastic_joints, elastic_torques, hybrid_dynamics,
                      rigid_joints)
from .geometry import jacobian, transform, transforms
from .loops import (active_joints, closed_loop_inertia_matrix, closed_loop_inverse_dynamics, closure_error,
                    constraint_jacobian, independent_jacobian, independent_joints, loop_frames, loop_jacobian,
                    loop_states, passive_joints, solve_closure)
from .table import FRAME_FIELDS, PARAMETER_FIELDS, MDHRobot

if TYPE_CHECKING:
    from .codegen import symbolic_export
    from .symbolic import SymbolicModel, SymbolicModels, symbolic_models

_LAZY = {"symbolic_models": "symbolic", "SymbolicModels": "symbolic", "SymbolicModel": "symbolic",
         "symbolic_export": "codegen"}

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
    "independent_joints",
    "passive_joints",
    "closure_error",
    "loop_jacobian",
    "solve_closure",
    "constraint_jacobian",
    "independent_jacobian",
    "loop_states",
    "closed_loop_inverse_dynamics",
    "closed_loop_inertia_matrix",
    "symbolic_models",
    "SymbolicModels",
    "SymbolicModel",
    "symbolic_export",
]


def __getattr__(name: str) -> Any:
    try:
        module = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value
