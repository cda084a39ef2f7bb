"""Controller tuning, time approach (paper III.B.3): calibrated step responses, loop by loop.

The method of the NC manufacturers: the velocity loop first, with Ti large (0.5 s) so the integral
action sits far below the bandwidth; Kp is adjusted for a step overshoot near 10 %; then Ti for an
overshoot between 20 % and 40 %; finally Kv of the position loop for a desired position overshoot.
The step responses are those of the exact sampled linear loops (velocity loop at Tv, position loop
lifted at Tp; :mod:`sicomat.frequency.loops`), so every effect of the digital control and of the flexible
mechanics is in them. Each iteration is recorded with its rise time and overshoot.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import AnalysisError
from ..lti.response import zoh_matrices
from ..frequency.loops import LoopAnalysis
from ..simulation.timeseries import step_figures
from .frequency import require_tunable
from ..progress import notify

if TYPE_CHECKING:  # pragma: no cover
    from ..servo.loop import ServoLoop
    from ..progress import ProgressCallback

__all__ = ["TimeTargets", "StepResponse", "TimeTuningResult", "velocity_step", "position_step", "tune_time", "margin_check"]


@dataclass(frozen=True)
class TimeTargets:
    """Targets of the time approach (overshoots in percent) and the margins the result must keep.

    The tuned loop meets its targets only if, besides the overshoots, both loops keep a gain margin
    of ``min_gain_margin`` dB and a worst phase margin (over all gain crossovers, as ``sicomat
    margins`` reports it) of ``min_phase_margin`` degrees: the classic floors of 6 dB and 30°.
    """

    initial_Ti: float = 0.5
    velocity_overshoot_p: float = 10.0
    velocity_overshoot_pi: tuple[float, float] = (20.0, 40.0)
    position_overshoot: float = 1.0
    tolerance: float = 0.5
    min_gain_margin: float = 6.0
    min_phase_margin: float = 30.0


@dataclass(frozen=True)
class StepResponse:
    """A unit step response of a sampled loop with its overshoot, rise time (10–90 %) and 2 %
    settling time (:func:`sicomat.simulation.timeseries.step_figures`, as ``simulate`` reports them)."""

    time: np.ndarray
    response: np.ndarray
    overshoot_percent: float
    rise_time: float | None
    stable: bool
    settling_time: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures (without the samples); an unstable loop has no overshoot (None)."""
        return {"overshoot_percent": self.overshoot_percent if self.stable else None,
                "rise_time": self.rise_time, "settling_time": self.settling_time, "stable": self.stable}

    def plot(self, title: str = "step response"):
        """The response against time, its overshoot and rise time in the title; returns the Figure."""
        from ..plots.time import plot_step

        return plot_step(self, title)


def _step(A: np.ndarray, B: np.ndarray, C: np.ndarray, period: float, n: int, velocity_period: float,
          tail: int = 1) -> StepResponse:
    """Unit step response of ``x+ = A x + B``, ``y = C x``, judged by the poles of A (see
    :mod:`sicomat.servo.stability`; poles at z = 1, the free position a velocity loop does not hold, are
    marginal). The final value is the mean of the last ``tail`` samples; the figures are
    :func:`~sicomat.simulation.timeseries.step_figures` of a step of that size. An unstable loop has
    no overshoot, rise or settling time (``inf``, None, None) and its samples stop, as NaN, where
    they overflow."""
    from ..servo.stability import LoopPoles

    stable = LoopPoles("step", np.linalg.eigvals(A), period, velocity_period).stable
    x = np.zeros(A.shape[0])
    y = np.full(n, np.nan)
    with np.errstate(all="ignore"):
        for k in range(n):
            y[k] = C @ x
            if not np.isfinite(y[k]) or abs(y[k]) > 1e12:
                y[k] = np.nan
                break
            x = A @ x + B
    t = np.arange(n) * period
    final = float(np.mean(y[-max(1, tail):])) if stable else np.nan
    if not stable or not np.isfinite(final) or abs(final) < 1e-12:
        return StepResponse(t, y, np.inf, None, False)
    figures = step_figures(t, y, final)
    return StepResponse(t, y, figures.overshoot_percent, figures.rise_time, True, figures.settling_time)


def velocity_step(an: LoopAnalysis, Kp: float, Ti: float, duration: float | None = None) -> StepResponse:
    """Response of the measured velocity to a unit step of the velocity command (an analog loop:
    sampled at the velocity period, exactly: a step is held)."""
    T = an.loop.controller.velocity_period
    if an.analog:
        A, B, C = an.analog_closed_loop(Kp, Ti)
        A, B = zoh_matrices(A, B, T)
    else:
        A, B, C = an.velocity_closed_loop(Kp, Ti)
    # the position integrator does not act on the velocity: keep the output row of v_meas
    n = _samples(duration or max(30 * Ti if Ti < 0.05 else 0.5, 0.1), T)
    return _step(A, B[:, 0], C[1], T, n, T, tail=max(3, n // 50))


def _samples(duration: float, period: float) -> int:
    """Samples of a step response of ``duration``, refused beyond the memory limit (the response,
    its times and the normalised copy: 3 arrays of 8-byte numbers)."""
    from ..budget import require_memory

    n = round(duration / period)
    require_memory(24.0 * n, "this step response", f"{n} samples of {period:g} s x 3 arrays x 8 bytes")
    if n < 2:
        raise AnalysisError(f"a step response of {duration:g} s is shorter than two samples of {period:g} s")
    return int(n)


def position_step(an: LoopAnalysis, Kp: float, Ti: float, Kv: float, duration: float | None = None) -> StepResponse:
    """Response of the measured position to a unit position step (position loop at Tp, lifted; a
    continuous position loop sampled at the velocity period)."""
    from ..servo.stability import position_closed_loop

    ctrl = an.loop.controller
    Tv = ctrl.velocity_period
    duration = duration or max(10.0 / max(Kv, 1e-3), 0.2)
    A, B, C, Tp = position_closed_loop(an, Kp, Ti, Kv)
    if Tp is None:     # a continuous position loop: sampled exactly at the velocity period (a step is held)
        A, B = zoh_matrices(A, B[:, None], Tv)
        return _step(A, B[:, 0], C, Tv, _samples(duration, Tv), Tv)
    return _step(A, B, C, Tp, _samples(duration, Tp), Tv)


@dataclass(frozen=True)
class TimeTuningResult:
    """Gains found by the time approach and every iteration (rise time, overshoot)."""

    Kp: float
    Kp_normalized: float
    Ti: float
    Kv: float
    velocity: StepResponse
    position: StepResponse
    iterations: tuple[dict[str, Any], ...]
    targets_met: bool
    wall_time_s: float = 0.0
    notes: tuple[str, ...] = field(default_factory=tuple)
    unmet: tuple[str, ...] = ()
    margins: dict[str, float | None] = field(default_factory=dict)
    stable: bool | None = None
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat tune --method time --json`` object."""
        return {"method": "time", "velocity": {"Kp": self.Kp, "Kp_normalized": self.Kp_normalized, "Kp_si": self.Kp,
                                                      "Ti": self.Ti},
                "position": {"Kv": self.Kv},
                "achieved": {"velocity_overshoot_percent": self.velocity.to_dict()["overshoot_percent"],
                             "velocity_rise_time": self.velocity.rise_time,
                             "position_overshoot_percent": self.position.to_dict()["overshoot_percent"],
                             "position_rise_time": self.position.rise_time, **self.margins,
                             "targets_met": self.targets_met, "unmet": list(self.unmet)},
                "iterations": list(self.iterations), "notes": list(self.notes), "wall_time_s": self.wall_time_s,
                "stable": self.stable, "warnings": list(self.warnings)}


def _bisect(f, lo: float, hi: float, target: float, tol: float, record, max_iter: int = 40) -> float:
    """Find x in [lo, hi] (log scale) with f(x) ≈ target, f increasing."""
    for _ in range(max_iter):
        mid = np.sqrt(lo * hi)
        value = f(mid)
        record(mid, value)
        if abs(value - target) <= tol:
            return mid
        if value > target:
            hi = mid
        else:
            lo = mid
    return np.sqrt(lo * hi)


def tune_time(loop: "ServoLoop", targets: TimeTargets | None = None, *,
              progress: "ProgressCallback | None" = None) -> TimeTuningResult:
    """Run the three steps of the time approach automatically; ``progress`` (:mod:`sicomat.progress`)
    is told each step response computed (the total is not known in advance).

    Raises
    ------
    AnalysisError
        No gain reaches an overshoot target (e.g. the loop goes unstable before).
    """
    require_tunable(loop)
    start = time.perf_counter()
    t = targets or TimeTargets()
    an = LoopAnalysis.of(loop)
    m = loop.m_rigid
    iterations: list[dict[str, Any]] = []
    notes: list[str] = []
    count = [0]  # step responses computed, for the progress callback

    def v_overshoot(kp: float, ti: float) -> StepResponse:
        count[0] += 1
        notify(progress, "tuning by step responses", count[0], None)
        return velocity_step(an, kp, ti)

    # 1. Kp with Ti large, for ~10 % overshoot
    ti = t.initial_Ti

    def record_kp(kp, value):
        r = v_overshoot(kp, ti)
        iterations.append({"step": "velocity Kp", "Kp": kp, "Kp_normalized": kp / m, "Kp_si": kp, "Ti": ti,
                           "overshoot_percent": value, "rise_time": r.rise_time})

    lo, hi = m * 1.0, m * 10.0
    while v_overshoot(hi, ti).overshoot_percent < t.velocity_overshoot_p and hi < m * 1e6:
        lo, hi = hi, hi * 4
    while v_overshoot(lo, ti).overshoot_percent > t.velocity_overshoot_p and lo > m * 1e-3:
        lo, hi = lo / 4, lo
    kp = _bisect(lambda k: v_overshoot(k, ti).overshoot_percent, lo, hi, t.velocity_overshoot_p, t.tolerance, record_kp)

    # 2. Ti for an overshoot between 20 and 40 %: aim at the middle
    low, high = t.velocity_overshoot_pi
    goal = 0.5 * (low + high)

    def record_ti(ti_, value):
        r = v_overshoot(kp, ti_)
        iterations.append({"step": "velocity Ti", "Kp": kp, "Kp_normalized": kp / m, "Kp_si": kp, "Ti": ti_,
                           "overshoot_percent": value, "rise_time": r.rise_time})

    # overshoot grows as Ti shrinks: bisect on 1/Ti
    inv = _bisect(lambda x: v_overshoot(kp, 1.0 / x).overshoot_percent, 1.0 / t.initial_Ti,
                  1.0 / (loop.controller.velocity_period * 2), goal, 0.5 * (high - low) - 1.0,
                  lambda x, v: record_ti(1.0 / x, v))
    ti = 1.0 / inv
    vel = v_overshoot(kp, ti)

    # 3. Kv for the desired position overshoot: the largest Kv that does not exceed it
    def p_overshoot(kv: float) -> float:
        count[0] += 1
        notify(progress, "tuning by step responses", count[0], None)
        return position_step(an, kp, ti, kv).overshoot_percent

    def record_kv(kv, value):
        r = position_step(an, kp, ti, kv)
        iterations.append({"step": "position Kv", "Kv": kv, "overshoot_percent": value, "rise_time": r.rise_time})

    kv_hi = kp / m
    while p_overshoot(kv_hi) < t.position_overshoot and kv_hi < 1e4:
        kv_hi *= 2
    kv = _bisect(p_overshoot, kv_hi / 1e3, kv_hi, t.position_overshoot, 0.25, record_kv)
    pos = position_step(an, kp, ti, kv)
    if not vel.stable:
        raise AnalysisError("the velocity loop found by the time approach is unstable")
    unmet = []
    if abs(vel.overshoot_percent - goal) > 0.5 * (high - low):
        unmet.append(f"velocity overshoot {vel.overshoot_percent:.3g} % outside {low:g}-{high:g} %")
    if not abs(pos.overshoot_percent - t.position_overshoot) <= max(0.5, t.tolerance):
        unmet.append(f"position overshoot {pos.overshoot_percent:.3g} % instead of {t.position_overshoot:g} %")
    margins, margin_unmet = margin_check(an, kp, ti, kv, t)
    from ..servo.stability import loop_verdict

    verdict = loop_verdict(loop, Kp=kp, Ti=ti, Kv=kv, an=an)
    unmet += margin_unmet + list(verdict.warnings)
    return TimeTuningResult(Kp=kp, Kp_normalized=kp / m, Ti=ti, Kv=kv, velocity=vel, position=pos,
                            iterations=tuple(iterations), targets_met=not unmet,
                            wall_time_s=time.perf_counter() - start, notes=tuple(notes), unmet=tuple(unmet),
                            margins=margins, stable=verdict.stable,
                            warnings=tuple(f"not met: {u}" for u in unmet if u not in verdict.warnings)
                            + verdict.warnings)


def margin_check(an: LoopAnalysis, kp: float, ti: float, kv: float, t: TimeTargets) -> tuple[dict[str, float | None], list[str]]:
    """The tuned loop's margins as ``sicomat margins`` reports them (None: no crossover), and the floors
    they miss; ``an`` the loop's analysis (or another model of it: the coupled one)."""
    from ..frequency.margins import stability_margins

    out: dict[str, float | None] = {}
    unmet: list[str] = []
    for name in ("velocity", "position"):
        m = stability_margins(an.response(f"{name}-open", Kp=kp, Ti=ti, Kv=kv))
        gm, pm = m.gain_margin_db, m.phase_margin_deg
        out[f"{name}_gain_margin_db"] = float(gm) if np.isfinite(gm) else None
        out[f"{name}_worst_phase_margin_deg"] = float(pm) if np.isfinite(pm) else None
        if gm < t.min_gain_margin - 0.05:
            unmet.append(f"{name} gain margin {gm:.1f} dB below {t.min_gain_margin:g} dB")
        if pm < t.min_phase_margin - 0.05:
            unmet.append(f"{name} worst phase margin {pm:.1f}° below {t.min_phase_margin:g}°")
    return out, unmet
