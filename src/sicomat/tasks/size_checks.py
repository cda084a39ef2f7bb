"""The checks of the sizing (:mod:`sicomat.tasks.size`): each a free function from the simulated motor's signals
and the ``components`` chain's parts to :class:`Check` objects. Formulas, sources and decisions:
``docs/components.md``, "Sizing"."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from ..servo.loop import ServoLoop

__all__ = ["Check", "MotorRun", "make_check", "drive_checks", "motor_checks", "train_checks", "motorless_checks",
           "mass_ratio_note", "CRITICAL_SPEED_FACTOR", "LIMIT_TOLERANCE"]

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


def make_check(name: str, value: float | None, limit: float | None, unit: str, note: str = "",
               missing: str = "") -> Check:
    """``ok = value <= limit`` (with :data:`LIMIT_TOLERANCE`); unknown with ``missing`` as the note."""
    if value is None or limit is None:
        return Check(name, value, None, None, unit, missing or note)
    return Check(name, float(value), float(limit), bool(value <= limit * (1.0 + LIMIT_TOLERANCE)), unit, note)


@dataclass(frozen=True)
class MotorRun:
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


def _linear(loop: "ServoLoop") -> bool:
    return loop.mechanics.actuator(loop.actuator).kind == "translational"


def _units(loop: "ServoLoop") -> tuple[str, str]:
    return ("N", "m/s") if _linear(loop) else ("N·m", "rad/s")


def motorless_checks(loop: "ServoLoop", run: MotorRun) -> list[Check]:
    effort, speed = _units(loop)
    word = "force" if _linear(loop) else "torque"
    missing = "the limit needs a motor part (mechanics type 'components')"
    return [make_check(f"peak_{word}", run.peak(run.effort), None, effort, missing=missing),
            make_check(f"rms_{word}", run.rms(run.effort), None, effort, missing=missing),
            make_check("max_speed", run.peak(run.speed), None, speed, missing=missing)]


def _bus_voltage(spec: Any, motor: Any | None) -> tuple[float | None, str]:
    """U_dc: the drive's supply voltage × √6 (the drive model's per-phase rms, space-vector modulation),
    else the motor's ``dc_bus``."""
    if spec.drive.supply_voltage is not None:
        return math.sqrt(6.0) * spec.drive.supply_voltage, "U_dc = √6 × the drive's supply_voltage"
    if motor is not None and getattr(motor, "dc_bus", None) is not None:
        return motor.dc_bus, "U_dc = the motor's dc_bus"
    return None, ""


def drive_checks(loop: "ServoLoop", spec: Any, run: MotorRun, mech: Any | None) -> list[Check]:
    drv = loop.drive
    out = []
    limit = drv.i_peak if math.isfinite(drv.i_peak) else None
    out.append(make_check("peak_current", run.peak(run.demand), limit, "A",
                          "the controller's current demand (before the drive's limits), A rms per phase",
                          missing="the drive gives no peak_current"))
    motor = mech.parts[0] if mech is not None else None
    bus, bus_note = _bus_voltage(spec, motor)
    if spec.drive.back_emf_constant is not None:
        # the drive model's phase voltage (rms) for the demanded current at the run's speed
        i, w = run.demand, run.speed
        u_phase = np.sqrt((drv.resistance * i + drv.ke * w) ** 2 + (drv.wl * w * i) ** 2)
        needed = math.sqrt(6.0) * float(np.max(u_phase))
        out.append(make_check("voltage", needed, bus, "V",
                              "√6·√((R·i + kE_ph·ω)² + (ω_el·L·i)²), the line-to-line peak the drive model "
                              "needs; " + bus_note,
                              missing="no DC bus: give the drive's supply_voltage or the motor's dc_bus"))
    return out


def motor_checks(mech: Any, spec: Any, loop: "ServoLoop", run: MotorRun, inertia_ratio_limit: float) -> list[Check]:
    from ..description import motor_checks as mc

    m = mech.parts[0]
    linear = m.kind == "linear-motor"
    effort_unit, speed_unit = _units(loop)
    word = "force" if linear else "torque"
    peak_limit = m.peak_force if linear else m.peak_torque
    continuous, which = ((m.continuous_force, "continuous_force") if linear else
                         ((m.stall_torque, "stall_torque") if m.stall_torque is not None else
                          (m.rated_torque, "rated_torque")))
    out = [make_check(f"peak_{word}", run.peak(run.effort), peak_limit, effort_unit,
                      f"max |kT·i| (the drive's effort) over the run, against the motor's peak_{word}",
                      missing=f"the motor gives no peak_{word}"),
           make_check(f"rms_{word}", run.rms(run.effort), continuous, effort_unit,
                      f"RMS of kT·i over the move (t = {run.time[run.window][0]:.4g} to "
                      f"{run.time[run.window][-1]:.4g} s), "
                      f"against the motor's {which}",
                      missing="the motor gives no "
                      + ("continuous_force" if linear else "stall_torque or rated_torque"))]
    speed = run.peak(run.speed)
    out.append(make_check("max_speed", speed, m.max_speed, speed_unit, "max |ω| of the motor shaft over the run"
                          if not linear else "max |v| of the primary over the run",
                          missing="the motor gives no max_speed"))
    ke = None                      # kE line-to-line rms: the motor's, else √3 × the drive's per-phase one
    if m.back_emf_constant is not None:
        ke = mc.back_emf_line_rms(m.back_emf_constant, m.back_emf_basis)
    elif spec.drive.back_emf_constant is not None:
        ke = math.sqrt(3.0) * spec.drive.back_emf_constant
    bus, bus_note = _bus_voltage(spec, m)
    if ke is None:
        out.append(make_check("back_emf", None, bus, "V", missing="the motor gives no back_emf_constant"))
    else:
        out.append(make_check("back_emf", math.sqrt(2.0) * ke * speed, bus, "V",
                              f"√2·kE_ll,rms·ω_max, the line-to-line peak at the top speed; {bus_note}",
                              missing="no DC bus: give the motor's dc_bus or the drive's supply_voltage"))
    if not linear:
        out.append(_inertia_ratio(mech, inertia_ratio_limit))
    return out


def _inertia_ratio(mech: Any, limit: float) -> Check:
    m = mech.parts[0]
    total = sum(b.referred for b in mech.chain.bodies)
    return make_check("inertia_ratio", (total - m.rotor_inertia) / m.rotor_inertia, limit, "1",
                      "(J at the motor shaft of everything but the rotor) / rotor_inertia")


def mass_ratio_note(mech: Any) -> str:
    m = mech.parts[0]
    load = sum(b.value for b in mech.chain.bodies) - m.primary_mass
    return (f"inertia ratio: not a check for a direct linear drive (no inertia matching); moved mass besides the "
            f"primary / primary mass = {load / m.primary_mass:.4g}")


def train_checks(mech: Any, run: MotorRun) -> list[Check]:
    """Gearboxes, couplings and the screw: each sees the motor's speed and torque through the gearboxes
    before it (rigid referral: torque × i, speed ÷ i)."""
    from ..description import drivetrain as dt

    out: list[Check] = []
    ratio = 1.0                      # speed of the motor / speed of the current shaft
    torque_peak, torque_rms, speed = run.peak(run.effort), run.rms(run.effort), run.peak(run.speed)
    for i, p in enumerate(mech.parts[1:], start=1):
        where = f"parts.{i} ({p.kind}{' ' + p.id if p.id else ''})"
        if p.kind == "coupling":
            out.append(make_check("coupling_torque", torque_peak * ratio, p.rated_torque, "N·m",
                                  f"{where}: peak motor torque × {ratio:g} (upper bound: the rotor's own "
                                  "acceleration torque not subtracted), against its rated_torque",
                                  missing=f"{where} gives no rated_torque"))
            out.append(make_check("coupling_speed", speed / ratio, p.max_speed, "rad/s",
                                  f"{where}: max |ω| of its shaft",
                                  missing=f"{where} gives no max_speed"))
        elif p.kind == "gearbox":
            out.append(make_check("gearbox_input_speed", speed / ratio, p.max_input_speed, "rad/s",
                                  f"{where}: max |ω| at its input", missing=f"{where} gives no max_input_speed"))
            ratio *= p.ratio
            eta = p.efficiency or 1.0
            out.append(make_check("gearbox_torque", torque_rms * ratio / eta, p.rated_torque, "N·m",
                                  f"{where}: RMS output torque over the move, T_rms·i/η (η = {eta:g}: an upper "
                                  "bound driving and braking), against its rated (nominal) output torque",
                                  missing=f"{where} gives no rated_torque"))
        elif p.kind == "ball-screw":
            w = speed / ratio
            wc = dt.critical_speed(p.root_diameter, p.length, p.mounting, youngs_modulus=p.youngs_modulus,
                                   density=p.density)
            out.append(make_check("screw_critical_speed", w, CRITICAL_SPEED_FACTOR * wc, "rad/s",
                                  f"{where}: max |ω| of the screw against {CRITICAL_SPEED_FACTOR:g} × its first "
                                  f"whirling speed {wc:.6g} rad/s ({p.mounting}, span = length {p.length:g} m between "
                                  "the bearings, root diameter)"))
            out.append(make_check("screw_max_speed", w, p.max_speed, "rad/s",
                                  f"{where}: max |ω| of the screw against its max_speed (the nut's DN limit)",
                                  missing=f"{where} gives no max_speed (the nut's DN limit)"))
    return out
