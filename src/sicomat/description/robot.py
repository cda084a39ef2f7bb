"""The model file's ``[robot]`` section (issue 13): a multi-body machine described by the robotics formalism,
one ``[[robot.frames]]`` row per frame in modified Denavit–Hartenberg parameters (SYMORO's field names), its
joint sensors and the configuration it is linearised about.

Each row holds ``ant`` and ``sigma`` (required) and ``mu gamma b alpha d theta r eta k`` and the link's
``XX XY XZ YY YZ ZZ MX MY MZ M IA FV FS`` (default 0, units allowed: the dimension of ``k``, ``IA``, ``FV``,
``FS`` and of a joint value follows the joint's type), plus ``name``, the joint variable's name (default
``q<frame>``). The rows obey :mod:`.robot_table`. The motorised joints (``mu = 1``) are the machine's axes
(:class:`~sicomat.description.machine.Machine`); every joint gets a position sensor of its own name, and a
motorised joint followed by elastic joints on its own axis (a screw's or belt's deflection) a load-side sensor
``<name>_load`` reading their sum. The lowering into a :class:`~sicomat.mechanics.Mechanics` is
:mod:`sicomat.robotics.lowering`; the conventions and decisions are in ``docs/robotics.md``.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from ..errors import ModelError
from .base import Name, Spec, fail
from .mechanics import quantization_step
from .robot_table import (FIELD_UNITS, FIXED, FRAME_FIELDS, PRISMATIC, check_frame, check_gravity, check_links,
                          check_loops, field_unit)
from .units import UNITS, parse_quantity

__all__ = ["RobotSpec", "RobotSensor", "Frame"]

class Frame(Spec):
    """One row of the MDH table, in SI units (see :mod:`.robot_table` for the rules)."""

    name: Name | None = None
    ant: int
    sigma: int
    mu: int = 0
    eta: int = 0
    gamma: float = 0.0
    b: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    r: float = 0.0
    k: float = 0.0
    XX: float = 0.0
    XY: float = 0.0
    XZ: float = 0.0
    YY: float = 0.0
    YZ: float = 0.0
    ZZ: float = 0.0
    MX: float = 0.0
    MY: float = 0.0
    MZ: float = 0.0
    M: float = 0.0
    IA: float = 0.0
    FV: float = 0.0
    FS: float = 0.0

    def table_row(self) -> dict[str, float]:
        """The row as :meth:`sicomat.robotics.MDHRobot.from_table` takes it (without ``name``)."""
        return {key: getattr(self, key) for key in FRAME_FIELDS}


class RobotSensor(Spec):
    """A sensor reading the sum of joint variables (``joints``, by name): a position (m or rad) or a
    velocity, quantized by ``resolution`` (in the joints' unit) or ``counts_per_revolution`` (rotary)."""

    joints: list[Name] = Field(min_length=1)
    kind: Literal["position", "velocity"] = "position"
    resolution: float | None = Field(default=None, gt=0)
    counts_per_revolution: int | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _one_resolution(self) -> "RobotSensor":
        quantization_step(self.resolution, self.counts_per_revolution)
        return self

    @property
    def step(self) -> float | None:
        """Quantization step in SI units (m or rad), or ``None``."""
        return quantization_step(self.resolution, self.counts_per_revolution)


class RobotSpec(Spec):
    """The ``[robot]`` section: gravity (base frame), the frames, extra sensors and the configuration.

    ``configuration`` lists every joint variable in frame order (elastic joints included), the point the
    machine is linearised about for modal analysis, frequency responses, tuning and linear simulation
    (default: all zero).
    """

    gravity: list[float] = Field(default_factory=lambda: [0.0, 0.0, -9.81])
    frames: list[Frame] = Field(min_length=1)
    sensors: dict[Name, RobotSensor] = Field(default_factory=dict)
    configuration: list[float] | None = None
    links: int | None = None
    """NL (SYMORO's name) for a machine with closed loops: frames after NL are the cut joints and their
    closing frames (``docs/robotics.md``, "Closed loops"); none for a tree."""
    tool: Name | None = None
    """The frame (by name) whose origin is the tool point, for path following on the coupled model
    (``sicomat circle``); default: the last frame of the tree (frame NL)."""

    @model_validator(mode="before")
    @classmethod
    def _parse_units(cls, data: Any) -> Any:
        """Parse the quantities whose dimension depends on a joint's type, before the field checks."""
        if not isinstance(data, dict):
            return data
        data = dict(data)
        if isinstance(data.get("gravity"), list):
            data["gravity"] = [_quantity(v, "acceleration", f"gravity.{i}") for i, v in enumerate(data["gravity"])]
        frames = data.get("frames")
        if not isinstance(frames, list):
            return data
        data["frames"] = [_parse_frame(row, frame) for row, frame in enumerate(frames)]
        q0 = data.get("configuration")
        if isinstance(q0, list):
            sigmas = [f.get("sigma") if isinstance(f, dict) else None for f in frames]
            kinds = [("length" if s == PRISMATIC else "angle") for s in sigmas if s != FIXED]
            data["configuration"] = [_quantity(v, kinds[i], f"configuration.{i}") if isinstance(v, str) and i < len(kinds)
                                     else v for i, v in enumerate(q0)]
        sensors = data.get("sensors")
        if isinstance(sensors, dict):
            sigma = {(f.get("name") or f"q{row + 1}"): f.get("sigma") for row, f in enumerate(frames) if isinstance(f, dict)}
            data["sensors"] = {name: _parse_sensor(sensor, sigma, f"sensors.{name}") for name, sensor in sensors.items()}
        return data

    @model_validator(mode="after")
    def _check(self) -> "RobotSpec":
        try:
            check_gravity(self.gravity)
        except ModelError as exc:
            raise fail(exc.message, "gravity", self.gravity) from None
        for row, frame in enumerate(self.frames):
            try:
                check_frame(row, frame.table_row())
            except ModelError as exc:
                raise fail(exc.message, _table_path(exc), exc.value) from None
        try:
            nl = check_links(self.links, len(self.frames))
            if nl is not None:
                check_loops({key: [getattr(f, key) for f in self.frames] for key in FRAME_FIELDS}, nl)
        except ModelError as exc:
            raise fail(exc.message, _table_path(exc), exc.value) from None
        names = self.joint_names
        seen: dict[str, int] = {}
        for row, frame in enumerate(self.frames):
            name = self.frame_name(row)
            if name in seen:
                raise fail(f"frame {row + 1}: the name {{value}} is already frame {seen[name] + 1}'s",
                           f"frames.{row}.name", name)
            seen[name] = row
        defaults = self.default_sensors()
        for sensor_name, sensor in self.sensors.items():
            if sensor_name in defaults:
                raise fail("{value} is a sensor every robot has (a joint's own position or its load side); "
                           "name this one differently", f"sensors.{sensor_name}", sensor_name)
            kinds = set()
            for i, joint in enumerate(sensor.joints):
                if joint not in names:
                    raise fail("unknown joint {value}; expected one of {known}", f"sensors.{sensor_name}.joints.{i}",
                               joint, known=", ".join(names))
                kinds.add(self.joint_kind(joint))
            if len(kinds) > 1:
                raise fail("a sensor adds joint variables of one kind: these mix revolute and prismatic joints",
                           f"sensors.{sensor_name}.joints", sensor.joints)
        if self.tool is not None and self.tool not in seen:
            raise fail("unknown frame {value}; the tool point is the origin of a named frame: {known}", "tool",
                       self.tool, known=", ".join(seen))
        if self.configuration is not None and len(self.configuration) != len(names):
            raise fail(f"expected {len(names)} joint values (every joint in frame order: {', '.join(names)})",
                       "configuration", self.configuration)
        return self

    # ------------------------------------------------------------------ names
    def frame_name(self, row: int) -> str:
        """The name of frame ``row + 1``'s joint variable: its ``name`` or ``q<frame>``."""
        return self.frames[row].name or f"q{row + 1}"

    @property
    def joint_rows(self) -> list[int]:
        """Rows of the frames that have a joint variable (not fixed), in frame order."""
        return [row for row, f in enumerate(self.frames) if f.sigma != FIXED]

    @property
    def joint_names(self) -> list[str]:
        """The joint variables' names, in frame order (the order of ``q``)."""
        return [self.frame_name(row) for row in self.joint_rows]

    @property
    def motor_names(self) -> list[str]:
        """The motorised joints' names (``mu = 1``): the machine's axes."""
        return [self.frame_name(row) for row in self.joint_rows if self.frames[row].mu == 1]

    def joint_kind(self, name: str) -> Literal["translational", "rotational"]:
        """``"translational"`` for a prismatic joint, ``"rotational"`` for a revolute one."""
        row = self.joint_rows[self.joint_names.index(name)]
        return "translational" if self.frames[row].sigma == PRISMATIC else "rotational"

    def followers(self, name: str) -> list[str]:
        """The elastic joints that continue joint ``name`` on its own axis: each the elastic child of the
        previous one, of the same type, with ``gamma = alpha = d = 0`` (same line; ``b``, ``theta`` and
        ``r`` move along or turn about it). A screw's or a belt's deflection after its motor."""
        rows = self.joint_rows
        row = rows[self.joint_names.index(name)]
        out: list[str] = []
        while True:
            child = next((c for c, f in enumerate(self.frames) if f.ant == row + 1 and f.eta == 1
                          and f.sigma == self.frames[row].sigma and f.gamma == f.alpha == f.d == 0.0), None)
            if child is None:
                return out
            out.append(self.frame_name(child))
            row = child

    def default_sensors(self) -> dict[str, RobotSensor]:
        """The sensors every robot has: each joint's position (its own name), and for a motorised joint
        with elastic followers the load side ``<name>_load`` (the joint and its followers)."""
        sensors = {name: RobotSensor(joints=[name]) for name in self.joint_names}
        for name in self.motor_names:
            followers = self.followers(name)
            if followers:
                sensors[f"{name}_load"] = RobotSensor(joints=[name, *followers])
        return sensors

    def all_sensors(self) -> dict[str, RobotSensor]:
        """The default sensors, then the section's own."""
        return {**self.default_sensors(), **self.sensors}

    @property
    def tool_frame(self) -> int:
        """The frame number (1..NF) of the tool point: the frame named by ``tool``, else the tree's last."""
        if self.tool is not None:
            return next(row for row in range(len(self.frames)) if self.frame_name(row) == self.tool) + 1
        return self.links if self.links is not None else len(self.frames)

    def tool_sensor(self, axis: str) -> str:
        """The sensor whose reading is axis ``axis``'s coordinate by default: its load side, else itself."""
        return f"{axis}_load" if self.followers(axis) else axis


def _table_path(exc: ModelError) -> str:
    """The table rules' location ``frames[ROW].FIELD`` (or ``links``) as a model-file key path below
    ``robot``: ``frames.ROW.FIELD``."""
    return (exc.path or "").replace("[", ".").replace("]", "")


def _quantity(value: Any, unit: str, where: str) -> Any:
    try:
        return parse_quantity(value, UNITS[unit])
    except ValueError as exc:
        raise fail(str(exc), where, value) from None


def _parse_frame(row: int, frame: Any) -> Any:
    """A row with its quantities in SI (a missing or malformed ``sigma`` leaves the typed fields to the
    schema's own messages)."""
    if not isinstance(frame, dict):
        return frame
    sigma = frame.get("sigma")
    if isinstance(sigma, bool) or not isinstance(sigma, int) or sigma not in (0, 1, 2):
        sigma = FIXED if sigma == FIXED else None
    out = dict(frame)
    for key, value in frame.items():
        if key in FIELD_UNITS and isinstance(value, str):
            if sigma is None:
                raise fail(f"frame {row + 1}: sigma (0 revolute, 1 prismatic, 2 fixed) is needed to read "
                           "this value's unit", f"frames.{row}.{key}", value)
            out[key] = _quantity(value, field_unit(key, sigma), f"frames.{row}.{key}")
    return out


def _parse_sensor(sensor: Any, sigma: dict[Any, Any], where: str) -> Any:
    """A sensor's ``resolution`` in the unit of its first joint (m or rad)."""
    if not isinstance(sensor, dict) or not isinstance(sensor.get("resolution"), str):
        return sensor
    joints = sensor.get("joints")
    first = joints[0] if isinstance(joints, list) and joints else None
    unit = "length" if sigma.get(first) == PRISMATIC else "angle"
    return {**sensor, "resolution": _quantity(sensor["resolution"], unit, f"{where}.resolution")}


def configuration_units(spec: RobotSpec) -> list[str]:
    """The dimension of each joint value of ``configuration`` (``length`` or ``angle``)."""
    return ["length" if spec.frames[row].sigma == PRISMATIC else "angle" for row in spec.joint_rows]
