"""The servo loop: mechanics + drive + CNC cascade controller, lowered to a hybrid program.

``build_servo_loop`` resolves an axis description into numbers (gains in physical units, sensor
conversions, rigid mass); ``servo_program`` lowers it, with sampled setpoints, into the
:class:`~sicomat.simulate.program.HybridProgram` the kernel runs. Every block lowers to the same few
element kinds (linear blocks, sums, saturations, quantizers, delays, current limit, clamping gate),
so a new controller or drive type only adds a lowering here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .controller import DiscreteSS, difference_block, filter_block, velocity_law
from .drive import DriveModel, drive_model
from .errors import ModelError
from .mechanics import Mechanics, build_mechanics

if TYPE_CHECKING:  # pragma: no cover
    from .model import Machine
    from .plant import Plant
    from .servo_spec import ControllerSpec
    from .simulate.program import HybridProgram

__all__ = ["ServoLoop", "build_servo_loop", "servo_plant", "servo_program", "SetpointTable"]


@dataclass(frozen=True, eq=False)
class ServoLoop:
    """An axis's closed loop, resolved to SI numbers.

    Attributes
    ----------
    axis : str
    mechanics : Mechanics
    drive : DriveModel
    controller : ControllerSpec
        The controller description (periods, delays, filters, feedforwards).
    actuator : str
        The driven actuator.
    tool : ndarray
        Position vector of the axis coordinate (``tool · q``).
    m_rigid : float
        Rigid mass or inertia seen by the actuator per unit axis acceleration.
    Kp : float
        Velocity gain in physical units (effort per axis velocity); ``Kp_normalized = Kp / m_rigid``.
    Ti, Kv : float
        Integral time (s) and position gain (1/s).
    position_gain, velocity_gain : float
        Sensor reading per unit axis motion (rigid), for the position and velocity feedback.
    """

    axis: str
    mechanics: Mechanics
    drive: DriveModel
    controller: "ControllerSpec"
    actuator: str
    tool: np.ndarray
    m_rigid: float
    Kp: float
    Ti: float
    Kv: float
    position_gain: float
    velocity_gain: float

    @property
    def Kp_normalized(self) -> float:
        """The paper's normalised velocity gain (1/s)."""
        return self.Kp / self.m_rigid

    @property
    def base_period(self) -> float:
        """The simulator's base step: the velocity-loop period (s)."""
        return self.controller.velocity_period

    @property
    def position_ratio(self) -> int:
        """Position period in velocity periods."""
        return int(round(self.controller.position_period / self.controller.velocity_period))

    def with_gains(self, *, Kp: float | None = None, Ti: float | None = None, Kv: float | None = None) -> "ServoLoop":
        """A copy with other gains (Kp in physical units)."""
        from dataclasses import replace

        return replace(self, Kp=self.Kp if Kp is None else Kp, Ti=self.Ti if Ti is None else Ti,
                       Kv=self.Kv if Kv is None else Kv)


def build_servo_loop(machine: "Machine", axis: str | None = None) -> ServoLoop:
    """Resolve an axis with mechanics, drive and controller into a :class:`ServoLoop`.

    Raises
    ------
    ModelError
        The axis has no drive or controller, or its actuator cannot move the tool.
    """
    name = machine.axis_name(axis)
    spec = machine.axes[name]
    if spec.controller is None or spec.drive is None:
        missing = "controller" if spec.controller is None else "drive"
        raise ModelError(f"the axis has no {missing}; a servo loop needs [axes.{name}.drive] and "
                         f"[axes.{name}.controller]", path=f"axes.{name}.{missing}")
    mech = build_mechanics(spec.mechanics)
    if not mech.actuators:
        raise ModelError("the mechanics has no actuator for the drive to command",
                         path=f"axes.{name}.mechanics.actuators")
    ctrl = spec.controller
    actuator = spec.drive.actuator or mech.actuators[0].name
    act = mech.actuator(actuator)
    pos_sensor = mech.sensor(ctrl.position_sensor)
    vel_sensor = mech.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
    if spec.tool is not None:
        tool = np.zeros(mech.n)
        tool[mech.index(spec.tool)] = 1.0
    else:
        tool = np.array(pos_sensor.vector)
    try:
        phi, m_rigid = mech.rigid_motion(act.vector, tool)
    except ModelError as exc:
        raise ModelError(exc.message, path=f"axes.{name}.tool") from None
    gains = {}
    for key, sensor in (("position", pos_sensor), ("velocity", vel_sensor)):
        gain = float(sensor.vector @ phi)
        if abs(gain) < 1e-12:
            raise ModelError(f"sensor {sensor.name!r} does not see the axis's rigid motion",
                             path=f"axes.{name}.controller.{key}_sensor", value=sensor.name)
        gains[key] = gain
    kp = ctrl.Kp if ctrl.Kp is not None else ctrl.Kp_normalized * m_rigid  # type: ignore[operator]
    return ServoLoop(axis=name, mechanics=mech, drive=drive_model(spec.drive, act.kind == "rotational"),
                     controller=ctrl, actuator=actuator, tool=tool, m_rigid=m_rigid, Kp=float(kp),
                     Ti=ctrl.Ti, Kv=ctrl.Kv, position_gain=gains["position"], velocity_gain=gains["velocity"])


@dataclass(frozen=True, eq=False)
class SetpointTable:
    """Setpoints sampled for the loop: position, velocity, acceleration at the position-loop period
    (what the CNC's interpolator hands to the position loop) and the position at the base step (the
    reference of the following error)."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    fine_position: np.ndarray


class _Slots:
    def __init__(self) -> None:
        self.names: list[str] = []

    def __call__(self, name: str) -> int:
        if name in self.names:
            return self.names.index(name)
        self.names.append(name)
        return len(self.names) - 1


def servo_plant(loop: ServoLoop, *, disturbance: np.ndarray | None = None) -> "Plant":
    """The continuous part of the loop: mechanics and current loop, from the current reference.

    States ``(q, q̇, i)``; inputs ``"current.reference"`` (A) and, with ``disturbance`` (a vector of
    generalised forces per unit input, e.g. the tool vector), an external load ``"disturbance"``; outputs ``sensor.<name>`` (raw sensor units),
    ``tool.position``, ``tool.velocity``, ``actuator.velocity``, ``drive.current``, ``drive.effort``
    and every dof's position and velocity.
    """
    from .plant import Plant

    mech, drv = loop.mechanics, loop.drive
    n = mech.n
    act = mech.actuator(loop.actuator)
    base = mech.state_space()
    nx = 2 * n + 1
    A = np.zeros((nx, nx))
    A[: 2 * n, : 2 * n] = base.A
    m_inv = 1.0 / np.diag(mech.mass)
    A[n: 2 * n, 2 * n] = m_inv * act.vector * drv.kt
    A[2 * n, 2 * n] = -1.0 / drv.tau
    columns = [np.eye(nx)[2 * n] / drv.tau]
    inputs = ["current.reference"]
    if disturbance is not None:
        load = np.zeros(nx)
        load[n: 2 * n] = m_inv * np.asarray(disturbance, dtype=float)
        columns.append(load)
        inputs.append("disturbance")
    rows, names = [], []
    zeros = np.zeros(n)
    for sensor in mech.sensors:
        row = np.concatenate([zeros, sensor.vector] if sensor.kind == "velocity" else [sensor.vector, zeros])
        rows.append(np.append(row, 0.0))
        names.append(f"sensor.{sensor.name}")
    for name, row in (("tool.position", np.concatenate([loop.tool, zeros, [0.0]])),
                      ("tool.velocity", np.concatenate([zeros, loop.tool, [0.0]])),
                      ("actuator.velocity", np.concatenate([zeros, act.vector, [0.0]])),
                      ("drive.current", np.eye(nx)[2 * n]),
                      ("drive.effort", drv.kt * np.eye(nx)[2 * n])):
        rows.append(row)
        names.append(name)
    for i, dof in enumerate(mech.dofs):
        rows.append(np.eye(nx)[i])
        names.append(dof.position)
    for i, dof in enumerate(mech.dofs):
        rows.append(np.eye(nx)[n + i])
        names.append(dof.velocity)
    states = [d.position for d in mech.dofs] + [d.velocity for d in mech.dofs] + ["drive.current"]
    return Plant(A, np.column_stack(columns), np.array(rows), np.zeros((len(rows), len(columns))),
                 tuple(states), tuple(inputs), tuple(names))


def servo_program(loop: ServoLoop, setpoints: SetpointTable, *, nonlinear: bool = True) -> "HybridProgram":
    """Lower a servo loop and its sampled setpoints to a hybrid program.

    ``nonlinear=False`` drops the limits, quantizers and Coulomb friction (the linear loop).
    """
    from .simulate import program as p

    mech, drv, ctrl = loop.mechanics, loop.drive, loop.controller
    n = mech.n
    h = loop.base_period
    Np = loop.position_ratio
    s = _Slots()

    # ---- continuous part: mechanics (q, q̇) + current state i, every named output
    plant = servo_plant(loop)
    A, B, C = plant.A, plant.B[:, :1], plant.C
    nx = plant.n_states
    m_inv = 1.0 / np.diag(mech.mass)
    output_slots = tuple(s(name) for name in plant.outputs)

    links = [f for f in mech.frictions if nonlinear and (f.coulomb > 0 or f.static > 0)]
    F = np.zeros((nx, len(links)))
    G = np.zeros((len(links), nx))
    for j, link in enumerate(links):
        F[n: 2 * n, j] = m_inv * link.g
        G[j, n: 2 * n] = link.g
    friction_slots = tuple(s(f"friction.{link.name}") for link in links)

    ops: list = []
    blocks: list = []

    def block(ss: DiscreteSS, inputs, outputs, period: int, x0=None) -> int:
        blocks.append(p.LinearBlock(ss.A, ss.B, ss.C, ss.D, tuple(inputs), tuple(outputs), x0))
        return len(blocks) - 1

    def gain(src: str, dst: str, k: float, period: int) -> None:
        ops.append(p.Sum(period=period, inputs=(s(src),), weights=(k,), output=s(dst)))

    def quantize(src: str, dst: str, step: float | None, period: int) -> None:
        if nonlinear and step:
            ops.append(p.Quantize(period=period, input=s(src), output=s(dst), step=step, mode="floor"))
        else:
            gain(src, dst, 1.0, period)

    def delay(src: str, dst: str, samples: int, period: int) -> None:
        if samples:
            ops.append(p.Delay(period=period, input=s(src), output=s(dst), samples=samples))
        else:
            gain(src, dst, 1.0, period)

    # ---- position loop (period Np): setpoints, sampled feedback, P law, computation delay
    pos_sensor = mech.sensor(ctrl.position_sensor)
    for column, name in enumerate(("setpoint.position", "setpoint.velocity", "setpoint.acceleration")):
        ops.append(p.Setpoint(period=Np, column=column, output=s(name)))
    quantize(f"sensor.{pos_sensor.name}", "position.sampled", pos_sensor.step, Np)
    gain("position.sampled", "position.measured", 1.0 / loop.position_gain, Np)
    ops.append(p.Sum(period=Np, inputs=(s("setpoint.position"), s("position.measured")), weights=(1.0, -1.0),
                     output=s("position.error")))
    gain("position.error", "position.output", loop.Kv, Np)
    delay("position.output", "velocity.command_fb", ctrl.position_delay, Np)

    # ---- velocity loop (every base step)
    ff_samples = int(round(ctrl.feedforward_delay / h))
    delay("setpoint.velocity", "feedforward.velocity", ff_samples, 1)
    delay("setpoint.acceleration", "feedforward.acceleration", ff_samples, 1)
    ops.append(p.Sum(inputs=(s("velocity.command_fb"), s("feedforward.velocity")),
                     weights=(1.0, ctrl.velocity_feedforward), output=s("velocity.command")))
    vel_sensor = mech.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
    if vel_sensor.kind == "velocity":
        gain(f"sensor.{vel_sensor.name}", "velocity.raw", 1.0 / loop.velocity_gain, 1)
    else:
        quantize(f"sensor.{vel_sensor.name}", "velocity.sampled", vel_sensor.step, 1)
        diff = block(difference_block(h), [s("velocity.sampled")], [s("velocity.differenced")], 1)
        ops += [p.LinearOutput(block=diff), p.LinearUpdate(block=diff)]
        gain("velocity.differenced", "velocity.raw", 1.0 / loop.velocity_gain, 1)
    if ctrl.velocity_filter is not None:
        flt = block(_filter(ctrl.velocity_filter, h, "controller.velocity_filter"), [s("velocity.raw")],
                    [s("velocity.measured")], 1)
        ops += [p.LinearOutput(block=flt), p.LinearUpdate(block=flt)]
    else:
        gain("velocity.raw", "velocity.measured", 1.0, 1)
    ops.append(p.Sum(inputs=(s("velocity.command"), s("velocity.measured")), weights=(1.0, -1.0),
                     output=s("velocity.error")))

    limited = nonlinear and (np.isfinite(drv.i_peak) or np.isfinite(drv.u_max))
    if limited:
        ops.append(p.CurrentLimit(speed=s("actuator.velocity"), lower=s("current.lower"), upper=s("current.upper"),
                                  i_peak=drv.i_peak, u_max=drv.u_max, resistance=drv.resistance, ke=drv.ke,
                                  wl=drv.wl))
        gain("current.lower", "effort.lower", drv.kt, 1)
        gain("current.upper", "effort.upper", drv.kt, 1)
    aw = ctrl.anti_windup if limited else "none"
    tracking = (ctrl.tracking_time or loop.Ti) if aw == "back-calculation" else None
    law = velocity_law(ctrl.type, loop.Kp, loop.Ti, h, tracking)
    gated = "velocity.error_gated" if aw == "clamping" else "velocity.error"
    pi = block(law, [s("velocity.error"), s(gated), s("effort.excess"), s("velocity.measured")],
               [s("controller.feedback")], 1)
    ops.append(p.LinearOutput(block=pi))
    ops.append(p.Sum(inputs=(s("controller.feedback"), s("feedforward.acceleration")),
                     weights=(1.0, ctrl.acceleration_feedforward * loop.m_rigid), output=s("effort.unsaturated")))
    if limited:
        ops.append(p.Saturate(input=s("effort.unsaturated"), output=s("effort.command"),
                              lower_slot=s("effort.lower"), upper_slot=s("effort.upper")))
    else:
        gain("effort.unsaturated", "effort.command", 1.0, 1)
    ops.append(p.Sum(inputs=(s("effort.command"), s("effort.unsaturated")), weights=(1.0, -1.0),
                     output=s("effort.excess")))
    if aw == "clamping":
        ops.append(p.ClampGate(input=s("velocity.error"), unsaturated=s("effort.unsaturated"),
                               saturated=s("effort.command"), output=s(gated)))
    ops.append(p.LinearUpdate(block=pi))
    gain("effort.command", "current.reference", 1.0 / drv.kt, 1)
    signal = "current.reference"
    for i, spec in enumerate(ctrl.current_filters):
        out = f"current.filter{i + 1}"
        flt = block(_filter(spec, h, f"controller.current_filters.{i}"), [s(signal)], [s(out)], 1)
        ops += [p.LinearOutput(block=flt), p.LinearUpdate(block=flt)]
        signal = out
    delay(signal, "current.delayed", ctrl.velocity_delay, 1)
    if limited:
        ops.append(p.Saturate(input=s("current.delayed"), output=s("current.limited"),
                              lower_slot=s("current.lower"), upper_slot=s("current.upper")))
    else:
        gain("current.delayed", "current.limited", 1.0, 1)
    if nonlinear and ctrl.command_bits and np.isfinite(drv.i_peak):
        ops.append(p.Quantize(input=s("current.limited"), output=s("current.applied"),
                              step=2.0 * drv.i_peak / 2 ** ctrl.command_bits, mode="round"))
    else:
        gain("current.limited", "current.applied", 1.0, 1)

    # ---- following error against the setpoint at the base step
    ops.append(p.Setpoint(column=3, output=s("setpoint.fine")))
    ops.append(p.Sum(inputs=(s("setpoint.fine"), s(f"sensor.{pos_sensor.name}")),
                     weights=(1.0, -1.0 / loop.position_gain), output=s("following_error")))
    ops.append(p.Sum(inputs=(s("setpoint.fine"), s("tool.position")), weights=(1.0, -1.0),
                     output=s("tool_error")))

    table = _table(setpoints)
    continuous = p.ContinuousPart(
        A=A, B=B, C=C, D=np.zeros((C.shape[0], 1)), F=F, G=G,
        coulomb=np.array([link.coulomb for link in links]), static=np.array([link.static for link in links]),
        x0=np.zeros(nx), input_slots=(s("current.applied"),), output_slots=output_slots,
        friction_slots=friction_slots)
    return p.HybridProgram(step=h, slot_names=tuple(s.names), continuous=continuous, blocks=tuple(blocks),
                           ops=tuple(ops), table=table, record=tuple(range(len(s.names))))


def _filter(spec, period: float, path: str) -> DiscreteSS:
    try:
        return filter_block(spec, period)
    except ValueError as exc:
        raise ModelError(str(exc), path=path, value=spec.frequency) from None


def _table(setpoints: SetpointTable) -> np.ndarray:
    columns = [setpoints.position, setpoints.velocity, setpoints.acceleration, setpoints.fine_position]
    length = max(len(c) for c in columns)
    table = np.empty((4, length))
    for i, c in enumerate(columns):
        table[i, : len(c)] = c
        table[i, len(c):] = c[-1]
    return table
