"""The servo loop: mechanics + drive + CNC cascade controller, lowered to a hybrid program.

``build_servo_loop`` resolves an axis description into numbers (gains in physical units, sensor
conversions, rigid mass); ``servo_program`` lowers it, with sampled setpoints, into the
:class:`~sicomat.servo.program.HybridProgram` the kernel runs. Every block lowers to the same few
element kinds (linear blocks, sums, saturations, quantizers, delays, current limit, clamping gate):
the velocity law and the drive come from their kind's one lowering (:mod:`sicomat.servo.blocks`),
so a new controller or drive type is one class there, and needs nothing here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from .blocks import controller_kind, drive_model
from .controller import DiscreteSS, difference_block, filter_block
from .drive import DriveModel
from ..errors import ModelError
from ..mechanics.lumped import Load, Mechanics

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from ..lti.plant import Plant
    from ..description.servo import ControllerSpec
    from .program import HybridProgram

__all__ = ["ServoLoop", "build_servo_loop", "servo_plant", "drives_plant", "servo_program", "SetpointTable",
           "derived_signals"]


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
        Integral time (s) and position gain (1/s); ``Ti`` is infinite for a law without one (``P-TF``).
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
    from ..robotics.lowering import axis_mechanics

    mech = axis_mechanics(machine, name)   # checked: the loop's analyses need resolvable poles
    if not mech.actuators:
        raise ModelError("the mechanics has no actuator for the drive to command",
                         path=f"axes.{name}.mechanics.actuators")
    ctrl = spec.controller
    actuator = spec.drive.actuator or mech.actuators[0].name
    act = mech.actuator(actuator)
    pos_sensor = mech.sensor(ctrl.position_sensor)
    vel_sensor = mech.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
    if spec.mechanics is None and machine.robot is not None:     # a robot's axis: its tool is a robot sensor
        tool = np.array(mech.sensor(spec.tool or machine.robot.tool_sensor(name)).vector)
    elif spec.tool is not None:
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
                     Ti=ctrl.Ti if ctrl.Ti is not None else np.inf, Kv=ctrl.Kv, position_gain=gains["position"], velocity_gain=gains["velocity"])


@dataclass(frozen=True, eq=False)
class SetpointTable:
    """Setpoints sampled for the loop: position, velocity, acceleration at the position-loop period
    (what the CNC's interpolator hands to the position loop)."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @cached_property
    def columns(self) -> np.ndarray:
        """The kernel's table ``(3, n)``, shorter columns held at their last value (built once:
        the programs of a batch share it)."""
        columns = [self.position, self.velocity, self.acceleration]
        length = max(len(c) for c in columns)
        table = np.empty((3, length))
        for i, c in enumerate(columns):
            table[i, : len(c)] = c
            table[i, len(c):] = c[-1]
        return table


class _Slots:
    """Signal slots by name; an alias names a slot that carries the same value as another one
    (an identity copy costs no operation in the kernel)."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.aliases: dict[str, int] = {}

    def __call__(self, name: str) -> int:
        if name in self.aliases:
            return self.aliases[name]
        if name in self.names:
            return self.names.index(name)
        self.names.append(name)
        return len(self.names) - 1

    def alias(self, name: str, target: str) -> None:
        self.aliases[name] = self(target)


class _Prefixed:
    """One axis's view of the slots of a coupled program: every name it uses is ``<prefix><name>``."""

    def __init__(self, slots: _Slots, prefix: str) -> None:
        self.slots, self.prefix = slots, prefix

    def __call__(self, name: str) -> int:
        return self.slots(self.prefix + name)

    def alias(self, name: str, target: str) -> None:
        self.slots.alias(self.prefix + name, self.prefix + target)


class _Lowering:
    """The ops and blocks of a program being built on named slots, and the elements every block
    lowers to (a gain, a quantizer, a delay, a weighted sum, a linear block): an identity element is an
    alias, a nonlinear one is dropped in a linear program."""

    def __init__(self, slots: "_Slots | _Prefixed", nonlinear: bool, ops: list, blocks: list) -> None:
        self.s, self.nonlinear, self.ops, self.blocks = slots, nonlinear, ops, blocks

    def block(self, ss: DiscreteSS, inputs, outputs, x0=None) -> int:
        from . import program as p

        self.blocks.append(p.LinearBlock(ss.A, ss.B, ss.C, ss.D, tuple(inputs), tuple(outputs), x0))
        return len(self.blocks) - 1

    def gain(self, src: str, dst: str, k: float, period: int) -> None:
        from . import program as p

        if abs(k - 1.0) <= 1e-12:
            self.s.alias(dst, src)
        else:
            self.ops.append(p.Sum(period=period, inputs=(self.s(src),), weights=(k,), output=self.s(dst)))

    def quantize(self, src: str, dst: str, step: float | None, period: int) -> None:
        from . import program as p

        if self.nonlinear and step:
            self.ops.append(p.Quantize(period=period, input=self.s(src), output=self.s(dst), step=step, mode="floor"))
        else:
            self.s.alias(dst, src)

    def delay(self, src: str, dst: str, samples: int, period: int) -> None:
        from . import program as p

        if samples:
            self.ops.append(p.Delay(period=period, input=self.s(src), output=self.s(dst), samples=samples))
        else:
            self.s.alias(dst, src)

    def combine(self, dst: str, terms: list[tuple[str, float]], period: int) -> None:
        from . import program as p

        terms = [(name, w) for name, w in terms if w != 0.0]
        if len(terms) == 1 and abs(terms[0][1] - 1.0) <= 1e-12:
            self.s.alias(dst, terms[0][0])
        else:
            self.ops.append(p.Sum(period=period, inputs=tuple(self.s(n) for n, _ in terms),
                                  weights=tuple(w for _, w in terms), output=self.s(dst)))


def drives_plant(mech: Mechanics, drives: "Sequence[tuple[str, DriveModel, Load, np.ndarray]]", *,
                 disturbance: np.ndarray | None = None) -> "Plant":
    """Mechanics and the current loops of its drives, ``(prefix, drive, actuator, tool vector)`` each:
    :func:`servo_plant` (one drive, no prefix) and the coupled plant (one per axis, prefix ``"<axis>."``).

    States ``(q, q̇)`` then ``<prefix>drive.current`` per drive; inputs ``<prefix>current.reference``
    (and ``"disturbance"``); outputs ``sensor.<name>`` for every sensor, then per drive
    ``<prefix>tool.position``, ``.tool.velocity``, ``.actuator.velocity``, ``.drive.current``,
    ``.drive.effort``, then every dof's position and velocity.
    """
    from ..lti.plant import Plant
    from ..mechanics.statespace import second_order_state_space

    n, m = mech.n, len(drives)
    nx = 2 * n + m
    forces = [act.vector for _, _, act, _ in drives]
    forces += [np.asarray(disturbance, dtype=float)] if disturbance is not None else []
    A_mech, B_mech = second_order_state_space(mech.mass_factor, mech.damping, mech.stiffness,
                                              np.column_stack(forces))
    A = np.zeros((nx, nx))                      # eqs. (11)-(12) and the current loops
    A[: 2 * n, : 2 * n] = A_mech
    eye = np.eye(nx)
    columns, inputs = [], []
    for j, (prefix, drv, _, _) in enumerate(drives):
        A[n: 2 * n, 2 * n + j] = B_mech[n:, j] * drv.kt
        A[2 * n + j, 2 * n + j] = -1.0 / drv.tau
        columns.append(eye[2 * n + j] / drv.tau)
        inputs.append(f"{prefix}current.reference")
    if disturbance is not None:
        load = np.zeros(nx)
        load[: 2 * n] = B_mech[:, m]
        columns.append(load)
        inputs.append("disturbance")
    rows, names = [], []
    for sensor in mech.sensors:
        row = np.zeros(nx)
        (row[n: 2 * n] if sensor.kind == "velocity" else row[:n])[:] = sensor.vector
        rows.append(row)
        names.append(f"sensor.{sensor.name}")
    for j, (prefix, drv, act, tool) in enumerate(drives):
        for name, vector, offset in (("tool.position", tool, 0), ("tool.velocity", tool, n),
                                     ("actuator.velocity", act.vector, n)):
            row = np.zeros(nx)
            row[offset: offset + n] = vector
            rows.append(row)
            names.append(prefix + name)
        rows += [eye[2 * n + j], drv.kt * eye[2 * n + j]]
        names += [f"{prefix}drive.current", f"{prefix}drive.effort"]
    C = np.vstack([np.array(rows), eye[: 2 * n]])       # then every dof's position and velocity
    names += [d.position for d in mech.dofs] + [d.velocity for d in mech.dofs]
    states = [d.position for d in mech.dofs] + [d.velocity for d in mech.dofs]
    states += [f"{prefix}drive.current" for prefix, _, _, _ in drives]
    return Plant(A, np.column_stack(columns), C, np.zeros((len(names), len(columns))),
                 tuple(states), tuple(inputs), tuple(names))


def servo_plant(loop: ServoLoop, *, disturbance: np.ndarray | None = None) -> "Plant":
    """The continuous part of the loop: mechanics and current loop, from the current reference.

    States ``(q, q̇, i)``; inputs ``"current.reference"`` (A) and, with ``disturbance`` (a vector of
    generalised forces per unit input, e.g. the tool vector), an external load ``"disturbance"``; outputs ``sensor.<name>`` (raw sensor units),
    ``tool.position``, ``tool.velocity``, ``actuator.velocity``, ``drive.current``, ``drive.effort``
    and every dof's position and velocity.
    """
    mech = loop.mechanics
    return drives_plant(mech, [("", loop.drive, mech.actuator(loop.actuator), loop.tool)], disturbance=disturbance)


def friction_links(mech: Mechanics, nonlinear: bool) -> list:
    """The friction links the simulator steps with Coulomb friction (none in a linear program)."""
    return [f for f in mech.frictions if nonlinear and (f.coulomb > 0 or f.static > 0)]


def loop_reads(loop: ServoLoop) -> set[str]:
    """The continuous outputs an axis's discrete ops read (in its own names): its sensors, its
    actuator's speed (the drive's voltage limit)."""
    ctrl = loop.controller
    return {f"sensor.{ctrl.position_sensor}", f"sensor.{ctrl.velocity_sensor or ctrl.position_sensor}",
            "actuator.velocity"}


def servo_program(loop: ServoLoop, setpoints: SetpointTable, *, nonlinear: bool = True) -> "HybridProgram":
    """Lower a servo loop and its sampled setpoints to a hybrid program.

    ``nonlinear=False`` drops the limits, quantizers and Coulomb friction (the linear loop).
    """
    mech = loop.mechanics
    s = _Slots()
    # ---- continuous part: mechanics (q, q̇) + current state i; only the outputs the controller reads
    # are computed at every step, the others come from the recorded states afterwards
    plant = servo_plant(loop)
    read = loop_reads(loop)
    rows = [i for i, name in enumerate(plant.outputs) if name in read]
    links = friction_links(mech, nonlinear)
    for name in [plant.outputs[i] for i in rows] + [f"friction.{link.name}" for link in links]:
        s(name)                 # their slots first, in this order (the matrices come in _assemble)
    low = _Lowering(s, nonlinear, [], [])
    axis_ops(loop, mech, low)
    if loop.controller.velocity_loop == "continuous":
        return _analog_program(loop, plant, setpoints, s, low.ops, read_rows=rows, links=links)
    C = plant.C[rows]
    return _assemble(mech, loop.base_period, setpoints.columns, s, low.ops, low.blocks, links, plant.A,
                     plant.B[:, :1], C, np.zeros((C.shape[0], 1)), ["current.applied"],
                     [plant.outputs[i] for i in rows])


def axis_ops(loop: ServoLoop, mech: Mechanics, low: _Lowering, *, column: int = 0) -> None:
    """The discrete ops of one axis, appended to ``low``: the one lowering of an axis's loop, used by
    :func:`servo_program` and by the coupled program (:mod:`sicomat.servo.coupled`, on a prefixed view
    of the slots).

    Reads the slots ``sensor.<name>`` (the sensors, found by name in ``mech``) and
    ``actuator.velocity``, its setpoints from the table's columns ``column .. column + 2`` (position,
    velocity, acceleration), and writes ``current.applied``, the drive's current reference; a
    continuous velocity loop stops at the velocity command and the feedforward effort (the caller closes
    it in the continuous part).
    """
    from . import program as p

    drv, ctrl = loop.drive, loop.controller
    h = loop.base_period
    Np = loop.position_ratio
    s, ops, nonlinear = low.s, low.ops, low.nonlinear
    gain, quantize, delay, combine, block = low.gain, low.quantize, low.delay, low.combine, low.block

    pos_sensor = mech.sensor(ctrl.position_sensor)
    vel_sensor = mech.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
    analog = ctrl.velocity_loop == "continuous"
    # ---- sampling at the velocity period (a sensor shared by both loops is sampled once)
    if vel_sensor.kind == "position" and not analog:
        quantize(f"sensor.{vel_sensor.name}", "velocity.sampled", vel_sensor.step, 1)

    # ---- position loop (period Np): setpoints, sampled feedback, P law, computation delay
    for offset, name in enumerate(("setpoint.position", "setpoint.velocity", "setpoint.acceleration")):
        ops.append(p.Setpoint(period=Np, column=column + offset, output=s(name)))
    if ctrl.position_loop == "continuous":
        s.alias("position.sampled", f"sensor.{pos_sensor.name}")     # read continuously, unquantized
    elif vel_sensor.name == pos_sensor.name and vel_sensor.kind == "position" and not analog:
        s.alias("position.sampled", "velocity.sampled")
    else:
        quantize(f"sensor.{pos_sensor.name}", "position.sampled", pos_sensor.step, Np)
    if ctrl.position_loop == "discrete":
        combine("position.output", [("setpoint.position", loop.Kv),
                                    ("position.sampled", -loop.Kv / loop.position_gain)], Np)
        delay("position.output", "velocity.command_fb", ctrl.position_delay, Np)

    # ---- velocity loop (every base step), in current units from the controller's output on
    ff_samples = int(round(ctrl.feedforward_delay / h))
    if ctrl.velocity_feedforward:
        delay("setpoint.velocity", "feedforward.velocity", ff_samples, 1)
    if ctrl.acceleration_feedforward:
        delay("setpoint.acceleration", "feedforward.acceleration", ff_samples, 1)
    if ctrl.position_loop == "discrete":
        combine("velocity.command", [("velocity.command_fb", 1.0),
                                     ("feedforward.velocity", ctrl.velocity_feedforward)], 1)
    if analog:
        if ctrl.acceleration_feedforward:
            gain("feedforward.acceleration", "feedforward.effort", ctrl.acceleration_feedforward * loop.m_rigid, 1)
        return
    if vel_sensor.kind == "velocity":
        gain(f"sensor.{vel_sensor.name}", "velocity.raw", 1.0 / loop.velocity_gain, 1)
    else:
        diff = difference_block(h)
        diff = DiscreteSS(diff.A, diff.B, diff.C / loop.velocity_gain, diff.D / loop.velocity_gain)
        blk = block(diff, [s("velocity.sampled")], [s("velocity.raw")])
        ops += [p.LinearOutput(block=blk), p.LinearUpdate(block=blk)]
    if ctrl.velocity_filter is not None:
        flt = block(_filter(ctrl.velocity_filter, h, f"axes.{loop.axis}.controller.velocity_filter"), [s("velocity.raw")],
                    [s("velocity.measured")])
        ops += [p.LinearOutput(block=flt), p.LinearUpdate(block=flt)]
    else:
        s.alias("velocity.measured", "velocity.raw")
    combine("velocity.error", [("velocity.command", 1.0), ("velocity.measured", -1.0)], 1)

    limited = nonlinear and (np.isfinite(drv.i_peak) or np.isfinite(drv.u_max))
    if limited:
        ops.append(p.CurrentLimit(speed=s("actuator.velocity"), lower=s("current.lower"), upper=s("current.upper"),
                                  i_peak=drv.i_peak, u_max=drv.u_max, resistance=drv.resistance, ke=drv.ke,
                                  wl=drv.wl))
    aw = ctrl.anti_windup if limited else "none"
    tracking = (ctrl.tracking_time or loop.Ti) if aw == "back-calculation" else None
    law = controller_kind(ctrl.type, path=f"axes.{loop.axis}.controller.type").law(ctrl, loop.Kp, loop.Ti, h, tracking)
    # the law's state stays in effort units; its output is turned into current, its excess input back
    # second output: the integral action itself (N or N·m), recorded as a controller state
    law = DiscreteSS(law.A, law.B * np.array([[1.0, 1.0, drv.kt, 1.0]]),
                     np.vstack([law.C / drv.kt, law.C]), np.vstack([law.D / drv.kt, np.zeros_like(law.D)]))
    gated = "velocity.error_gated" if aw == "clamping" else "velocity.error"
    pi = block(law, [s("velocity.error"), s(gated), s("current.excess"), s("velocity.measured")],
               [s("current.feedback"), s("velocity.integral")])
    ops.append(p.LinearOutput(block=pi))
    combine("current.unsaturated", [("current.feedback", 1.0),
                                    ("feedforward.acceleration", ctrl.acceleration_feedforward * loop.m_rigid / drv.kt)],
            1)
    if limited:
        ops.append(p.Saturate(input=s("current.unsaturated"), output=s("current.command"),
                              lower_slot=s("current.lower"), upper_slot=s("current.upper")))
        if aw == "back-calculation":
            combine("current.excess", [("current.command", 1.0), ("current.unsaturated", -1.0)], 1)
    else:
        s.alias("current.command", "current.unsaturated")
    if aw == "clamping":
        ops.append(p.ClampGate(input=s("velocity.error"), unsaturated=s("current.unsaturated"),
                               saturated=s("current.command"), output=s(gated)))
    ops.append(p.LinearUpdate(block=pi))
    s.alias("current.reference", "current.command")
    signal = "current.reference"
    for i, spec in enumerate(ctrl.current_filters):
        out = f"current.filter{i + 1}"
        flt = block(_filter(spec, h, f"axes.{loop.axis}.controller.current_filters.{i}"), [s(signal)], [s(out)])
        ops += [p.LinearOutput(block=flt), p.LinearUpdate(block=flt)]
        signal = out
    delay(signal, "current.delayed", ctrl.velocity_delay, 1)
    if limited and (ctrl.current_filters or ctrl.velocity_delay):
        ops.append(p.Saturate(input=s("current.delayed"), output=s("current.limited"),
                              lower_slot=s("current.lower"), upper_slot=s("current.upper")))
    else:
        s.alias("current.limited", "current.delayed")
    if nonlinear and ctrl.command_bits and np.isfinite(drv.i_peak):
        ops.append(p.Quantize(input=s("current.limited"), output=s("current.applied"),
                              step=2.0 * drv.i_peak / 2 ** ctrl.command_bits, mode="round"))
    else:
        s.alias("current.applied", "current.limited")


def _analog_program(loop: ServoLoop, plant: "Plant", setpoints: SetpointTable, s: _Slots, ops: list, *,
                    read_rows: list[int], links: list) -> "HybridProgram":
    """The program of a loop whose velocity loop (and maybe position loop) is continuous: those
    loops join the continuous part (:mod:`sicomat.servo.analog`), the setpoints and a discrete position
    loop stay ops. Drive limits act inside the analog loop and are not simulated (see docs/servo.md)."""
    from .analog import analog_loop

    closed = analog_loop(loop, plant)
    nx, nc = plant.n_states, closed.n_controller
    for name in closed.inputs:          # feedforward inputs not used by the loop read a zero slot
        s(name)
    rows = [np.concatenate([plant.C[i], np.zeros(nc + len(closed.inputs))]) for i in read_rows]
    CD = np.array(rows + list(closed.outputs.values()))
    s.alias("current.reference", "current.command")
    return _assemble(loop.mechanics, loop.base_period, setpoints.columns, s, ops, [], links, closed.A, closed.B,
                     CD[:, : nx + nc], CD[:, nx + nc:], list(closed.inputs),
                     [plant.outputs[i] for i in read_rows] + list(closed.outputs))


def _assemble(mech: Mechanics, step: float, table: np.ndarray, s: _Slots, ops: list, blocks: list, links: list,
              A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, inputs: list[str],
              outputs: list[str]) -> "HybridProgram":
    """The hybrid program: the continuous part ``(A, B, C, D)`` (its first ``2n`` states the
    mechanics' ``(q, q̇)``) with the friction links, the ops and blocks, the setpoint table."""
    from . import program as p

    n, nx = mech.n, A.shape[0]
    from ..mechanics.statespace import second_order_input

    F = np.zeros((nx, len(links)))
    G = np.zeros((len(links), nx))
    if links:
        F[: 2 * n] = second_order_input(mech.mass_factor, np.column_stack([link.g for link in links]))
    for j, link in enumerate(links):
        G[j, n: 2 * n] = link.g
    continuous = p.ContinuousPart(
        A=A, B=B, C=C, D=D, F=F, G=G,
        coulomb=np.array([link.coulomb for link in links]), static=np.array([link.static for link in links]),
        x0=np.zeros(nx), input_slots=tuple(s(name) for name in inputs),
        output_slots=tuple(s(name) for name in outputs),
        friction_slots=tuple(s(f"friction.{link.name}") for link in links))
    return p.HybridProgram(step=step, slot_names=tuple(s.names), continuous=continuous,
                           blocks=tuple(blocks), ops=tuple(ops), table=table,
                           record=tuple(range(len(s.names))), aliases=dict(s.aliases))


def derived_signals(loop: ServoLoop, signals: dict[str, np.ndarray], fine_setpoint: np.ndarray,
                    states: np.ndarray, *, outputs: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Signals computed after a run rather than at every step: every output of the continuous part
    (from the states, shape ``(n_steps, nx)``; or ``outputs``, those of :func:`servo_plant` by name,
    computed by the caller: an axis of a coupled run), the setpoint at the base step and the following
    errors against it, the measured position and position error, the effort command."""
    if outputs is None:
        plant = servo_plant(loop)
        values = states[:, : plant.n_states] @ plant.C.T      # analog loops append controller states
        outputs = {name: values[:, i] for i, name in enumerate(plant.outputs)}
    out = dict(outputs)
    position = out[f"sensor.{loop.controller.position_sensor}"] / loop.position_gain
    out.update({"setpoint.fine": fine_setpoint,
                "following_error": fine_setpoint - position,
                "tool_error": fine_setpoint - out["tool.position"],
                "effort.command": loop.drive.kt * signals["current.command"],
                "position.measured": signals["position.sampled"] / loop.position_gain})
    out["position.error"] = signals["setpoint.position"] - out["position.measured"]
    return out


def _filter(spec, period: float, path: str) -> DiscreteSS:
    try:
        return filter_block(spec, period)
    except ValueError as exc:
        raise ModelError(str(exc), path=path, value=spec.frequency) from None


