"""SICOMAT: SImulation and COntrol analysis of MAchine Tool axes.

The pipeline's verbs and results, stage by stage (``docs/architecture.md``)::

    machine = sicomat.load_model("examples/paper_5m4s.toml")        # description + io
    mech = sicomat.build_mechanics(machine.axis().mechanics)         # mechanics
    modes = sicomat.modal_analysis(mech)
    loop = sicomat.build_servo_loop(machine.axis())                  # servo
    run = sicomat.simulate(loop, sicomat.step_profile(1e-3), 0.1)    # simulation
    margins = sicomat.stability_margins(sicomat.loop_response(loop, "velocity-open"))   # frequency
    reduced = sicomat.reduce(machine, "balanced", order=4)           # reduction

Names are imported on first use (PEP 562), so ``import sicomat`` stays light (no numba, no scipy until
asked) and the command line starts fast; each stage's subpackage re-exports its own public names.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> subpackage that defines it
_EXPORTS: dict[str, str] = {
    # errors
    "SicomatError": "errors", "ModelError": "errors", "AnalysisError": "errors", "ResourceError": "errors",
    "OutputError": "errors",
    # description
    "Machine": "description", "Axis": "description", "LumpedSpec": "description", "ChainSpec": "description",
    "BeltRackSpec": "description", "Body": "description", "Coupling": "description", "Friction": "description",
    "Actuator": "description", "Sensor": "description", "DriveSpec": "description",
    "ControllerSpec": "description",
    # io
    "load_model": "io", "save_model": "io", "dump_model": "io", "machine_from_dict": "io",
    "with_overrides": "io",
    # lti
    "Plant": "lti", "FrequencyResponse": "lti",
    # mechanics
    "Mechanics": "mechanics", "Dof": "mechanics", "build_mechanics": "mechanics", "mechanics_plant": "mechanics",
    "ModalResult": "mechanics", "Mode": "mechanics", "modal_analysis": "mechanics",
    # motion
    "Profile": "motion", "step_profile": "motion", "ramp_profile": "motion", "trapezoid_profile": "motion",
    "scurve_profile": "motion", "profile_from_spec": "motion",
    # servo
    "ServoLoop": "servo", "build_servo_loop": "servo", "Verdict": "servo", "loop_verdict": "servo",
    "CoupledLoop": "servo",
    # simulation
    "simulate": "simulation", "simulate_batch": "simulation", "TimeSeries": "simulation", "StepMetrics": "simulation",
    "StepFigures": "simulation", "step_figures": "simulation",
    # (the paths module imports servo/: not imported by the simulation package itself)
    "simulate_path": "simulation.paths", "circle_test": "simulation.paths", "PathRun": "simulation.paths",
    "CircleTest": "simulation.paths",
    "simulate_coupled": "simulation.coupled", "CoupledRun": "simulation.coupled",
    # frequency
    "LoopAnalysis": "frequency", "Margins": "frequency",
    "stability_margins": "frequency", "closed_loop": "frequency", "sensitivity": "frequency",
    "closed_loop_bandwidth": "frequency", "loop_response": "frequency",
    # tuning
    "tune_frequency": "tuning", "tune_time": "tuning", "TuningResult": "tuning", "TimeTuningResult": "tuning",
    "TuningTargets": "tuning", "TimeTargets": "tuning",
    # reduction
    "ReductionResult": "reduction", "modal_truncation": "reduction",
    "balanced_truncation": "reduction", "physical_reduction": "reduction", "reduce": "reduction",
    # tasks (issue 12: the mode map over the stroke)
    "mode_map": "tasks", "ModeMap": "tasks", "tune_over_stroke": "tasks", "StrokeTuning": "tasks",
}

__all__ = ["__version__", *_EXPORTS]


_SUBPACKAGES = ("robotics", "catalogue")
"""Subpackages reached as attributes without their own import (``sicomat.robotics.MDHRobot``), loaded
on first use like the names above."""


def __getattr__(name: str) -> Any:
    if name in _SUBPACKAGES:
        module = importlib.import_module(f".{name}", __name__)
        globals()[name] = module
        return module
    try:
        package = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'sicomat' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{package}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS) | set(_SUBPACKAGES))


if TYPE_CHECKING:  # the static view of the same names (mypy, IDEs)
    from .description import (Actuator, Axis, BeltRackSpec, Body, ChainSpec, ControllerSpec, Coupling, DriveSpec, Friction, LumpedSpec, Machine, Sensor)
    from .errors import AnalysisError, ModelError, OutputError, ResourceError, SicomatError
    from .frequency import (LoopAnalysis, Margins, closed_loop, closed_loop_bandwidth, loop_response, sensitivity, stability_margins)
    from .io import dump_model, load_model, machine_from_dict, save_model, with_overrides
    from .lti import FrequencyResponse, Plant
    from .mechanics import Dof, Mechanics, ModalResult, Mode, build_mechanics, mechanics_plant, modal_analysis
    from .motion import (Profile, profile_from_spec, ramp_profile, scurve_profile, step_profile, trapezoid_profile)
    from .reduction import ReductionResult, balanced_truncation, modal_truncation, physical_reduction, reduce
    from .servo import CoupledLoop, ServoLoop, Verdict, build_servo_loop, loop_verdict
    from .simulation import StepFigures, StepMetrics, TimeSeries, simulate, simulate_batch, step_figures
    from .simulation.paths import CircleTest, PathRun, circle_test, simulate_path
    from .simulation.coupled import CoupledRun, simulate_coupled
    from .tuning import TimeTargets, TimeTuningResult, TuningResult, TuningTargets, tune_frequency, tune_time
    from .tasks import ModeMap, StrokeTuning, mode_map, tune_over_stroke
