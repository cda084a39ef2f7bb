"""sicomat.servo.stability (the verdict from the closed loop's poles) and sicomat.simulation.checks (what a run
says: divergence, limit cycles, final error), against closed forms, python-control and the kernel."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
import pytest
import scipy.optimize

from accuracy import eigenvalue_accuracy

import sicomat
from sicomat.servo.loop import build_servo_loop, servo_plant
from sicomat.frequency.loops import LoopAnalysis
from sicomat.motion.setpoints import step_profile, trapezoid_profile
from sicomat.simulation import simulate
from sicomat.simulation.checks import (FINAL_ERROR_BAND, final_error_warning, limit_cycle_warning, simulation_verdict)
from sicomat.frequency.margins import margins_warnings
from sicomat.servo.stability import Verdict, combine, loop_poles, loop_verdict
from sicomat.simulation.timeseries import TimeSeries

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _loop(name: str, *overrides: str, axis: str | None = None):
    return build_servo_loop(sicomat.load_model(EXAMPLES / name, list(overrides)), axis)


# ------------------------------------------------------------------------------------ poles
def test_analog_pi_on_a_rigid_mass_against_the_routh_boundary():
    """Analog PI velocity loop, first-order current loop τ, mass m with viscous friction c:
    ``m τ Ti s³ + (m + c τ) Ti s² + (c + Kp) Ti s + Kp = 0``; Routh: stable iff
    ``Ti > Ti* = m τ Kp / ((m + c τ)(c + Kp))``. At ±5 % of Ti* the critical pair's real part is a few
    percent of its frequency (thousands of 1/s), far above the eigenvalue rounding (1e-12 relative)
    and the verdict's tolerance (1e-7 per 125 µs period: 8e-4 1/s)."""
    loop = _loop("rigid_1m.toml", "axes.X.controller.velocity_delay=0", "axes.X.controller.velocity_loop=continuous")
    m, c, tau, kp = 150.0, 50.0, loop.drive.tau, loop.Kp
    ti_star = m * tau * kp / ((m + c * tau) * (c + kp))
    assert loop_verdict(loop, Ti=1.05 * ti_star, loops=("velocity",)).stable is True
    unstable = loop_verdict(loop, Ti=0.95 * ti_star, loops=("velocity",))
    assert unstable.stable is False and "velocity loop is unstable" in unstable.warnings[0]


def _pc_velocity_growth(loop, Kp: float) -> float:
    """Largest |z| of python-control's closed sampled velocity loop, poles at z = 1 (the free position
    the velocity loop does not hold) left out: ZOH plant to the position sensor, differencing, one
    sample of computation delay, forward-Euler PI."""
    ctrl = loop.controller
    T = ctrl.velocity_period
    plant = servo_plant(loop)
    row = plant.outputs.index(f"sensor.{ctrl.position_sensor}")
    G = control.c2d(control.ss(plant.A, plant.B[:, :1], plant.C[row:row + 1], 0), T, "zoh")
    pi = control.tf([Kp, Kp * (T / loop.Ti - 1.0)], [1.0, -1.0], T)
    delay = control.tf([1.0], [1.0] + [0.0] * ctrl.velocity_delay, T)
    diff = control.tf([1.0, -1.0], [T, 0.0], T) * (1.0 / loop.velocity_gain)
    L = control.series(control.ss(pi * delay * (1.0 / loop.drive.kt)), G, control.ss(diff))
    poles = np.linalg.eigvals(control.feedback(L, 1).A)
    # the free position's pole at z = 1 is known to 2e-11 (accuracy.eigenvalue_accuracy); the loop's other
    # poles stay >= 3e-2 away from 1 for Kp up to 10 times the rigid model's: 1e-6 separates them
    poles = poles[np.abs(poles - 1.0) > 1e-6]
    return float(np.max(np.abs(poles)))


def test_sampled_velocity_loop_boundary_against_python_control():
    """The Kp where python-control's closed loop reaches |z| = 1 (found to 1e-6 relative by brentq)
    separates the verdicts at ±3 %: near the boundary |z| moves by about 2e-3 per percent of Kp
    (|z| = 0.9945 at -3 %, 1.0054 at +3 %), four orders above the tolerance of 1e-7 and far above the
    rounding of either model's eigenvalues (geev balances: n·eps·‖A_bal‖·κ = 2e-14 for the package's
    closed loop, ``eigenvalue_accuracy(A, λ, balanced=True)``; 1e-6 for python-control's near Kp)."""
    loop = _loop("rigid_1m.toml")
    kp_star = scipy.optimize.brentq(lambda k: _pc_velocity_growth(loop, k) - 1.0, loop.Kp, 100 * loop.Kp,
                                    xtol=1e-6 * loop.Kp)
    assert loop_verdict(loop, Kp=0.97 * kp_star, loops=("velocity",)).stable is True
    assert loop_verdict(loop, Kp=1.03 * kp_star, loops=("velocity",)).stable is False


@pytest.mark.parametrize("kp_factor, diverges", [(1.0, False), (1000.0, True)])
def test_verdict_agrees_with_the_linear_simulation(kp_factor, diverges):
    """The compiled kernel (another code path: the hybrid program, not the closed-loop matrix) diverges
    exactly when the poles say unstable: the 5M4S with Kp x1000 grows at 9.5e3 1/s, 1e9 in 2 ms."""
    from sicomat.simulation.kernel import SimulationDiverged

    loop = _loop("paper_5m4s.toml")
    loop = loop.with_gains(Kp=kp_factor * loop.Kp)
    assert loop_verdict(loop).stable is (not diverges)
    if diverges:
        with pytest.raises(SimulationDiverged):
            simulate(loop, step_profile(1e-3), 0.05, nonlinear=False)
    else:
        simulate(loop, step_profile(1e-3), 0.05, nonlinear=False)


def test_position_loop_instability_is_named_and_velocity_loop_stays_stable():
    loop = _loop("paper_5m4s.toml", "axes.X.controller.Kv=5000")
    verdict = loop_verdict(loop)
    assert verdict.stable is False and verdict.loops == {"velocity": True, "position": False}
    assert "position loop is unstable" in verdict.warnings[0]


def test_rigid_body_pole_of_the_velocity_loop_is_marginal_not_unstable():
    """The velocity loop alone leaves the position free: a pole at z = 1 exactly (2e-16 off in double
    precision), which must not count as unstable."""
    loop = _loop("paper_5m4s.toml")
    an = LoopAnalysis.of(loop)
    poles = loop_poles(an, loops=("velocity",))["velocity"]
    # the computed pole is within geev's (balanced) eigenvalue accuracy of 1: 1.8e-14, far below the
    # verdict's tolerance (1e-7 per period); the unbalanced bound would be 4e-8 (mixed units)
    A = an.velocity_closed_loop(loop.Kp, loop.Ti)[0]
    assert np.min(np.abs(poles.poles - 1.0)) <= eigenvalue_accuracy(A, np.array([1.0]), balanced=True)[0]
    assert poles.stable


def test_margins_warnings_reconcile_with_the_poles():
    from sicomat.frequency.margins import stability_margins

    loop = _loop("paper_5m4s.toml", "axes.X.controller.velocity_delay=0", "axes.X.controller.velocity_loop=continuous")
    margins = stability_margins(LoopAnalysis.of(loop).response("velocity-open"))
    assert margins.gain_margin_db < 0
    assert margins_warnings(margins, "velocity", False) == [f"velocity loop: gain margin {margins.gain_margin_db:.1f} dB < 0"]
    assert "conditionally stable" in margins_warnings(margins, "velocity", True)[0]
    assert margins_warnings(margins, "position", False, open_loop_unstable=True)[0].endswith("mean nothing")


def test_combine_verdicts():
    both = combine([Verdict(True), Verdict(False, ("a",))], ["axis X: ", "axis Y: "])
    assert both.stable is False and both.warnings == ("axis Y: a",)
    assert combine([Verdict(True), Verdict(None)]).stable is None
    assert combine([Verdict(True), Verdict(True)]).to_dict() == {"stable": True, "warnings": []}


# ------------------------------------------------------------------------------------ runs
def test_saturated_unstable_loop_is_reported_as_a_limit_cycle():
    """Kp x1000 on the 5M4S: the drive's ±40 A holds the unstable loop in a bang-bang oscillation."""
    loop = _loop("paper_5m4s.toml", "axes.X.controller.Kp_normalized=94260")
    profile = trapezoid_profile(0.01, 0.5, 5.0)
    series = simulate(loop, profile, profile.end_time + 0.2)
    verdict = simulation_verdict(loop, series, profile)
    assert verdict.stable is False
    assert any("limit cycle" in w for w in verdict.warnings)
    assert any("did not diverge" in w for w in verdict.warnings)


def test_paper_gains_run_clean():
    loop = _loop("paper_5m4s.toml")
    profile = trapezoid_profile(0.01, 0.5, 5.0)
    series = simulate(loop, profile, profile.end_time + 0.2)
    assert simulation_verdict(loop, series, profile) == Verdict(True, (), {"velocity": True, "position": True})


def test_run_that_ends_far_from_its_target():
    loop = _loop("paper_5m4s.toml", "axes.X.controller.Kv=5000")
    profile = trapezoid_profile(0.01, 0.5, 5.0)
    series = simulate(loop, profile, profile.end_time + 0.2)
    warning = final_error_warning(loop, series, profile)
    assert warning is not None and "off its target" in warning


def _synthetic(current, setpoint, error, limit=40.0, step=1e-3):
    n = len(current)
    return TimeSeries(time=np.arange(n) * step, info={"step": step},
                      signals={"current.applied": np.asarray(current, dtype=float),
                               "current.lower": np.full(n, -limit), "current.upper": np.full(n, limit),
                               "setpoint.fine": np.asarray(setpoint, dtype=float),
                               "following_error": np.asarray(error, dtype=float)})


def test_limit_cycle_definition_on_synthetic_runs():
    n = 400
    still = np.ones(n)
    square = 40.0 * np.sign(np.sin(2 * np.pi * np.arange(n) / 50.0) + 1e-9)
    assert "limit cycle" in limit_cycle_warning(_synthetic(square, still, np.zeros(n)))
    # a move that saturates once accelerating and once braking, within the tail: no limit cycle
    brake = np.concatenate([np.zeros(300), np.full(50, 40.0), np.full(50, -40.0)])
    assert limit_cycle_warning(_synthetic(brake, np.linspace(0, 1, n), np.zeros(n))) is None
    # oscillating below the limits: not saturation-bound
    assert limit_cycle_warning(_synthetic(0.5 * square, still, np.zeros(n))) is None
    # at a limit in less than 20 % of the tail's samples
    rare = np.zeros(n)
    rare[-100:][:8], rare[-100:][50:58] = 40.0, -40.0
    assert limit_cycle_warning(_synthetic(rare, still, np.zeros(n))) is None


def test_final_error_threshold_is_two_percent_of_the_move_or_ten_counts():
    loop = _loop("rigid_1m.toml")       # its scale has no resolution: the 2 % band alone
    profile = step_profile(0.01)
    n = 100
    setpoint = np.full(n, 0.01)
    setpoint[0] = 0.0
    inside = np.zeros(n)                # 1 % either side of the threshold: 1e13 times its rounding
    inside[-1] = 0.99 * FINAL_ERROR_BAND * 0.01
    outside = inside.copy()
    outside[-1] = 1.01 * FINAL_ERROR_BAND * 0.01
    assert final_error_warning(loop, _synthetic(np.zeros(n), setpoint, inside), profile) is None
    assert final_error_warning(loop, _synthetic(np.zeros(n), setpoint, outside), profile) is not None
    # the setpoint still moving at the end (a run shorter than the move): no verdict on the final error
    assert final_error_warning(loop, _synthetic(np.zeros(n), setpoint, outside), step_profile(0.01, start=1.0)) is None


def test_circle_with_an_unstable_axis_gives_no_figures():
    from sicomat.simulation.paths import circle_test

    machine = sicomat.load_model(EXAMPLES / "xy_table.toml", ["axes.X.controller.Kp_normalized=15080"])
    test = circle_test(machine, 0.05, 2.0 / 60, clockwise=False)
    assert test.circle is None and test.verdict.stable is False
    assert test.to_dict()["circular_deviation"] is None
    assert any(w.startswith("axis X: ") for w in test.verdict.warnings)
