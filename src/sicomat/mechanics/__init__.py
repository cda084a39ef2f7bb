"""Lumped mechanics (stage 2): M, D, K from the description, the state space of the mechanics,
modal analysis and the numerical-meaning checks."""

from .conditioning import check_numeric_range, check_resolvable, COEFFICIENT_RANGE
from .lumped import Dof, Link, Load, Measurement, Mechanics, build_mechanics, check_axis_mechanics
from .modal import Mode, ModalResult, modal_analysis
from .statespace import MassFactor, mechanics_plant, second_order_input, second_order_state_space

__all__ = [
    "check_numeric_range",
    "check_resolvable",
    "check_axis_mechanics",
    "COEFFICIENT_RANGE",
    "Dof",
    "Link",
    "Load",
    "Measurement",
    "Mechanics",
    "build_mechanics",
    "Mode",
    "ModalResult",
    "modal_analysis",
    "mechanics_plant",
    "MassFactor",
    "second_order_state_space",
    "second_order_input",
]
