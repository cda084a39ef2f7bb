"""Controller tuning: the frequency approach and the time approach (step responses)."""

from .frequency import (TuningTargets, TuningResult, equivalent_delay, require_tunable, rigid_velocity_pi, rigid_position_gain, tune_frequency)
from .time import TimeTargets, StepResponse, TimeTuningResult, velocity_step, position_step, tune_time

__all__ = [
    "TuningTargets",
    "TuningResult",
    "equivalent_delay",
    "require_tunable",
    "rigid_velocity_pi",
    "rigid_position_gain",
    "tune_frequency",
    "TimeTargets",
    "StepResponse",
    "TimeTuningResult",
    "velocity_step",
    "position_step",
    "tune_time",
]
