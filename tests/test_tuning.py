"""Controller tuning: the rigid closed forms, the complete-model tuning re-measured independently,
and the time approach's overshoot windows checked by an independent simulation."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
import pytest

import sicomat
from sicomat.errors import AnalysisError, ModelError
from sicomat.servo.loop import build_servo_loop, servo_plant
from sicomat.tuning.frequency import (TuningTargets, equivalent_delay, rigid_position_gain, rigid_velocity_pi, tune_frequency)
from sicomat.tuning.time import tune_time

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("m,w,pm,tau", [(362.5, 125.6, 45.0, 4e-4), (1.0, 10.0, 60.0, 0.0), (50.0, 800.0, 30.0, 2e-4)])
def test_rigid_velocity_pi_meets_its_margin(m, w, pm, tau):
    kp, ti = rigid_velocity_pi(m, w, pm, tau)
    s = 1j * w
    L = kp * (1 + 1 / (ti * s)) * np.exp(-s * tau) / (m * s)
    # the closed-form PI solves |L| = 1 and ∠L exactly at ω: a few roundings of trig functions (1e-12; 1e-9°)
    assert abs(L) == pytest.approx(1.0, rel=1e-12)
    assert np.degrees(np.angle(L)) + 180.0 == pytest.approx(pm, abs=1e-9)


def test_rigid_velocity_pi_out_of_reach():
    with pytest.raises(AnalysisError, match="out of reach"):
        rigid_velocity_pi(1.0, 1000.0, 60.0, 1e-3)   # 57 degrees of delay at crossover


def test_rigid_position_gain_meets_its_margin():
    m, tau_v, tau_p = 362.5, 4e-4, 1.5e-3
    kp, ti = rigid_velocity_pi(m, 125.6, 45.0, tau_v)
    kv = rigid_position_gain(m, kp, ti, tau_v, tau_p, phase_margin_deg=80.0)
    w = np.logspace(0, 3, 200000)
    s = 1j * w
    Lv = kp * (1 + 1 / (ti * s)) * np.exp(-s * tau_v) / (m * s)
    Lp = kv * Lv / (1 + Lv) * np.exp(-s * tau_p) / s
    i = np.argmin(np.abs(np.abs(Lp) - 1))
    # the crossover is the nearest of 200000 grid points (Δ = 3.5e-5 in ln ω): the phase there differs by its
    # slope × Δ/2 < 0.01°, and rigid_position_gain solves the margin on its own grid: 0.05°
    assert 180 + np.degrees(np.angle(Lp[i])) == pytest.approx(80.0, abs=0.05)


@pytest.fixture(scope="module")
def paper_loop():
    return build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))


@pytest.fixture(scope="module")
def table_one(paper_loop):
    return tune_frequency(paper_loop, TuningTargets(velocity_crossover=125.6, velocity_phase_margin=45.0,
                                                    position_phase_margin=80.0))


def test_table_one_targets_met(table_one):
    a = table_one.achieved
    # every target at the main crossovers is met; the resonant crossings of the velocity loop keep only
    # 30.3° (at the 374 Hz mode, docs/table-1.md), below the 45° asked: not all targets are met
    assert not table_one.targets_met
    assert len(table_one.unmet) == 1 and "velocity worst phase margin" in table_one.unmet[0]
    assert a.velocity_worst_phase_margin_deg < 45.0 - 1.0
    # the main-crossover targets hold within TuningTargets' acceptance window (tolerance_deg = 1°,
    # tolerance_rel = 3 %); the paper's Table I is a physical reference: the rigid initial tuning within 5 %
    # of it (the paper's equivalent delay is rounded and its plant is the rigid approximation)
    assert a.velocity_phase_margin_deg == pytest.approx(45.0, abs=1.0)
    assert a.velocity_crossover_rad_s == pytest.approx(125.6, rel=0.03)
    assert a.position_phase_margin_deg == pytest.approx(80.0, abs=1.0)
    assert a.gain_margin_db >= 6.0
    # the rigid initial tuning lands near the paper's Table I (Kp = 94.26 1/s, Ti = 9 ms)
    assert table_one.initial.Kp_normalized == pytest.approx(94.26, rel=0.05)
    assert table_one.initial.Ti == pytest.approx(0.009, rel=0.05)


def test_tuned_velocity_loop_remeasured_with_python_control(paper_loop, table_one):
    """Rebuild the sampled velocity loop gain with python-control at the reported crossover."""
    t = table_one.tuned
    ctrl = paper_loop.controller
    T = ctrl.velocity_period
    plant = servo_plant(paper_loop)
    row = plant.outputs.index(f"sensor.{ctrl.velocity_sensor}")
    disc = control.c2d(control.ss(plant.A, plant.B[:, :1], plant.C[row:row + 1], 0), T, "zoh")
    wc = table_one.achieved.velocity_crossover_rad_s
    z = np.exp(1j * wc * T)
    G = np.asarray(disc.frequency_response([wc]).complex).ravel()[0]
    L = (t.Kp + t.Kp * T / t.Ti / (z - 1)) * z ** -ctrl.velocity_delay / paper_loop.drive.kt * G \
        * (1 - 1 / z) / T / paper_loop.velocity_gain
    # the reported crossover comes from the tuner's grid (2000 points over 7 decades, Δ = 8e-3 in ln ω, local
    # cubics): near the flexible mode the cubic error Δ⁴/24·|y''''| reaches ~1e-3; python-control's c2d and ours
    # agree to ~1e-12: 2e-3 in |L|, 0.3° in phase
    assert abs(L) == pytest.approx(1.0, rel=2e-3)
    assert 180 + np.degrees(np.angle(L)) == pytest.approx(table_one.achieved.velocity_phase_margin_deg, abs=0.3)


def test_tuned_loop_is_stable_in_simulation(paper_loop, table_one):
    from sicomat.motion.setpoints import step_profile
    from sicomat.simulation import simulate

    loop = table_one.tuned_loop()
    series = simulate(loop, step_profile(1e-4), 0.4, nonlinear=False)
    # a linear PI loop settles to zero error; after 0.4 s the slowest closed-loop pole (~30 rad/s) leaves
    # e^(-12) of the 1e-4 m step: 1e-6 m ≈ 1 % of the step is slack
    assert abs(series.metrics.final_error) < 1e-6


def test_equivalent_delay_adds_the_documented_lags(paper_loop):
    T = paper_loop.controller.velocity_period
    expected = T / 2 + 1 * T + paper_loop.drive.tau + T / 2   # ZOH, one-sample delay, current loop, differencing
    # a sum of four terms: a few roundings
    assert equivalent_delay(paper_loop) == pytest.approx(expected, rel=1e-12)


def test_bad_targets(paper_loop):
    with pytest.raises(ModelError, match="Nyquist"):
        tune_frequency(paper_loop, TuningTargets(velocity_crossover=1e6))
    with pytest.raises(ModelError, match="between 0 and 90"):
        tune_frequency(paper_loop, TuningTargets(velocity_crossover=100.0, velocity_phase_margin=95.0))


def test_time_approach_lands_in_its_windows(paper_loop):
    result = tune_time(paper_loop)
    assert 20.0 <= result.velocity.overshoot_percent <= 40.0
    assert result.position.overshoot_percent <= 1.5
    first_ti = [it for it in result.iterations if it["step"] == "velocity Kp"]
    assert first_ti and all(it["Ti"] == 0.5 for it in first_ti)
    # the time method's documented acceptance window: ±0.5 points of overshoot
    assert abs(first_ti[-1]["overshoot_percent"] - 10.0) <= 0.5
    # independent check: the sampled velocity loop rebuilt with python-control, stepped with forced_response
    ctrl = paper_loop.controller
    T = ctrl.velocity_period
    plant = servo_plant(paper_loop)
    row = plant.outputs.index(f"sensor.{ctrl.velocity_sensor}")
    disc = control.c2d(control.ss(plant.A, plant.B[:, :1], plant.C[row:row + 1], 0), T, "zoh")
    z = control.tf([1, 0], [1], T)
    law = control.ss(result.Kp + result.Kp * T / result.Ti / (z - 1)) * control.ss(1 / z) * (1 / paper_loop.drive.kt)
    meas = control.ss((1 - 1 / z) / T) * (1 / paper_loop.velocity_gain)
    closed = control.feedback(meas * disc * law, 1)   # v_cmd -> measured velocity (unit feedback on v_meas)
    t = np.arange(int(0.1 / T)) * T
    y = control.forced_response(closed, T=t, U=np.ones_like(t)).outputs
    overshoot = (y.max() / y[-200:].mean() - 1) * 100
    # python-control's forced response of the same sampled loop against ours: exact to rounding, but its final
    # value is the mean of the last 200 samples of a still-ringing response and ours the exact static gain: 1
    # point of overshoot
    assert overshoot == pytest.approx(result.velocity.overshoot_percent, abs=1.0)
