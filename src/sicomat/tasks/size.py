"""The sizing check of ``sicomat size`` (issue 12, §5): the controlled **flexible** axis, simulated, against
the limits of its parts.

Vendor sizing tools size a rigid load from the move's kinematics; here the move (the axis's trajectory, a
``--move`` or a G-code path) runs through the closed-loop hybrid simulator, nonlinear (current and voltage
limits, friction), and the motor's effort (``drive.effort`` = Kt·i, torque or force) and speed
(``actuator.velocity``, the actuator's stretch rate: the motor shaft) are checked against the limits of
the ``components`` chain's parts. Every check's formula, source and decision is in ``docs/components.md``
("Sizing"). A check whose limit is unknown is reported with ``limit`` and ``ok`` None and a note, never
passed; a run that diverges or ends unstable is reported (``stable`` False) and not sized.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from ..progress import ProgressCallback
    from ..servo.loop import ServoLoop
    from ..servo.stability import Verdict
    from ..simulation.timeseries import TimeSeries

__all__ = ["Check", "SizingResult", "size_axis", "INERTIA_RATIO_LIMIT", "CRITICAL_SPEED_FACTOR",
           "LIMIT_TOLERANCE"]

INERTIA_RATIO_LIMIT = 10.0
"""Default largest load-to-rotor inertia ratio of a servo axis (``--inertia-ratio-limit``): the usual
rule of thumb for a ball-screw servo axis (docs/components.md, "Sizing")."""
CRITICAL_SPEED_FACTOR = 0.8
"""Fraction of the screw's first whirling speed that may be used (THK, "Permissible rotational speed":
the critical speed × 0.8; NSK and Schneeberger use the same factor)."""
LIMIT_TOLERANCE = 1e-9
"""Relative slack of ``value <= limit``: a demand equal to a limit (a current clipped at the drive's
peak current) passes; anything measurably above fails."""


@dataclass(frozen=True)
class Check:
    """One sizing check: ``value`` against ``limit`` (SI, in ``unit``); ``ok`` None when the limit is
    unknown (``note`` says what is missing) or the value cannot be computed."""

    name: str
    value: float | None
    limit: float | None
    ok: bool | None
    unit: str
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """``{"name", "value", "limit", "ok", "unit", "note"}``."""
        return {"name": self.name, "value": self.value, "limit": self.limit, "ok": self.ok, "unit": self.unit,
                "note": self.note}


def _check(name: str, value: float | None, limit: float | None, unit: str, note: str = "",
           missing: str = "") -> Check:
    """``ok = value <= limit`` (with :data:`LIMIT_TOLERANCE`); unknown with ``missing`` as the note."""
    if value is None or limit is None:
        return Check(name, value, None, None, unit, missing or note)
    return Check(name, float(value), float(limit), bool(value <= limit * (1.0 + LIMIT_TOLERANCE)), unit, note)


@dataclass(frozen=True)
class SizingResult:
    """What :func:`size_axis` found: the checks (failing first, then passing, then unknown), the run's
    stability verdict and what was simulated (``move``: source, window of the RMS values, duration)."""

    axis: str
    checks: tuple[Check, ...]
    verdict: "Verdict"
    move: dict[str, Any] = field(default_factory=dict)
    diverged: bool = False
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool | None:
        """False if any check fails; True if every check passes; None if none fails but one is unknown
        (or nothing was sized: an unstable run)."""
        flags = [c.ok for c in self.checks]
        if False in flags:
            return False
        if not flags or None in flags or self.verdict.stable is False:
            return None
        return True

    @property
    def failed(self) -> list[Check]:
        """The failing checks."""
        return [c for c in self.checks if c.ok is False]

    def check(self, name: str) -> Check:
        """The check called ``name``."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat size --json`` object: ``axis``, ``ok``, ``checks`` (each ``name``, ``value``,
        ``limit``, ``ok``, ``unit``, ``note``), ``failed`` and ``unknown`` (names), ``move``, ``notes``,
        ``diverged``, ``stable``, ``warnings`` (a failing check is a warning too, as ``tune``'s unmet targets)."""
        failed = [f"sizing check {c.name} failed: {c.value:.6g} > {c.limit:.6g} {c.unit}".rstrip()
                  for c in self.failed if c.value is not None and c.limit is not None]
        verdict = self.verdict.with_warnings(failed)
        return {"axis": self.axis, "ok": self.ok, "checks": [c.to_dict() for c in self.checks],
                "failed": [c.name for c in self.checks if c.ok is False],
                "unknown": [c.name for c in self.checks if c.ok is None], "move": dict(self.move),
                "notes": list(self.notes), "diverged": self.diverged, **verdict.to_dict()}


def _ordered(checks: list[Check]) -> tuple[Check, ...]:
    rank = {False: 0, True: 1, None: 2}
    return tuple(sorted(checks, key=lambda c: rank[c.ok]))   # stable: the order within a group is kept


# --------------------------------------------------------------------------- the run
def size_axis(machine: "Machine", axis: str | None = None, *, move_mm: float | None = None,
              max_velocity: float | None = None, max_acceleration: float | None = None,
              gcode_path: Any = None, feed_mm_min: float | None = None,
              inertia_ratio_limit: float = INERTIA_RATIO_LIMIT,
              progress: "ProgressCallback | None" = None) -> SizingResult:
    """Simulate a move of ``axis`` on the closed loop and check the motor and the drive train against it.

    The move is, by priority: a G-code path (``gcode_path``, the axes it moves simulated as ``simulate
    --gcode`` does, ``axis`` one of them), a trapezoidal move of ``move_mm`` mm (limits ``max_velocity``,
    ``max_acceleration`` or the model's, as ``simulate --move``), or the axis's trajectory. The run is
    nonlinear (the drive's current and voltage limits, friction, quantizers). Peaks are taken over the
    whole run (the move and its settling), RMS values over the move (from its start to the end of its
    setpoint: the move repeated without dwell, docs/components.md).

    Raises
    ------
    ModelError
        No move (no trajectory, no ``move_mm``, no ``gcode_path``), a step trajectory (infinite
        acceleration), an unknown axis, a G-code file that is missing or does not move ``axis``.
    """
    if not inertia_ratio_limit > 0 or not math.isfinite(inertia_ratio_limit):
        raise ModelError("expected a finite inertia ratio limit > 0", path="inertia_ratio_limit",
                         value=inertia_ratio_limit)
    name = machine.axis_name(axis)
    if gcode_path is not None:
        if move_mm is not None:
            raise ModelError("a G-code path cannot be combined with a move", path="gcode_path", value=str(gcode_path))
        return _size_gcode(machine, name, gcode_path, feed_mm_min, inertia_ratio_limit, progress)
    from ..servo.loop import build_servo_loop
    from ..simulation import simulate
    from ..simulation.checks import diverged_verdict, simulation_verdict
    from ..simulation.kernel import SimulationDiverged
    from .simulate import choose_profile

    loop = build_servo_loop(machine, name)
    trajectory = machine.axes[name].trajectory
    if move_mm is None and trajectory is None:
        raise ModelError(f"no move to size: give a move (mm) or a G-code file, or add a [axes.{name}.trajectory] "
                         "table", path="trajectory")
    profile, duration = choose_profile(trajectory, None, move_mm, max_velocity, max_acceleration)
    if profile.kind == "step":
        raise ModelError("a step has an infinite acceleration and cannot be sized: give a move (mm) or a "
                         "trapezoid or S-curve trajectory", path="trajectory", value="step")
    source = "move" if move_mm is not None else "trajectory"
    try:
        series = simulate(loop, profile, duration, nonlinear=True, progress=progress)
    except SimulationDiverged as exc:
        return SizingResult(name, (), diverged_verdict(loop, exc), {"source": source}, diverged=True,
                            notes=("the simulation diverged: nothing was sized",))
    verdict = simulation_verdict(loop, series, profile)
    start, end = float(profile.breaks[0]), float(profile.end_time)
    return _sized(machine, loop, series, verdict, source, (start, end), inertia_ratio_limit)


def _size_gcode(machine: "Machine", name: str, gcode_path: Any, feed_mm_min: float | None,
                inertia_ratio_limit: float, progress: "ProgressCallback | None") -> SizingResult:
    from ..servo.loop import build_servo_loop
    from ..servo.stability import Verdict
    from .simulate import simulate_gcode

    payload, run = simulate_gcode(machine, gcode_path, feed_mm_min, None, None, nonlinear=True, progress=progress)
    if run is None:
        verdict = Verdict(False, tuple(payload.get("warnings", ())))
        return SizingResult(name, (), verdict, {"source": "gcode", "file": str(gcode_path)}, diverged=True,
                            notes=("the simulation diverged: nothing was sized",))
    moved = {machine_axis: path_axis for path_axis, machine_axis in run.info["machine_axes"].items()}
    if name not in moved:
        raise ModelError(f"the G-code path does not move axis {name!r}; it moves {', '.join(sorted(moved))}",
                         path="axis", value=name)
    series = run.axes[moved[name]]
    loop = build_servo_loop(machine, name)
    window = (float(run.samples.time[0]), float(run.samples.profile.end_time))
    sized = _sized(machine, loop, series, run.verdicts[moved[name]], "gcode", window, inertia_ratio_limit)
    return SizingResult(sized.axis, sized.checks, sized.verdict, {**sized.move, "file": str(gcode_path)},
                        notes=sized.notes)


# --------------------------------------------------------------------------- the checks
@dataclass(frozen=True)
class _Run:
    """The motor's signals of a run: effort (N·m or N), shaft speed, current demand and its bounds."""

    time: np.ndarray
    effort: np.ndarray
    speed: np.ndarray
    demand: np.ndarray
    window: np.ndarray           # the samples of the move (the RMS values)

    def peak(self, x: np.ndarray) -> float:
        return float(np.max(np.abs(x)))

    def rms(self, x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(x[self.window] ** 2)))


def _sized(machine: "Machine", loop: "ServoLoop", series: "TimeSeries", verdict: "Verdict", source: str,
           window: tuple[float, float], inertia_ratio_limit: float) -> SizingResult:
    move = {"source": source, "window": [window[0], window[1]],
            "duration": float(series.time[-1] + series.info.get("step", 0.0))}
    if verdict.stable is False:
        return SizingResult(loop.axis, (), verdict, move, notes=("the run is unstable: nothing was sized",))
    t = series.time
    inside = (t >= window[0]) & (t <= window[1])
    if np.count_nonzero(inside) < 2:          # a move shorter than two samples: the whole run
        inside = np.ones_like(t, dtype=bool)
        move["window"] = [float(t[0]), float(t[-1])]
    demand = series.signals.get("current.unsaturated", series["drive.current"])
    run = _Run(t, series["drive.effort"], series["actuator.velocity"], demand, inside)
    spec = machine.axes[loop.axis]
    from ..description.components import ComponentsSpec

    mech = spec.mechanics
    notes: list[str] = []
    checks = _drive_checks(loop, spec, run, mech if isinstance(mech, ComponentsSpec) else None)
    if isinstance(mech, ComponentsSpec):
        checks += _motor_checks(mech, spec, loop, run, inertia_ratio_limit)
        checks += _train_checks(mech, run)
        if mech.parts[0].kind == "linear-motor":
            notes.append(_mass_ratio_note(mech))
        notes += _angle_coordinate_note(mech, spec, loop.axis)
    else:
        checks = _motorless_checks(loop, run) + checks
        notes.append(f"the mechanics is of type {mech.type!r}: the motor's and the drive train's limits need a "
                     "'components' chain with a motor part; only the drive's limits were checked")
    return SizingResult(loop.axis, _ordered(checks), verdict, move, notes=tuple(notes))


def _angle_coordinate_note(mech: Any, spec: Any, axis: str) -> list[str]:
    """A note when the axis coordinate is a rotation: no ``tool`` and a rotary encoder as the position sensor
    make the move's distance, velocity and acceleration radians of the motor (the setpoint follows the sensor)."""
    if spec.tool is not None or spec.controller is None:
        return []
    entry = mech.chain.sensors.get(spec.controller.position_sensor)
    if entry is None:
        return []
    kinds = {b.name: b.kind for b in mech.chain.bodies}
    if entry.get("stretch") != "rotational" and kinds.get(entry["body"]) != "rotational":
        return []
    table = mech.chain.bodies[-1].name
    return [f"the axis coordinate is the angle of the position sensor {spec.controller.position_sensor!r} (no "
            f"[axes.{axis}] tool): the move's distance and limits were read in rad, rad/s, rad/s²; set "
            f"tool = {table!r} to move the table in metres"]


def _linear(loop: "ServoLoop") -> bool:
    return loop.mechanics.actuator(loop.actuator).kind == "translational"


def _units(loop: "ServoLoop") -> tuple[str, str]:
    return ("N", "m/s") if _linear(loop) else ("N·m", "rad/s")


def _motorless_checks(loop: "ServoLoop", run: _Run) -> list[Check]:
    effort, speed = _units(loop)
    word = "force" if _linear(loop) else "torque"
    missing = "the limit needs a motor part (mechanics type 'components')"
    return [_check(f"peak_{word}", run.peak(run.effort), None, effort, missing=missing),
            _check(f"rms_{word}", run.rms(run.effort), None, effort, missing=missing),
            _check("max_speed", run.peak(run.speed), None, speed, missing=missing)]


def _bus_voltage(spec: Any, motor: Any | None) -> tuple[float | None, str]:
    """U_dc: the drive's supply voltage × √6 (the drive model's per-phase rms, space-vector modulation),
    else the motor's ``dc_bus``."""
    if spec.drive.supply_voltage is not None:
        return math.sqrt(6.0) * spec.drive.supply_voltage, "U_dc = √6 × the drive's supply_voltage"
    if motor is not None and getattr(motor, "dc_bus", None) is not None:
        return motor.dc_bus, "U_dc = the motor's dc_bus"
    return None, ""


def _drive_checks(loop: "ServoLoop", spec: Any, run: _Run, mech: Any | None) -> list[Check]:
    drv = loop.drive
    out = []
    limit = drv.i_peak if math.isfinite(drv.i_peak) else None
    out.append(_check("peak_current", run.peak(run.demand), limit, "A",
                      "the controller's current demand (before the drive's limits), A rms per phase",
                      missing="the drive gives no peak_current"))
    motor = mech.parts[0] if mech is not None else None
    bus, bus_note = _bus_voltage(spec, motor)
    if spec.drive.back_emf_constant is not None:
        # the drive model's phase voltage (rms) for the demanded current at the run's speed
        i, w = run.demand, run.speed
        u_phase = np.sqrt((drv.resistance * i + drv.ke * w) ** 2 + (drv.wl * w * i) ** 2)
        needed = math.sqrt(6.0) * float(np.max(u_phase))
        out.append(_check("voltage", needed, bus, "V",
                          f"√6·√((R·i + kE_ph·ω)² + (ω_el·L·i)²), the line-to-line peak the drive model needs; {bus_note}",
                          missing="no DC bus: give the drive's supply_voltage or the motor's dc_bus"))
    return out


def _motor_checks(mech: Any, spec: Any, loop: "ServoLoop", run: _Run, inertia_ratio_limit: float) -> list[Check]:
    from ..description import motor_checks as mc

    m = mech.parts[0]
    linear = m.kind == "linear-motor"
    effort_unit, speed_unit = _units(loop)
    word = "force" if linear else "torque"
    peak_limit = m.peak_force if linear else m.peak_torque
    continuous, which = ((m.continuous_force, "continuous_force") if linear else
                         ((m.stall_torque, "stall_torque") if m.stall_torque is not None else
                          (m.rated_torque, "rated_torque")))
    out = [_check(f"peak_{word}", run.peak(run.effort), peak_limit, effort_unit,
                  f"max |kT·i| (the drive's effort) over the run, against the motor's peak_{word}",
                  missing=f"the motor gives no peak_{word}"),
           _check(f"rms_{word}", run.rms(run.effort), continuous, effort_unit,
                  f"RMS of kT·i over the move (t = {run.time[run.window][0]:.4g} to {run.time[run.window][-1]:.4g} s), "
                  f"against the motor's {which}",
                  missing="the motor gives no " + ("continuous_force" if linear else "stall_torque or rated_torque"))]
    speed = run.peak(run.speed)
    out.append(_check("max_speed", speed, m.max_speed, speed_unit, "max |ω| of the motor shaft over the run"
                      if not linear else "max |v| of the primary over the run",
                      missing="the motor gives no max_speed"))
    ke = None                      # kE line-to-line rms: the motor's, else √3 × the drive's per-phase one
    if m.back_emf_constant is not None:
        ke = mc.back_emf_line_rms(m.back_emf_constant, m.back_emf_basis)
    elif spec.drive.back_emf_constant is not None:
        ke = math.sqrt(3.0) * spec.drive.back_emf_constant
    bus, bus_note = _bus_voltage(spec, m)
    if ke is None:
        out.append(_check("back_emf", None, bus, "V", missing="the motor gives no back_emf_constant"))
    else:
        out.append(_check("back_emf", math.sqrt(2.0) * ke * speed, bus, "V",
                          f"√2·kE_ll,rms·ω_max, the line-to-line peak at the top speed; {bus_note}",
                          missing="no DC bus: give the motor's dc_bus or the drive's supply_voltage"))
    if not linear:
        out.append(_inertia_ratio(mech, inertia_ratio_limit))
    return out


def _inertia_ratio(mech: Any, limit: float) -> Check:
    m = mech.parts[0]
    total = sum(b.referred for b in mech.chain.bodies)
    return _check("inertia_ratio", (total - m.rotor_inertia) / m.rotor_inertia, limit, "1",
                  "(J at the motor shaft of everything but the rotor) / rotor_inertia")


def _mass_ratio_note(mech: Any) -> str:
    m = mech.parts[0]
    load = sum(b.value for b in mech.chain.bodies) - m.primary_mass
    return (f"inertia ratio: not a check for a direct linear drive (no inertia matching); moved mass besides the "
            f"primary / primary mass = {load / m.primary_mass:.4g}")


def _train_checks(mech: Any, run: _Run) -> list[Check]:
    """Gearboxes, couplings and the screw: each sees the motor's speed and torque through the gearboxes
    before it (rigid referral: torque × i, speed ÷ i)."""
    from ..description import drivetrain as dt

    out: list[Check] = []
    ratio = 1.0                      # speed of the motor / speed of the current shaft
    torque_peak, torque_rms, speed = run.peak(run.effort), run.rms(run.effort), run.peak(run.speed)
    for i, p in enumerate(mech.parts[1:], start=1):
        where = f"parts.{i} ({p.kind}{' ' + p.id if p.id else ''})"
        if p.kind == "coupling":
            out.append(_check("coupling_torque", torque_peak * ratio, p.rated_torque, "N·m",
                              f"{where}: peak motor torque × {ratio:g} (upper bound: the rotor's own "
                              "acceleration torque not subtracted), against its rated_torque",
                              missing=f"{where} gives no rated_torque"))
            out.append(_check("coupling_speed", speed / ratio, p.max_speed, "rad/s", f"{where}: max |ω| of its shaft",
                              missing=f"{where} gives no max_speed"))
        elif p.kind == "gearbox":
            out.append(_check("gearbox_input_speed", speed / ratio, p.max_input_speed, "rad/s",
                              f"{where}: max |ω| at its input", missing=f"{where} gives no max_input_speed"))
            ratio *= p.ratio
            eta = p.efficiency or 1.0
            out.append(_check("gearbox_torque", torque_rms * ratio / eta, p.rated_torque, "N·m",
                              f"{where}: RMS output torque over the move, T_rms·i/η (η = {eta:g}: an upper bound "
                              "driving and braking), against its rated (nominal) output torque",
                              missing=f"{where} gives no rated_torque"))
        elif p.kind == "ball-screw":
            w = speed / ratio
            wc = dt.critical_speed(p.root_diameter, p.length, p.mounting, youngs_modulus=p.youngs_modulus,
                                   density=p.density)
            out.append(_check("screw_critical_speed", w, CRITICAL_SPEED_FACTOR * wc, "rad/s",
                              f"{where}: max |ω| of the screw against {CRITICAL_SPEED_FACTOR:g} × its first whirling "
                              f"speed {wc:.6g} rad/s ({p.mounting}, span = length {p.length:g} m between the bearings, "
                              "root diameter)"))
            out.append(_check("screw_max_speed", w, p.max_speed, "rad/s",
                              f"{where}: max |ω| of the screw against its max_speed (the nut's DN limit)",
                              missing=f"{where} gives no max_speed (the nut's DN limit)"))
    return out
