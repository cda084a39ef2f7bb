"""The machine: named axes, each with its mechanics (any kind of :data:`MechanicsSpec`), drive,
controller and trajectory, and the cross-checks between an axis's blocks."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pydantic import Field, ValidationError, model_validator

from .base import Name, Spec, fail
from .registry import MechanicsKind, spec_union
from .motion import InterpolatorSpec, SetpointSpec
from .servo import ControllerSpec, DriveSpec
from . import mechanics as _mechanics, shorthands as _shorthands, components as _components  # noqa: F401  (register their types)
from .components import PART_CLASSES, ComponentsSpec, motor_drive_defaults
from .robot import RobotSpec
from ..errors import ModelError

__all__ = ["MechanicsSpec", "Axis", "Machine"]


if TYPE_CHECKING:  # a type checker sees the protocol, pydantic the discriminated union
    MechanicsSpec = MechanicsKind
else:
    MechanicsSpec = spec_union("mechanics")
"""Any registered mechanical structure, chosen by ``type`` (lumped, chain, belt-rack, components): its classes
are registered in ``mechanics.py``, ``shorthands.py`` and ``components.py``; a module with a new type is imported above."""


# --------------------------------------------------------------------------- machine
class Axis(Spec):
    """One feed axis: its mechanics and, for the servo loop, its drive, controller and trajectory.

    ``tool`` names the body whose position is the axis coordinate (the load or tool point) used
    for the following error and to convert every feedback sensor into axis units; by default, the
    body of the controller's position sensor.

    An axis of a machine with a ``[robot]`` section is one of its motorised joints: it has no
    ``mechanics`` of its own (the robot is its mechanics), its sensors are the robot's and ``tool``
    names the robot sensor that reads the axis coordinate (default: the joint's load side).
    """

    mechanics: MechanicsSpec | None = None
    drive: DriveSpec | None = None
    controller: ControllerSpec | None = None
    trajectory: SetpointSpec | None = None
    tool: Name | None = None

    @model_validator(mode="before")
    @classmethod
    def _drive_from_motor(cls, data: Any) -> Any:
        """A drive-chain axis's drive takes the motor's constants it does not give (docs/drive-chains.md).
        Only the motor part is read here (the mechanics field validates the whole chain, once)."""
        if not (isinstance(data, dict) and isinstance(data.get("drive"), dict)):
            return data
        mech = data.get("mechanics")
        parts = mech.get("parts") if isinstance(mech, dict) and mech.get("type") == "components" else None
        first = parts[0] if isinstance(parts, list) and parts and isinstance(parts[0], dict) else None
        if first is None or first.get("kind") not in ("motor", "linear-motor"):
            return data          # the mechanics field reports it, located
        try:
            motor = PART_CLASSES[first["kind"]].model_validate(first)
        except ValidationError:
            return data
        drive = {**motor_drive_defaults(motor), **data["drive"]}
        if "force_constant" not in drive:
            key = "force_constant" if first["kind"] == "linear-motor" else "torque_constant"
            raise fail(f"missing: give the drive's force_constant, or the motor part's {key} (and its basis) "
                       "that it is taken from", "drive.force_constant", None)
        return {**data, "drive": drive}

    @model_validator(mode="after")
    def _references(self) -> "Axis":
        if self.mechanics is None:      # a robot's joint: checked by the machine, which knows the robot
            return self
        if self.tool is None and isinstance(self.mechanics, ComponentsSpec):
            # a drive chain's tool is its table (the load body): a motor-encoder position loop would otherwise
            # move in motor radians (docs/drive-chains.md); set here, so dumps and saved files carry it
            object.__setattr__(self, "tool", self.mechanics.chain.bodies[-1].name)
        lumped = self.mechanics.to_lumped()
        bodies, sensors, actuators = lumped.bodies, lumped.sensors, lumped.actuators
        if self.tool is not None and self.tool not in bodies:
            raise fail("unknown body {value}; expected one of {known}", "tool", self.tool,
                       known=", ".join(bodies))
        if self.drive is not None:
            if self.drive.actuator is not None and self.drive.actuator not in actuators:
                raise fail("unknown actuator {value}; expected one of {known}", "drive.actuator",
                           self.drive.actuator, known=", ".join(actuators) or "(none: add one to the mechanics)")
            if not actuators:
                raise fail("the mechanics has no actuator for the drive to command; add one under "
                           "mechanics.actuators", "drive", None)
            if self.drive.actuator is None and len(actuators) != 1:
                raise fail("the mechanics has {count} actuators; name the driven one in 'actuator'",
                           "drive.actuator", None, count=len(actuators))
        if self.controller is not None:
            c = self.controller
            for key in ("position_sensor", "velocity_sensor"):
                name = getattr(c, key)
                if name is not None and name not in sensors:
                    raise fail("unknown sensor {value}; expected one of {known}", f"controller.{key}", name,
                               known=", ".join(sensors) or "(none: add one to the mechanics)")
            if sensors[c.position_sensor].kind != "position":
                raise fail("the position loop needs a position sensor", "controller.position_sensor",
                           c.position_sensor)
            if self.drive is None:
                raise fail("a controller needs a drive to command; add [axes.<name>.drive]", "drive", None)
        return self


class Machine(Spec):
    """A machine: a name and one or more named axes (the first is the default axis)."""

    name: str = ""
    description: str = ""
    axes: dict[Name, Axis] = Field(default_factory=dict)
    interpolator: InterpolatorSpec = Field(default_factory=InterpolatorSpec)
    robot: RobotSpec | None = None

    @model_validator(mode="after")
    def _axes(self) -> "Machine":
        """Axes with their own mechanics, or the robot's motorised joints (every one an axis, in frame
        order; an ``[axes.<joint>]`` table gives its drive, controller, trajectory and tool)."""
        if self.robot is None:
            if not self.axes:
                raise fail("missing required key: a machine needs at least one axis ([axes.<name>]) or a [robot] section",
                       "axes", None)
            for name, axis in self.axes.items():
                if axis.mechanics is None:
                    raise fail("missing: every axis needs [axes.<name>.mechanics] (or the machine a [robot] "
                               "section whose motorised joint it is)", f"axes.{name}.mechanics", None)
            return self
        robot = self.robot
        motors = robot.motor_names
        if not motors:
            raise fail("the robot has no motorised joint (mu = 1): its motorised joints are the machine's axes",
                       "robot.frames", None)
        for name, axis in self.axes.items():
            if name not in motors:
                raise fail("{value} is not a motorised joint of the robot; the axes of a robot are its motorised "
                           "joints: {known}", f"axes.{name}", name, known=", ".join(motors))
            if axis.mechanics is not None:
                raise fail("an axis of a robot has no mechanics of its own: the [robot] section is its mechanics",
                           f"axes.{name}.mechanics", None)
            _check_robot_axis(robot, name, axis)
        axes = {name: self.axes.get(name) or Axis() for name in motors}
        object.__setattr__(self, "axes", axes)
        return self

    def axis(self, name: str | None = None) -> Axis:
        """The axis called ``name``, or the first axis."""
        if name is None:
            return next(iter(self.axes.values()))
        if name not in self.axes:
            raise ModelError(f"unknown axis {name!r}; expected one of {', '.join(self.axes)}", path="axes")
        return self.axes[name]

    def axis_name(self, name: str | None = None) -> str:
        """The name of the axis ``name`` resolves to (the first axis when ``None``)."""
        self.axis(name)
        return name if name is not None else next(iter(self.axes))


def _check_robot_axis(robot: RobotSpec, name: str, axis: Axis) -> None:
    """The robot sensors an axis names exist and fit their use."""
    sensors = robot.all_sensors()
    known = ", ".join(sensors)
    if axis.tool is not None:
        if axis.tool not in sensors or sensors[axis.tool].kind != "position":
            raise fail("unknown position sensor {value} for the axis coordinate; expected one of the robot's "
                       "sensors: {known}", f"axes.{name}.tool", axis.tool, known=known)
    if axis.drive is not None and axis.drive.actuator not in (None, name):
        raise fail("the drive of a robot's axis drives its own joint {known}", f"axes.{name}.drive.actuator",
                   axis.drive.actuator, known=repr(name))
    c = axis.controller
    if c is None:
        return
    for key in ("position_sensor", "velocity_sensor"):
        sensor = getattr(c, key)
        if sensor is not None and sensor not in sensors:
            raise fail("unknown sensor {value}; expected one of the robot's sensors: {known}",
                       f"axes.{name}.controller.{key}", sensor, known=known)
    if sensors[c.position_sensor].kind != "position":
        raise fail("the position loop needs a position sensor", f"axes.{name}.controller.position_sensor",
                   c.position_sensor)
    if axis.drive is None:
        raise fail("a controller needs a drive to command; add [axes.<name>.drive]", f"axes.{name}.drive", None)
