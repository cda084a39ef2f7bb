"""What a simulation run says about its loop: divergence, linear instability, saturation-bound limit
cycles and a final error far from the target, as a :class:`~sicomat.servo.stability.Verdict`.

Definitions (also in ``docs/servo.md``):

* **Linearly unstable**: the closed loop's linear model has unstable poles
  (:func:`sicomat.servo.stability.loop_verdict`), whether or not the run has diverged yet: the limits of the
  drive may hold an unstable loop in a bounded oscillation, and a slowly growing mode may not have
  grown visibly within the run.
* **Diverged**: the kernel raised :class:`~sicomat.simulation.kernel.SimulationDiverged`.
* **Saturation-bound limit cycle**: over the last :data:`TAIL_FRACTION` of the run the applied current
  reference sits at one of its limits (within :data:`LIMIT_TOLERANCE` of the span between the two
  limits) in at least :data:`SATURATED_FRACTION` of the samples, and it goes from one limit to the
  other: once if the setpoint stands still over that tail (a drive holding a still axis has no reason
  to push at both limits), at least twice (a whole period) if the setpoint still moves there (a
  single move saturates once accelerating and once braking).
* **Final error far from the target**: once the setpoint has stopped within the run, the last
  following error exceeds :data:`FINAL_ERROR_BAND` (the settling band of the step metrics) of the
  setpoint's largest excursion, or :data:`FINAL_ERROR_COUNTS` quantization steps of the position
  sensor, whichever is larger (an axis with friction may stop a few counts off).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..servo.stability import Verdict, loop_verdict

if TYPE_CHECKING:  # pragma: no cover
    from typing import Mapping

    from ..servo.coupled import CoupledLoop
    from ..servo.loop import ServoLoop
    from .coupled import CoupledRun
    from .timeseries import TimeSeries
    from .kernel import SimulationDiverged

__all__ = ["TAIL_FRACTION", "SATURATED_FRACTION", "LIMIT_TOLERANCE", "FINAL_ERROR_BAND", "FINAL_ERROR_COUNTS",
           "simulation_verdict", "coupled_simulation_verdict", "diverged_verdict", "limit_cycle_warning",
           "saturation_cycle", "tail_start", "final_error_warning"]

TAIL_FRACTION = 0.25
"""The tail of a run examined for a limit cycle: its last quarter."""
SATURATED_FRACTION = 0.2
"""Fraction of the tail's samples at a current limit that, with oscillation, makes a limit cycle."""
LIMIT_TOLERANCE = 1e-3
"""A current within this fraction of the span ``upper − lower`` from a limit is at the limit."""
FINAL_ERROR_BAND = 0.02
"""Final error, as a fraction of the setpoint's excursion, beyond which the run ends off its target."""
FINAL_ERROR_COUNTS = 10
"""Final error, in position-sensor quantization steps, always tolerated."""


def simulation_verdict(loop: "ServoLoop", series: "TimeSeries", profile=None) -> Verdict:
    """The verdict of a finished run of ``loop``: its linear model's poles and what the run shows.

    ``profile`` (the setpoint) enables the final-error check. A limit cycle makes the verdict
    unstable even when the linear model is stable; a far final error is a warning only.
    """
    verdict = loop_verdict(loop)
    notes = [] if verdict.stable is not False else [_unstable_run(series)]
    cycle = limit_cycle_warning(series)
    if cycle is not None:
        notes.append(cycle)
    if profile is not None:
        far = final_error_warning(loop, series, profile)
        if far is not None:
            notes.append(far)
    return verdict.with_warnings(notes, unstable=cycle is not None)


def _unstable_run(series: "TimeSeries") -> str:
    duration = float(series.time[-1] + series.info.get("step", 0.0))
    return (f"the run of {duration:.3g} s did not diverge, but its figures are those of an unstable loop (bounded "
            "by the drive's limits, or not grown yet)")


def coupled_simulation_verdict(coupled: "CoupledLoop", run: "CoupledRun", profiles: "Mapping") -> Verdict:
    """The verdict of a finished run of coupled loops: the poles of the coupled linear loops
    (:func:`~sicomat.servo.coupled_linear.coupled_verdict`) and what each axis's run shows (a limit cycle,
    a far final error), each such warning naming its axis."""
    from ..servo.coupled_linear import coupled_verdict

    verdict = coupled_verdict(coupled)
    first = run[coupled.axes[0]]
    notes = [] if verdict.stable is not False else [_unstable_run(first)]
    cycles = False
    for loop in coupled.loops:
        cycle = limit_cycle_warning(run[loop.axis])
        far = final_error_warning(loop, run[loop.axis], profiles[loop.axis])
        notes += [f"axis {loop.axis}: {note}" for note in (cycle, far) if note is not None]
        cycles = cycles or cycle is not None
    return verdict.with_warnings(notes, unstable=cycles)


def diverged_verdict(loop: "ServoLoop", exc: "SimulationDiverged", verdict: Verdict | None = None) -> Verdict:
    """The verdict of a run that diverged: unstable, with the time of the divergence; from ``verdict``
    (the poles' verdict; default: those of ``loop``)."""
    verdict = loop_verdict(loop) if verdict is None else verdict
    return verdict.with_warnings([f"the simulation diverged at t = {exc.time:.6g} s: no figures"], unstable=True)


def limit_cycle_warning(series: "TimeSeries") -> str | None:
    """A sentence when the run ends in a saturation-bound limit cycle (module docstring), else None."""
    try:
        current, lower, upper = (series[name] for name in ("current.applied", "current.lower", "current.upper"))
    except KeyError:          # a continuous velocity loop: its current limits are not simulated
        return None
    start = tail_start(current.size)
    still = "setpoint.fine" in series.signals and np.ptp(series["setpoint.fine"][start:]) == 0
    cycle = saturation_cycle(current[start:], lower[start:], upper[start:], still)
    if cycle is None:
        return None
    saturated, switches = cycle
    return (f"saturation-bound limit cycle: from t = {float(series.time[start]):.3g} s the current reference is at "
            f"its limit in {100 * saturated:.0f} % of the samples, going from one limit to the other {switches} "
            f"time{'s' if switches > 1 else ''}")


def tail_start(n: int) -> int:
    """The first sample of the tail of ``n`` samples that the limit-cycle check examines (:data:`TAIL_FRACTION`)."""
    return n - max(int(TAIL_FRACTION * n), 1)


def saturation_cycle(current: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                     still: bool) -> tuple[float, int] | None:
    """``(fraction of samples at a limit, switches from one limit to the other)`` when the tail ``current`` with
    its limits ``lower``, ``upper`` is a saturation-bound limit cycle (module docstring; ``still``: the setpoint
    stands still over the tail), else None. The one definition of :func:`limit_cycle_warning` (``simulate``)
    and of :func:`~sicomat.simulation.simulate_batch`'s ``limit_cycle`` (studies)."""
    span = upper - lower
    with np.errstate(invalid="ignore"):
        tol = LIMIT_TOLERANCE * np.where(np.isfinite(span), span, np.nan)
        side = np.where(current >= upper - tol, 1, np.where(current <= lower + tol, -1, 0))
    saturated = np.count_nonzero(side) / side.size
    at = side[side != 0]
    switches = int(np.count_nonzero(at[1:] != at[:-1])) if at.size else 0
    if saturated < SATURATED_FRACTION or switches < (1 if still else 2):
        return None
    return float(saturated), switches


def final_error_warning(loop: "ServoLoop", series: "TimeSeries", profile) -> str | None:
    """A sentence when the run ends far from its target (module docstring), else None."""
    t_last = float(series.time[-1])
    if profile.end_time > t_last or profile.evaluate(np.array([t_last]))[1][0] != 0:
        return None           # the setpoint is still moving (a ramp, or a run shorter than the move)
    setpoint = series["setpoint.fine"]
    excursion = float(np.max(np.abs(setpoint - setpoint[0])))
    if excursion == 0:
        return None           # nothing was commanded
    sensor = loop.mechanics.sensor(loop.controller.position_sensor)
    quantum = abs((sensor.step or 0.0) / loop.position_gain)
    limit = max(FINAL_ERROR_BAND * excursion, FINAL_ERROR_COUNTS * quantum)
    error = float(series["following_error"][-1])
    if not abs(error) > limit:
        return None
    return (f"the run ends {abs(error) * 1e3:.4g} mm off its target (more than {limit * 1e3:.3g} mm: "
            f"{100 * FINAL_ERROR_BAND:g} % of the {excursion * 1e3:.4g} mm move or {FINAL_ERROR_COUNTS} sensor steps)")
