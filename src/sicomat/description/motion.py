"""Schema of the motion blocks: the setpoint generator of one axis (step, ramp, trapezoid, S-curve)
and the machine's path interpolator."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import ConfigDict, Field

from .base import NonNegativeTime, Spec, quantity
from .registry import SetpointKind, register, spec_union

__all__ = ["StepSetpoint", "RampSetpoint", "TrapezoidSetpoint", "SCurveSetpoint", "SetpointSpec", "InterpolatorSpec"]


@register("setpoint")
class StepSetpoint(Spec):
    """A position step of ``distance`` at ``start`` (s)."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "step", "distance": "2 mm", "start": "10 ms"}, {"type": "step", "distance": -0.5}]})

    type: Literal["step"]
    distance: Annotated[float, quantity("length")]
    start: NonNegativeTime = 0.0


@register("setpoint")
class RampSetpoint(Spec):
    """A constant-velocity ramp starting at ``start`` (position grows at ``velocity``)."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "ramp", "velocity": "3 m/min", "start": "4 ms"}]})

    type: Literal["ramp"]
    velocity: Annotated[float, quantity("velocity")]
    start: NonNegativeTime = 0.0


@register("setpoint")
class TrapezoidSetpoint(Spec):
    """A point-to-point move with a trapezoidal velocity profile (acceleration-limited)."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "trapezoid", "distance": "100 mm", "max_velocity": "1 m/s", "max_acceleration": "5 m/s^2"},
        {"type": "trapezoid", "distance": "-1 mm", "max_velocity": "1 m/s", "max_acceleration": "5 m/s^2",
         "start": "5 ms"}]})  # the second is triangular (v_max not reached)

    type: Literal["trapezoid"]
    distance: Annotated[float, quantity("length")]
    max_velocity: Annotated[float, quantity("velocity"), Field(gt=0)]
    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)]
    start: NonNegativeTime = 0.0


@register("setpoint")
class SCurveSetpoint(Spec):
    """A jerk-limited (7-segment S-curve), time-optimal point-to-point move."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "s-curve", "distance": "50 mm", "max_velocity": "0.2 m/s", "max_acceleration": "3 m/s^2",
         "max_jerk": "100 m/s^3", "start": "2 ms"},
        {"type": "s-curve", "distance": "-0.2 mm", "max_velocity": "0.2 m/s", "max_acceleration": "3 m/s^2",
         "max_jerk": "100 m/s^3"}]})  # the second reaches neither limit

    type: Literal["s-curve"]
    distance: Annotated[float, quantity("length")]
    max_velocity: Annotated[float, quantity("velocity"), Field(gt=0)]
    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)]
    max_jerk: Annotated[float, quantity("jerk"), Field(gt=0)]
    start: NonNegativeTime = 0.0


# a new setpoint type: one registered class above this line, and its lowering in motion/setpoints.py
if TYPE_CHECKING:  # a type checker sees the protocol, pydantic the discriminated union
    SetpointSpec = SetpointKind
else:
    SetpointSpec = spec_union("setpoint")
"""Any registered setpoint generator, chosen by ``type`` (step, ramp, trapezoid, s-curve)."""


class InterpolatorSpec(Spec):
    """The CNC's path interpolator (machine level): limits along the path for lines, arcs and G-code.

    It runs at the position-loop period of the first axis it moves.
    """

    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)] = 2.0
    max_jerk: Annotated[float, quantity("jerk"), Field(gt=0)] = 50.0
    rapid_feed: Annotated[float, quantity("velocity"), Field(gt=0)] = 0.25
    corner_tolerance: Annotated[float, quantity("angle"), Field(ge=0)] = 1e-3
