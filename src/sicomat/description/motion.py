"""Schema of the motion blocks: the setpoint generator of one axis (step, ramp, trapezoid, S-curve)
and the machine's path interpolator."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field

from .base import NonNegativeTime, Spec, quantity

__all__ = ["StepSetpoint", "RampSetpoint", "TrapezoidSetpoint", "SCurveSetpoint", "SetpointSpec", "InterpolatorSpec"]


class StepSetpoint(Spec):
    """A position step of ``distance`` at ``start`` (s)."""

    type: Literal["step"]
    distance: Annotated[float, quantity("length")]
    start: NonNegativeTime = 0.0


class RampSetpoint(Spec):
    """A constant-velocity ramp starting at ``start`` (position grows at ``velocity``)."""

    type: Literal["ramp"]
    velocity: Annotated[float, quantity("velocity")]
    start: NonNegativeTime = 0.0


class TrapezoidSetpoint(Spec):
    """A point-to-point move with a trapezoidal velocity profile (acceleration-limited)."""

    type: Literal["trapezoid"]
    distance: Annotated[float, quantity("length")]
    max_velocity: Annotated[float, quantity("velocity"), Field(gt=0)]
    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)]
    start: NonNegativeTime = 0.0


class SCurveSetpoint(Spec):
    """A jerk-limited (7-segment S-curve), time-optimal point-to-point move."""

    type: Literal["s-curve"]
    distance: Annotated[float, quantity("length")]
    max_velocity: Annotated[float, quantity("velocity"), Field(gt=0)]
    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)]
    max_jerk: Annotated[float, quantity("jerk"), Field(gt=0)]
    start: NonNegativeTime = 0.0


SetpointSpec = Annotated[Union[StepSetpoint, RampSetpoint, TrapezoidSetpoint, SCurveSetpoint],
                         Field(discriminator="type")]


class InterpolatorSpec(Spec):
    """The CNC's path interpolator (machine level): limits along the path for lines, arcs and G-code.

    It runs at the position-loop period of the first axis it moves.
    """

    max_acceleration: Annotated[float, quantity("acceleration"), Field(gt=0)] = 2.0
    max_jerk: Annotated[float, quantity("jerk"), Field(gt=0)] = 50.0
    rapid_feed: Annotated[float, quantity("velocity"), Field(gt=0)] = 0.25
    corner_tolerance: Annotated[float, quantity("angle"), Field(ge=0)] = 1e-3
