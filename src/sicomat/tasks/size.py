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
from .size_checks import (CRITICAL_SPEED_FACTOR, LIMIT_TOLERANCE, Check, MotorRun, drive_checks,
                          mass_ratio_note, motor_checks, motorless_checks, train_checks)

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
    run = MotorRun(t, series["drive.effort"], series["actuator.velocity"], demand, inside)
    spec = machine.axes[loop.axis]
    from ..description.components import ComponentsSpec

    mech = spec.mechanics
    notes: list[str] = list(series.info.get("notes", []))  # what the run left out
    checks = drive_checks(loop, spec, run, mech if isinstance(mech, ComponentsSpec) else None)
    if isinstance(mech, ComponentsSpec):
        checks += motor_checks(mech, spec, loop, run, inertia_ratio_limit)
        checks += train_checks(mech, run)
        if mech.parts[0].kind == "linear-motor":
            notes.append(mass_ratio_note(mech))
    else:
        checks = motorless_checks(loop, run) + checks
        notes.append(f"the mechanics is of type {mech.type if mech is not None else 'robot'!r}: the motor's and the drive train's limits need a "
                     "'components' chain with a motor part; only the drive's limits were checked")
    return SizingResult(loop.axis, _ordered(checks), verdict, move, notes=tuple(notes))
