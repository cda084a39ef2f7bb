"""SICOMAT: SImulation and COntrol analysis of MAchine Tool axes."""

from .errors import AnalysisError, ModelError, ResourceError, SicomatError
from .mechanics import Dof, Mechanics, build_mechanics
from .modal import ModalResult, Mode, modal_analysis
from .model import (Actuator, Axis, BeltRackSpec, Body, ChainSpec, Coupling, Friction, LumpedSpec,
                    Machine, Sensor)
from .modelfile import dump_model, load_model, machine_from_dict, save_model, with_overrides
from .margins import Margins, closed_loop, sensitivity, stability_margins
from .plant import Plant, mechanics_plant

__version__ = "0.1.0"

__all__ = [
    "SicomatError", "ModelError", "AnalysisError", "ResourceError",
    "Machine", "Axis", "LumpedSpec", "ChainSpec", "BeltRackSpec", "Body", "Coupling", "Friction",
    "Actuator", "Sensor",
    "load_model", "save_model", "dump_model", "machine_from_dict", "with_overrides",
    "Mechanics", "Dof", "build_mechanics",
    "Plant", "mechanics_plant",
    "ModalResult", "Mode", "modal_analysis",
    "Margins", "stability_margins", "closed_loop", "sensitivity",
]
