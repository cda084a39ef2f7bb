"""Automatic tuning of the cascade controller, frequency approach (paper III.B.1–B.2).

1. *Initial tuning on the rigid model*: the lags of sampling, hold, computation delay, current loop,
   differencing and filters are folded into one equivalent delay τ; the velocity PI is then solved in
   closed form for a phase margin φ_mv at ω_vit, and Kv for a phase margin φ_mp (or a crossover).
2. *Accurate tuning on the complete model*: Nelder–Mead (scipy) on the full digital, flexible loop
   frequency responses (:mod:`sicomat.frequency.loops`) to meet the same targets; then, if the gain margin is
   below the minimum, again with the gain-margin criterion. When the targets cannot all be met, a
   notch at the limiting resonance is suggested and the tuning is repeated with it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize

from ..errors import AnalysisError, ModelError
from ..frequency.loops import LoopAnalysis, default_omega
from ..progress import notify
from ..servo.blocks import controller_kind, loop_delays

if TYPE_CHECKING:  # pragma: no cover
    from ..servo.loop import ServoLoop
    from ..progress import ProgressCallback

__all__ = ["TuningTargets", "TuningResult", "Gains", "Achieved", "equivalent_delay", "require_tunable",
           "rigid_velocity_pi", "rigid_position_gain", "tune_frequency", "targets_on"]

_DEG = np.pi / 180.0


@dataclass(frozen=True)
class TuningTargets:
    """What the frequency tuning aims at.

    ``velocity_crossover`` (rad/s; default ``2π f_meca / 4``), ``velocity_phase_margin`` and
    ``position_phase_margin`` (degrees), or ``position_crossover`` (rad/s) instead of the latter;
    ``min_gain_margin`` (dB) of both loops.
    """

    velocity_crossover: float | None = None
    velocity_phase_margin: float = 45.0
    position_phase_margin: float | None = 80.0
    position_crossover: float | None = None
    min_gain_margin: float = 6.0
    tolerance_deg: float = 1.0
    tolerance_rel: float = 0.03


@dataclass(frozen=True)
class Gains:
    """Controller gains: Kp (physical units), Kp normalised (1/s), Ti (s), Kv (1/s)."""

    Kp: float
    Kp_normalized: float
    Ti: float
    Kv: float

    def to_dict(self) -> dict[str, Any]:
        """The ``tune --json`` shape: ``velocity: {Kp, Kp_normalized, Ti}``, ``position: {Kv}``, named and
        in the units of the model file's ``[controller]`` (``Kp`` physical; ``Kp_si``, the same value, is
        deprecated)."""
        return {"velocity": {"Kp": self.Kp, "Kp_normalized": self.Kp_normalized, "Kp_si": self.Kp, "Ti": self.Ti},
                "position": {"Kv": self.Kv}}


@dataclass(frozen=True)
class Achieved:
    """Margins and crossovers measured on the complete model."""

    velocity_phase_margin_deg: float
    velocity_crossover_rad_s: float
    velocity_gain_margin_db: float
    position_phase_margin_deg: float
    position_crossover_rad_s: float
    position_gain_margin_db: float
    velocity_worst_phase_margin_deg: float = float("nan")
    velocity_crossovers: int = 1
    velocity_bandwidth_rad_s: float | None = None
    position_bandwidth_rad_s: float | None = None
    position_worst_phase_margin_deg: float = float("nan")

    @property
    def gain_margin_db(self) -> float:
        """The smaller gain margin of the two loops."""
        return min(self.velocity_gain_margin_db, self.position_gain_margin_db)


@dataclass(frozen=True)
class TuningResult:
    """New controller settings and a report: what was asked, what was reached, and why not."""

    loop: "ServoLoop"
    targets: TuningTargets
    initial: Gains
    tuned: Gains
    equivalent_delay_s: float
    achieved: Achieved
    targets_met: bool
    unmet: tuple[str, ...] = ()
    notch: dict[str, float] | None = None
    with_notch: "TuningResult | None" = None
    evaluations: int = 0
    wall_time_s: float = 0.0
    stable: bool | None = None
    stability_warnings: tuple[str, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """Plain sentences: each unmet target, then what the poles of the tuned loop say."""
        return tuple(f"not met: {u}" for u in self.unmet if u not in self.stability_warnings) + self.stability_warnings

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat tune --json`` contract."""
        a = self.achieved
        out = {**self.tuned.to_dict(), "equivalent_delay_s": self.equivalent_delay_s,
               "initial": self.initial.to_dict(),
               "targets": {"velocity_crossover_rad_s": self.targets.velocity_crossover,
                           "velocity_phase_margin_deg": self.targets.velocity_phase_margin,
                           "position_phase_margin_deg": self.targets.position_phase_margin,
                           "position_crossover_rad_s": self.targets.position_crossover,
                           "min_gain_margin_db": self.targets.min_gain_margin},
               "achieved": {"velocity_phase_margin_deg": a.velocity_phase_margin_deg,
                            "velocity_crossover_rad_s": a.velocity_crossover_rad_s,
                            "velocity_gain_margin_db": _finite(a.velocity_gain_margin_db),
                            "velocity_worst_phase_margin_deg": _finite(a.velocity_worst_phase_margin_deg),
                            "velocity_crossovers": a.velocity_crossovers,
                            "position_phase_margin_deg": a.position_phase_margin_deg,
                            "position_worst_phase_margin_deg": _finite(a.position_worst_phase_margin_deg),
                            "position_crossover_rad_s": a.position_crossover_rad_s,
                            "position_gain_margin_db": _finite(a.position_gain_margin_db),
                            "gain_margin_db": _finite(a.gain_margin_db),
                            "velocity_bandwidth_rad_s": a.velocity_bandwidth_rad_s,
                            "position_bandwidth_rad_s": a.position_bandwidth_rad_s,
                            "targets_met": self.targets_met, "unmet": list(self.unmet),
                            "notch": self.notch},
               "evaluations": self.evaluations, "wall_time_s": self.wall_time_s,
               "stable": self.stable, "warnings": list(self.warnings)}
        if self.with_notch is not None:
            out["with_notch"] = {k: v for k, v in self.with_notch.to_dict().items() if k != "with_notch"}
        return out

    def tuned_loop(self) -> "ServoLoop":
        """The servo loop with the tuned gains (and the suggested notch if the tuning used one)."""
        return self.loop.with_gains(Kp=self.tuned.Kp, Ti=self.tuned.Ti, Kv=self.tuned.Kv)


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


# --------------------------------------------------------------------------- rigid model, closed forms
def equivalent_delay(loop: "ServoLoop") -> float:
    """The lags of the velocity loop folded into one delay (s), for the rigid model: the sum of the
    blocks' delays (:func:`~sicomat.servo.blocks.loop_delays`: ZOH ``Tv/2``, computation delay
    ``d_v·Tv``, the drive's lag, differencing of a position sensor ``Tv/2``, each filter's group
    delay at low frequency; an analog loop keeps only the drive and the filters)."""
    delay = 0.0
    for _, seconds in loop_delays(loop):
        delay += seconds
    return float(delay)


def require_tunable(loop: "ServoLoop") -> None:
    """Refuse a loop whose velocity law ``tune`` cannot set (it sets the Kp and Ti of a PI-type
    law): a located :class:`~sicomat.errors.ModelError`."""
    kind = controller_kind(loop.controller.type, path=f"axes.{loop.axis}.controller.type")
    if not kind.tunable:
        raise ModelError(f"tune sets the Kp and Ti of a P-PI or P-IP velocity law; a {kind.type!r} law is fixed "
                         "by its coefficients, so there is nothing to tune (analyse it with bode, margins, step "
                         "and simulate, or tune a P-PI and write its law as a transfer function)",
                         path=f"axes.{loop.axis}.controller.type", value=kind.type)


def rigid_velocity_pi(m_rigid: float, crossover: float, phase_margin_deg: float, delay: float) -> tuple[float, float]:
    """Kp (physical units) and Ti of a PI on ``1/(m s)·e^{−sτ}`` for a phase margin at a crossover.

    ``arg L = −90° − atan(1/(ωTi)) − ωτ = −180° + φ`` and ``|L| = 1`` give
    ``Ti = 1/(ω tan(90° − φ − ωτ))`` and ``Kp = m ω / sqrt(1 + 1/(ωTi)²)``.

    Examples
    --------
    >>> kp, ti = rigid_velocity_pi(1.0, 125.6, 45.0, 0.0)   # no delay: Ti = 1/ω, Kp = ω/√2
    >>> round(ti * 125.6, 9), round(kp / 125.6 * 2 ** 0.5, 9)
    (1.0, 1.0)
    """
    lead = (90.0 - phase_margin_deg) * _DEG - crossover * delay
    if lead <= 0:
        raise AnalysisError(f"a phase margin of {phase_margin_deg:g}° at {crossover:g} rad/s is out of reach "
                            f"with an equivalent delay of {delay * 1e3:.3g} ms: lower the crossover or the margin")
    ti = 1.0 / (crossover * np.tan(lead))
    kp = m_rigid * crossover / np.sqrt(1.0 + 1.0 / (crossover * ti) ** 2)
    return float(kp), float(ti)


def _rigid_velocity_closed(omega, m, kp, ti, delay):
    s = 1j * omega
    L = kp * (1 + 1 / (ti * s)) * np.exp(-s * delay) / (m * s)
    return L / (1 + L)


def rigid_position_gain(m_rigid: float, kp: float, ti: float, velocity_delay: float, position_delay: float,
                        phase_margin_deg: float | None = None, crossover: float | None = None) -> float:
    """Kv of ``Kv/s · T_v(s) · e^{−sτ_p}`` (rigid velocity closed loop ``T_v``) for a phase margin or a
    crossover (rad/s)."""
    def phase(w):
        return np.angle(_rigid_velocity_closed(w, m_rigid, kp, ti, velocity_delay)) - np.pi / 2 - w * position_delay

    if crossover is None:
        if phase_margin_deg is None:
            raise ValueError("rigid_position_gain needs phase_margin_deg or crossover")
        target = -np.pi + phase_margin_deg * _DEG
        grid = np.logspace(-2, 5, 2000)
        values = np.unwrap(phase(grid)) - target
        idx = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))
        if idx.size == 0:
            raise AnalysisError(f"no crossover gives a position phase margin of {phase_margin_deg:g}°")
        i = idx[0]
        crossover = scipy.optimize.brentq(lambda w: np.interp(np.log(w), np.log(grid), values), grid[i], grid[i + 1])
    return float(crossover / abs(_rigid_velocity_closed(crossover, m_rigid, kp, ti, velocity_delay)))


def _position_equivalent_delay(loop: "ServoLoop") -> float:
    ctrl = loop.controller
    if ctrl.position_loop == "continuous":
        return 0.0
    return ctrl.position_period / 2 + ctrl.position_delay * ctrl.position_period


# --------------------------------------------------------------------------- complete model
@dataclass(frozen=True)
class _Quick:
    """Margins read off a loop gain for the optimiser: the main (lowest) gain crossover and its
    phase margin, the smallest gain margin over all phase crossovers, the worst phase margin over all
    gain crossovers (resonances crossing 0 dB included)."""

    crossover: float
    phase_margin: float
    gain_margin: float
    worst_phase_margin: float
    n_crossovers: int


def _quick_margins(omega: np.ndarray, L: np.ndarray) -> _Quick:
    logw = np.log(omega)
    mag = np.log(np.abs(L))
    phase = np.unwrap(np.angle(L))
    phase -= 2 * np.pi * np.ceil(phase[0] / (2 * np.pi))
    down = np.flatnonzero(np.sign(mag[:-1]) != np.sign(mag[1:]))
    pms = []
    wcs = []
    for i in down:
        t = mag[i] / (mag[i] - mag[i + 1])
        wcs.append(np.exp(logw[i] + t * (logw[i + 1] - logw[i])))
        ph = phase[i] + t * (phase[i + 1] - phase[i])
        pms.append((np.degrees(ph) + 180.0 + 180.0) % 360.0 - 180.0)
    shifted = (phase + np.pi) / (2 * np.pi)
    k = np.floor(shifted)
    cross = np.flatnonzero(k[:-1] != k[1:])
    gms = []
    for i in cross:
        level = max(k[i], k[i + 1])
        t = (level - shifted[i]) / (shifted[i + 1] - shifted[i])
        gms.append(-20.0 / np.log(10) * (mag[i] + t * (mag[i + 1] - mag[i])))
    if not wcs:
        return _Quick(0.0, -180.0, min(gms) if gms else np.inf, -180.0, 0)
    worst = pms[int(np.argmin(np.abs(pms)))]
    return _Quick(float(wcs[0]), float(pms[0]), float(min(gms, key=abs)) if gms else np.inf, float(worst), len(wcs))


class _Evaluator:
    """Cheap re-evaluation of both loops for trial gains (the plant parts are computed once)."""

    def __init__(self, loop: "ServoLoop", n: int = 1200, progress=None, task: str = "tuning", *,
                 an: LoopAnalysis | None = None, grid=default_omega) -> None:
        self.loop = loop
        self.progress, self.task = progress, task
        self.an = LoopAnalysis.of(loop) if an is None else an
        self.omega_v = grid(loop, "velocity-open", n)
        self.omega_p = grid(loop, "position-open", n)
        _, integrator, act, meas = self.an.velocity_factors(self.omega_v, 1.0, 1.0)
        self.plant_v = act * meas
        self.integrator = integrator    # the integral part for Kp = Ti = 1: T/(z − 1), or 1/(jω) analog
        self.count = 0

    def velocity_gain(self, kp: float, ti: float) -> np.ndarray:
        """The velocity loop gain L_v on the velocity grid."""
        return kp * (1.0 + self.integrator / ti) * self.plant_v

    def velocity(self, kp: float, ti: float) -> _Quick:
        self.count += 1
        notify(self.progress, self.task, self.count, None)
        return _quick_margins(self.omega_v, self.velocity_gain(kp, ti))

    def position_base(self, kp: float, ti: float) -> np.ndarray:
        """The position loop gain for Kv = 1 (delay included)."""
        ctrl = self.loop.controller
        if ctrl.position_loop == "continuous":
            return self.an.position_continuous(self.omega_p, kp, ti)[0]
        g_v, _ = self.an.position_lifted(self.omega_p, kp, ti)
        z = np.exp(1j * self.omega_p * ctrl.position_period)
        return z ** (-ctrl.position_delay) * g_v

    def position(self, base: np.ndarray, kv: float) -> _Quick:
        self.count += 1
        notify(self.progress, self.task, self.count, None)
        return _quick_margins(self.omega_p, kv * base)

    def bandwidth(self, which: str, L: np.ndarray, kp: float, ti: float, kv: float) -> float | None:
        """The closed loop's −3 dB bandwidth (rad/s) by :func:`sicomat.frequency.margins.closed_loop_bandwidth`
        relative to its exact static gain, as ``sicomat margins`` reports it; ``None`` when not
        reached on the grid (or undefined)."""
        from ..lti.response import FrequencyResponse
        from ..frequency.margins import closed_loop, closed_loop_bandwidth

        omega = self.omega_v if which == "velocity-open" else self.omega_p
        T = closed_loop(FrequencyResponse(omega, L, which, open_loop=True))
        return _finite(closed_loop_bandwidth(T, self.an.closed_loop_static_gain(which, kp, ti, kv)))


def tune_frequency(loop: "ServoLoop", targets: TuningTargets | None = None, *, suggest_notch: bool = True,
                   progress: "ProgressCallback | None" = None) -> TuningResult:
    """Two-step automatic tuning (rigid closed form, then Nelder–Mead on the complete model).

    ``progress`` (:mod:`sicomat.progress`) is told each evaluation of the complete model (the total
    is not known in advance).

    Returns
    -------
    TuningResult
        Initial (rigid) and tuned gains, the equivalent delay, the margins reached, whether every
        target was met and, if not, which and a suggested notch with the tuning repeated with it.
    """
    require_tunable(loop)
    start = time.perf_counter()
    targets = targets or TuningTargets()
    if targets.velocity_crossover is None:
        f_meca = loop.mechanics.modes().f_meca_hz
        if f_meca is None:
            raise AnalysisError("the mechanics has no flexible mode: give the velocity crossover")
        targets = replace(targets, velocity_crossover=2 * np.pi * f_meca / 4)
    _check_targets(loop, targets)
    m = loop.m_rigid
    tau = equivalent_delay(loop)
    kp0, ti0 = rigid_velocity_pi(m, _resolved(targets.velocity_crossover), targets.velocity_phase_margin, tau)
    kv0 = rigid_position_gain(m, kp0, ti0, tau, _position_equivalent_delay(loop),
                              targets.position_phase_margin, targets.position_crossover)
    initial = Gains(kp0, kp0 / m, ti0, kv0)
    result = _refine(loop, targets, initial, tau, start, progress)
    if suggest_notch and not result.targets_met:
        notch = _suggest_notch(loop, result)
        if notch is not None:
            from ..description.servo import FilterSpec

            spec = FilterSpec(type="notch", frequency=notch["frequency_hz"], width=notch["width"], depth=notch["depth"])
            controller = loop.controller.model_copy(update={"current_filters": [*loop.controller.current_filters, spec]})
            notched = replace(loop, controller=controller)
            again = _refine(notched, targets, initial, equivalent_delay(notched), time.perf_counter(), progress,
                            "tuning with the suggested notch")
            result = replace(result, notch=notch, with_notch=again)
    return replace(result, wall_time_s=time.perf_counter() - start)


def _resolved(value: float | None) -> float:
    """A target that :func:`tune_frequency` has completed (the velocity crossover) or that
    :func:`_check_targets` has required (the position phase margin when no position crossover is given)."""
    if value is None:  # pragma: no cover - unreachable after tune_frequency's first lines
        raise AnalysisError("a tuning target was used before it was resolved")
    return value


def _check_targets(loop: "ServoLoop", t: TuningTargets) -> None:
    ctrl = loop.controller
    nyq_v = np.pi / ctrl.velocity_period if ctrl.velocity_loop == "discrete" else np.inf
    nyq_p = np.pi / ctrl.position_period if ctrl.position_loop == "discrete" else np.inf
    if not 0 < _resolved(t.velocity_crossover) < nyq_v:
        raise ModelError(f"the velocity crossover must be between 0 and the velocity loop's Nyquist frequency "
                         f"{nyq_v:.4g} rad/s", path="velocity_crossover", value=t.velocity_crossover)
    if not 0 < t.velocity_phase_margin < 90:
        raise ModelError("the velocity phase margin must be between 0 and 90 degrees",
                         path="velocity_phase_margin", value=t.velocity_phase_margin)
    if t.position_crossover is not None and not 0 < t.position_crossover < nyq_p:
        raise ModelError(f"the position crossover must be between 0 and {nyq_p:.4g} rad/s",
                         path="position_crossover", value=t.position_crossover)
    if t.position_crossover is None and not (t.position_phase_margin and 0 < t.position_phase_margin < 90):
        raise ModelError("the position phase margin must be between 0 and 90 degrees",
                         path="position_phase_margin", value=t.position_phase_margin)


def _refine(loop, targets: TuningTargets, initial: Gains, tau: float, start: float, progress=None,
            task: str = "tuning on the complete model") -> TuningResult:
    ev = _Evaluator(loop, progress=progress, task=task)
    wv, pmv, gmin = _resolved(targets.velocity_crossover), targets.velocity_phase_margin, targets.min_gain_margin

    def cost_velocity(x, gain_criterion: bool) -> float:
        kp, ti = initial.Kp * np.exp(x[0]), initial.Ti * np.exp(x[1])
        q = ev.velocity(kp, ti)
        reach = np.log(max(q.crossover, 1e-9) / wv) ** 2
        if not gain_criterion:  # phase margin and crossover as asked
            return float(((q.phase_margin - pmv) / pmv) ** 2 + reach)
        # gain-margin criterion: the margins become constraints, the crossover comes as close as it can
        short_gm = max(0.0, (gmin - q.gain_margin) / gmin)
        short_pm = max(0.0, (pmv - q.phase_margin) / pmv)
        return float(100.0 * (short_gm ** 2 + short_pm ** 2) + reach + 0.1 * ((q.phase_margin - pmv) / pmv) ** 2)

    options = {"xatol": 1e-4, "fatol": 1e-8, "maxiter": 400}
    x = scipy.optimize.minimize(cost_velocity, [0.0, 0.0], args=(False,), method="Nelder-Mead", options=options).x
    if ev.velocity(initial.Kp * np.exp(x[0]), initial.Ti * np.exp(x[1])).gain_margin < gmin:
        x = scipy.optimize.minimize(cost_velocity, x, args=(True,), method="Nelder-Mead", options=options).x
    kp, ti = float(initial.Kp * np.exp(x[0])), float(initial.Ti * np.exp(x[1]))
    qv = ev.velocity(kp, ti)
    base = ev.position_base(kp, ti)
    kv = _tune_position(ev, base, initial.Kv, targets)
    achieved = _achieved(ev, kp, ti, kv, qv, base)
    from ..servo.stability import loop_verdict

    verdict = loop_verdict(loop, Kp=kp, Ti=ti, Kv=kv, an=ev.an)
    unmet = _unmet(targets, achieved) + list(verdict.warnings)
    return TuningResult(loop=loop, targets=targets, initial=initial, tuned=Gains(kp, kp / loop.m_rigid, ti, kv),
                        equivalent_delay_s=tau, achieved=achieved, targets_met=not unmet, unmet=tuple(unmet),
                        evaluations=ev.count, wall_time_s=time.perf_counter() - start,
                        stable=verdict.stable, stability_warnings=verdict.warnings)


def _achieved(ev: _Evaluator, kp: float, ti: float, kv: float, qv: _Quick, base: np.ndarray) -> Achieved:
    """What the tuning reports as reached with the gains (the velocity loop's quick margins ``qv`` and the
    position loop gain for Kv = 1, ``base``, already computed)."""
    qp = ev.position(base, kv)
    return Achieved(qv.phase_margin, qv.crossover, qv.gain_margin, qp.phase_margin, qp.crossover,
                    qp.gain_margin, velocity_worst_phase_margin_deg=qv.worst_phase_margin,
                    velocity_crossovers=qv.n_crossovers,
                    velocity_bandwidth_rad_s=ev.bandwidth("velocity-open", ev.velocity_gain(kp, ti), kp, ti, kv),
                    position_bandwidth_rad_s=ev.bandwidth("position-open", kv * base, kp, ti, kv),
                    position_worst_phase_margin_deg=qp.worst_phase_margin)


def targets_on(an: LoopAnalysis, targets: TuningTargets, gains: Gains, *, grid=default_omega,
               n: int = 1200) -> tuple[Achieved, list[str]]:
    """The margins and crossovers the tuning reports (its definitions: the main, lowest, gain crossover;
    the worst phase margin; the smallest gain margin) of the loops of ``an`` with ``gains``, on the grid
    ``grid(loop, which, n)``, and the targets they miss (the tuning's tolerances). For another model of
    the tuned loop: e.g. the coupled one (:func:`sicomat.frequency.coupled.coupled_analysis`, with
    :func:`~sicomat.frequency.coupled.coupled_omega`'s grid). ``targets`` resolved
    (:attr:`TuningResult.targets`)."""
    ev = _Evaluator(an.loop, n, an=an, grid=grid)
    qv = ev.velocity(gains.Kp, gains.Ti)
    achieved = _achieved(ev, gains.Kp, gains.Ti, gains.Kv, qv, ev.position_base(gains.Kp, gains.Ti))
    return achieved, _unmet(targets, achieved)


def _tune_position(ev: _Evaluator, base: np.ndarray, kv0: float, t: TuningTargets) -> float:
    """Kv for the position phase margin (or crossover), then lowered if the gain margin is short."""
    def mismatch(log_kv: float) -> float:
        q = ev.position(base, np.exp(log_kv))
        if t.position_crossover is not None:
            return np.log(max(q.crossover, 1e-9) / t.position_crossover)
        return _resolved(t.position_phase_margin) - q.phase_margin   # grows with Kv

    # scan upwards from a small gain: the first change of sign is the root (further up, the phase
    # wraps and the mismatch jumps, which a bracketing solver would mistake for a root)
    grid = np.log(kv0) + np.linspace(-5.0, 3.0, 41)
    values = np.array([mismatch(g) for g in grid])
    change = np.flatnonzero((values[:-1] < 0) & (values[1:] >= 0))
    if change.size:
        i = change[0]
        log_kv = scipy.optimize.brentq(mismatch, grid[i], grid[i + 1], xtol=1e-7)
    else:
        log_kv = grid[int(np.argmin(np.abs(values)))]
    kv = float(np.exp(log_kv))
    while ev.position(base, kv).gain_margin < t.min_gain_margin and kv > 1e-6 * kv0:
        kv *= 0.95
    return kv


def _unmet(t: TuningTargets, a: Achieved) -> list[str]:
    unmet = []
    if abs(a.velocity_phase_margin_deg - t.velocity_phase_margin) > t.tolerance_deg:
        unmet.append(f"velocity phase margin {a.velocity_phase_margin_deg:.1f}° instead of {t.velocity_phase_margin:g}°")
    if abs(a.velocity_crossover_rad_s / _resolved(t.velocity_crossover) - 1) > t.tolerance_rel:
        unmet.append(f"velocity crossover {a.velocity_crossover_rad_s:.1f} rad/s instead of {t.velocity_crossover:.1f}")
    if t.position_crossover is not None:
        if abs(a.position_crossover_rad_s / t.position_crossover - 1) > t.tolerance_rel:
            unmet.append(f"position crossover {a.position_crossover_rad_s:.1f} rad/s instead of {t.position_crossover:.1f}")
    elif abs(a.position_phase_margin_deg - _resolved(t.position_phase_margin)) > t.tolerance_deg:
        unmet.append(f"position phase margin {a.position_phase_margin_deg:.1f}° instead of {t.position_phase_margin:g}°")
    # every crossover, not only the main one, must keep the margin asked for (resonances crossing 0 dB)
    for name, worst, asked in (("velocity", a.velocity_worst_phase_margin_deg, t.velocity_phase_margin),
                               ("position", a.position_worst_phase_margin_deg, t.position_phase_margin)):
        if asked is not None and not worst >= asked - t.tolerance_deg:
            unmet.append(f"{name} worst phase margin {worst:.1f}° (over all gain crossovers) below {asked:g}°")
    if a.gain_margin_db < t.min_gain_margin - 0.05:
        unmet.append(f"gain margin {a.gain_margin_db:.1f} dB below {t.min_gain_margin:g} dB")
    return unmet


def _suggest_notch(loop: "ServoLoop", result: TuningResult) -> dict[str, float] | None:
    """A notch at the resonance that limits the velocity loop: the largest |L| peak above crossover."""
    an = LoopAnalysis.of(loop)
    frf = an.response("velocity-open", Kp=result.tuned.Kp, Ti=result.tuned.Ti)
    above = frf.omega > 1.5 * max(result.achieved.velocity_crossover_rad_s, 1e-9)
    if not above.any():
        return None
    mag = np.abs(frf.response)
    mag_above = np.where(above, mag, 0.0)
    i = int(np.argmax(mag_above))
    if i == 0 or i == len(mag) - 1 or mag_above[i] <= mag_above[i - 1] or mag_above[i] <= mag_above[i + 1]:
        return None  # no resonance peak: a roll-off, not a mode, limits the loop
    peak_db = 20 * np.log10(mag[i])
    need_db = peak_db + result.targets.min_gain_margin + 3.0
    depth = float(min(0.5, 10 ** (-need_db / 20))) if need_db > 0 else 0.5
    # width from the resonance's half-power points
    half = mag[i] / np.sqrt(2)
    lo = i
    while lo > 0 and mag[lo] > half:
        lo -= 1
    hi = i
    while hi < len(mag) - 1 and mag[hi] > half:
        hi += 1
    width = float(np.clip(4 * (frf.omega[hi] - frf.omega[lo]) / frf.omega[i], 0.1, 1.0))
    return {"frequency_hz": float(frf.omega[i] / (2 * np.pi)), "depth": depth, "width": width,
            "peak_db": float(peak_db)}
