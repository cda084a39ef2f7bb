"""The servo blocks and the loop (stage 3): drive, discrete controller blocks, analog loops, the
servo loop and its lowering, coupled axes on one mechanics, the stability verdict."""

from .analog import AnalogLoop, analog_loop
from .controller import DiscreteSS, velocity_law, filter_block, difference_block, continuous_filter
from .drive import DriveModel
from .blocks import (DriveKind, ControllerKind, DRIVES, CONTROLLERS, drive_kind, drive_model, FirstOrderDrive, PIController, IPController, TransferFunctionController, linear_law, loop_delays)
from .linear import LoopModel
from .loop import ServoLoop, build_servo_loop, servo_plant, drives_plant, servo_program, SetpointTable, derived_signals
from .coupled import CoupledLoop, coupled_plant, coupled_program
from .stability import (GROWTH_TOLERANCE, LoopPoles, Verdict, position_closed_loop, loop_poles, loop_verdict, combine)

__all__ = [
    "AnalogLoop",
    "analog_loop",
    "DiscreteSS",
    "velocity_law",
    "filter_block",
    "difference_block",
    "continuous_filter",
    "DriveModel",
    "drive_model",
    "DriveKind",
    "ControllerKind",
    "DRIVES",
    "CONTROLLERS",
    "drive_kind",
    "FirstOrderDrive",
    "PIController",
    "IPController",
    "TransferFunctionController",
    "linear_law",
    "loop_delays",
    "LoopModel",
    "ServoLoop",
    "build_servo_loop",
    "servo_plant",
    "drives_plant",
    "servo_program",
    "SetpointTable",
    "derived_signals",
    "CoupledLoop",
    "coupled_plant",
    "coupled_program",
    "GROWTH_TOLERANCE",
    "LoopPoles",
    "Verdict",
    "position_closed_loop",
    "loop_poles",
    "loop_verdict",
    "combine",
]
