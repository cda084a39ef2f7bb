"""Coupled axes: the servo loops of several axes acting on ONE mechanics (a full mass matrix, one
actuator and its sensors per axis), lowered to one hybrid program.

Each axis keeps its own :class:`~sicomat.servo.loop.ServoLoop` (drive, CNC cascade controller,
gains in SI, sensor conversions, rigid mass), built as for a single axis, typically on that axis's
decoupled mechanics (the other axes locked). The coupled program finds each loop's actuator and
sensors **by name** in the coupled mechanics, and its tool vector over the coupled dofs in
:attr:`CoupledLoop.tools`. Each axis's discrete ops are those of a single-axis program
(:func:`~sicomat.servo.loop.axis_ops`, the one lowering of an axis), on slots named
``"<axis>.<signal>"``; the sensors' readings ``sensor.<name>`` and the friction forces
``friction.<link>`` belong to the coupled mechanics and keep their own names.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from ..errors import ModelError
from ..mechanics.lumped import Mechanics
from .loop import (ServoLoop, SetpointTable, _assemble, _Lowering, _Prefixed, _Slots, axis_ops, drives_plant,
                   friction_links, loop_reads)

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from ..lti.plant import Plant
    from .program import HybridProgram

__all__ = ["CoupledLoop", "coupled_plant", "coupled_program", "axis_view", "AXIS_OUTPUTS", "robot_coupled_loop"]

AXIS_OUTPUTS = ("tool.position", "tool.velocity", "actuator.velocity", "drive.current", "drive.effort")
"""The continuous outputs each axis has in the coupled plant, as ``"<axis>.<output>"``."""


@dataclass(frozen=True, eq=False)
class CoupledLoop:
    """The servo loops of several axes on one coupled mechanics.

    Attributes
    ----------
    mechanics : Mechanics
        The coupled mechanics: every dof, every axis's actuator and sensors (unique names).
    loops : tuple of ServoLoop
        One per axis (distinct axis names, without a ``"."``), sharing the velocity period (the
        simulator's base step). Each loop's gains, sensor conversions and rigid mass are used as they
        are (those of the mechanics it was built on); its actuator and sensors are looked up by name in
        ``mechanics``.
    tools : dict of str to ndarray
        Each axis's tool vector over the coupled dofs (axis coordinate ``tool · q``). An axis left out
        takes its loop's tool vector carried over by dof name (every dof it weights must be a dof of
        ``mechanics``).

    Raises
    ------
    ModelError
        No loop, a repeated or dotted axis name, different velocity periods (naming the axes and
        periods), an analog velocity loop (not supported coupled), an actuator, sensor or tool dof
        missing from the coupled mechanics, a tool vector of the wrong length, a tool for no axis.
    """

    mechanics: Mechanics
    loops: tuple[ServoLoop, ...]
    tools: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        loops = tuple(self.loops)
        object.__setattr__(self, "loops", loops)
        if not loops:
            raise ModelError("a coupled loop needs at least one axis's servo loop", path="loops")
        names = [loop.axis for loop in loops]
        for name in names:
            if names.count(name) > 1 or "." in name or not name:
                raise ModelError("the axes of a coupled loop need distinct names without a '.' (their "
                                 "signals are named '<axis>.<signal>')", path="loops", value=name)
        periods = {loop.axis: loop.base_period for loop in loops}
        h = loops[0].base_period
        if any(abs(p - h) > 1e-12 * h for p in periods.values()):
            listed = ", ".join(f"{axis} {p:g} s" for axis, p in periods.items())
            raise ModelError(f"the axes of a coupled loop must share their velocity period (the simulator's "
                             f"step): {listed}", path="loops")
        mech = self.mechanics
        unknown = sorted(set(self.tools) - set(names))
        if unknown:
            raise ModelError(f"a tool vector for no axis of the coupled loop (axes: {', '.join(names)})",
                             path=f"tools.{unknown[0]}", value=unknown[0])
        tools = {}
        for loop in loops:
            _check_names(loop, mech)
            tools[loop.axis] = _tool(loop, mech, self.tools.get(loop.axis))
        object.__setattr__(self, "tools", tools)

    @property
    def axes(self) -> tuple[str, ...]:
        """The axis names, in the order of :attr:`loops`."""
        return tuple(loop.axis for loop in self.loops)

    @property
    def base_period(self) -> float:
        """The simulator's base step: the velocity period every loop shares (s)."""
        return self.loops[0].base_period

    def loop(self, axis: str) -> ServoLoop:
        """The servo loop of ``axis``."""
        for loop in self.loops:
            if loop.axis == axis:
                return loop
        raise ModelError(f"no axis {axis!r} in the coupled loop (axes: {', '.join(self.axes)})", value=axis)


def _check_names(loop: ServoLoop, mech: Mechanics) -> None:
    """The loop's actuator and sensors exist in the coupled mechanics; its velocity loop is sampled."""
    ctrl, axis = loop.controller, loop.axis
    if ctrl.velocity_loop == "continuous":
        raise ModelError("a continuous (analog) velocity loop is not supported in a coupled loop (its "
                         "controller would join the shared continuous part); simulate the axis alone",
                         path=f"axes.{axis}.controller.velocity_loop", value="continuous")
    actuators = [a.name for a in mech.actuators]
    if loop.actuator not in actuators:
        raise ModelError(f"the actuator {loop.actuator!r} of axis {axis} is not an actuator of the coupled "
                         f"mechanics (its actuators: {', '.join(actuators) or 'none'})",
                         path=f"axes.{axis}.drive.actuator", value=loop.actuator)
    sensors = [s.name for s in mech.sensors]
    for key, name in (("position_sensor", ctrl.position_sensor), ("velocity_sensor", ctrl.velocity_sensor)):
        if name is not None and name not in sensors:
            raise ModelError(f"the sensor {name!r} of axis {axis} is not a sensor of the coupled mechanics "
                             f"(its sensors: {', '.join(sensors) or 'none'})",
                             path=f"axes.{axis}.controller.{key}", value=name)


def _tool(loop: ServoLoop, mech: Mechanics, given: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The axis's tool vector over the coupled dofs: given, or the loop's carried over by dof name."""
    if given is not None:
        tool = np.array(given, dtype=float)
        if tool.shape != (mech.n,) or not np.all(np.isfinite(tool)):
            raise ModelError(f"expected a finite vector over the {mech.n} dofs of the coupled mechanics, got "
                             f"shape {tool.shape}", path=f"tools.{loop.axis}")
    else:
        tool = np.zeros(mech.n)
        for dof, weight in zip(loop.mechanics.dofs, loop.tool):
            if weight == 0.0:
                continue
            if dof.name not in mech.dof_names:
                raise ModelError(f"the tool of axis {loop.axis} weights the dof {dof.name!r}, which the coupled "
                                 f"mechanics does not have; give its tool vector over the coupled dofs",
                                 path=f"tools.{loop.axis}", value=dof.name)
            tool[mech.index(dof.name)] = weight
    tool.setflags(write=False)
    return tool


def coupled_plant(coupled: CoupledLoop) -> "Plant":
    """The continuous part of a coupled loop: the coupled mechanics and every axis's current loop.

    States ``(q, q̇)`` of every dof, then ``<axis>.drive.current`` per axis; inputs
    ``<axis>.current.reference``; outputs ``sensor.<name>`` for every sensor of the coupled mechanics,
    then per axis ``<axis>.tool.position``, ``.tool.velocity``, ``.actuator.velocity``,
    ``.drive.current``, ``.drive.effort`` (:data:`AXIS_OUTPUTS`), then every dof's position and
    velocity (:func:`~sicomat.servo.loop.drives_plant`, which :func:`servo_plant` is for one axis).
    """
    mech = coupled.mechanics
    return drives_plant(mech, [(f"{loop.axis}.", loop.drive, mech.actuator(loop.actuator), coupled.tools[loop.axis])
                               for loop in coupled.loops])


def coupled_program(coupled: CoupledLoop, setpoints: Mapping[str, SetpointTable], *,
                    nonlinear: bool = True) -> "HybridProgram":
    """Lower a coupled loop and each axis's sampled setpoints to one hybrid program.

    Each axis's ops are those :func:`~sicomat.servo.loop.servo_program` builds for it, on slots named
    ``"<axis>.<signal>"`` (its setpoints in columns ``3k .. 3k + 2`` of one table, ``k`` its place in
    :attr:`CoupledLoop.loops`; shorter tables held at their last sample); one continuous part
    (:func:`coupled_plant`) with the coupled mechanics' friction links. ``nonlinear=False`` drops the
    limits, quantizers and Coulomb friction.
    """
    axes = coupled.axes
    missing = [axis for axis in axes if axis not in setpoints]
    extra = sorted(set(setpoints) - set(axes))
    if missing or extra:
        what = f"no setpoints for axis {missing[0]}" if missing else f"setpoints for no axis ({extra[0]})"
        raise ModelError(f"{what}: a coupled program takes one setpoint table per axis ({', '.join(axes)})",
                         path="setpoints", value=(missing or extra)[0])
    mech = coupled.mechanics
    s = _Slots()
    plant = coupled_plant(coupled)
    read = {name if name.startswith("sensor.") else f"{loop.axis}.{name}"
            for loop in coupled.loops for name in loop_reads(loop)}
    rows = [i for i, name in enumerate(plant.outputs) if name in read]
    links = friction_links(mech, nonlinear)
    for name in [plant.outputs[i] for i in rows] + [f"friction.{link.name}" for link in links]:
        s(name)
    ops: list = []
    blocks: list = []
    for k, loop in enumerate(coupled.loops):
        view = _Prefixed(s, f"{loop.axis}.")
        for name in sorted(loop_reads(loop)):
            if name.startswith("sensor."):      # the axis reads the coupled mechanics' sensor
                s.alias(f"{loop.axis}.{name}", name)
        axis_ops(loop, mech, _Lowering(view, nonlinear, ops, blocks), column=3 * k)
    tables = [setpoints[axis].columns for axis in axes]
    length = max(t.shape[1] for t in tables)
    table = np.empty((3 * len(tables), length))
    for k, t in enumerate(tables):
        table[3 * k: 3 * k + 3, : t.shape[1]] = t
        table[3 * k: 3 * k + 3, t.shape[1]:] = t[:, -1:]
    C = plant.C[rows]
    return _assemble(mech, coupled.base_period, table, s, ops, blocks, links, plant.A, plant.B, C,
                     np.zeros((C.shape[0], len(axes))), [f"{axis}.current.applied" for axis in axes],
                     [plant.outputs[i] for i in rows])


def axis_view(coupled: CoupledLoop, axis: str, names: Sequence[str]) -> dict[str, str]:
    """The names of a coupled program's slots (or of :func:`coupled_plant`'s outputs) as ``axis``
    calls them: its own ``"<axis>.<signal>"`` as ``<signal>``, and the coupled mechanics' signals
    (sensors, friction forces, dofs: every name of no axis) as they are. Maps the axis's name to
    the coupled one."""
    prefixes = tuple(f"{a}." for a in coupled.axes)
    shared = {f"sensor.{s.name}" for s in coupled.mechanics.sensors}
    shared |= {f"friction.{f.name}" for f in coupled.mechanics.frictions}
    shared |= {name for d in coupled.mechanics.dofs for name in (d.position, d.velocity)}
    view = {}
    for name in names:
        if name in shared or not name.startswith(prefixes):
            view[name] = name
        elif name.startswith(f"{axis}."):
            view[name[len(axis) + 1:]] = name
    return view


def robot_coupled_loop(machine: "Machine") -> CoupledLoop:
    """The servo loops of every motorised joint of a ``[robot]`` machine on its coupled linear model: the
    robot linearised at its configuration with every joint free (gravity compensated, as each axis's own
    model), each axis's loop built as for a single axis (its gains, rigid mass and sensor conversions
    those of its decoupled model, the other motors locked), its tool the sensor that reads its coordinate.
    Every motorised joint needs a drive and a controller.

    Raises
    ------
    ModelError
        The machine has no ``[robot]`` section, an axis has no drive or controller, or the loops do not
        fit together (:class:`CoupledLoop`).
    """
    from ..robotics.lowering import robot_mechanics
    from .loop import build_servo_loop

    robot = machine.robot
    if robot is None:
        raise ModelError("a coupled loop of a machine needs its [robot] section (its motorised joints are the "
                         "axes)", path="robot")
    mechanics = robot_mechanics(robot, gravity=False)
    loops = tuple(build_servo_loop(machine, axis) for axis in machine.axes)
    tools = {axis: np.array(mechanics.sensor(machine.axes[axis].tool or robot.tool_sensor(axis)).vector)
             for axis in machine.axes}
    return CoupledLoop(mechanics, loops, tools)
