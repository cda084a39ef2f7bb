"""The servo loop lowered to the hybrid kernel, against closed loops built independently with python-control."""

from __future__ import annotations

import control
import numpy as np
import pytest

from sicomat import machine_from_dict
from sicomat.errors import ModelError
from sicomat.servo.loop import build_servo_loop
from sicomat.motion.setpoints import step_profile, trapezoid_profile
from sicomat.simulation import simulate

M1, M2, K, C = 10.0, 30.0, 2.0e6, 500.0   # motor-side mass, table, transmission
KT, TAU = 50.0, 2.0e-4
KP_NORM, TI, KV = 50.0, 0.02, 12.0
H = 2.0e-4


def _machine(position_period=H, velocity_delay=1, position_delay=0, **controller):
    return machine_from_dict({"axes": {"X": {
        "mechanics": {"type": "chain", "masses": [M1, M2], "stiffnesses": [K], "dampings": [C]},
        "drive": {"force_constant": KT, "time_constant": TAU},
        "controller": {"position_sensor": "last", "velocity_sensor": "last", "Kv": KV,
                       "Kp_normalized": KP_NORM, "Ti": TI, "position_period": position_period,
                       "velocity_period": H, "velocity_delay": velocity_delay,
                       "position_delay": position_delay, **controller}}}})


def _reference_closed_loop(kp, velocity_delay, position_delay):
    """The sampled loop written out by hand: c2d of the plant, PI + differencing + delays in numpy."""
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                  [-K / M1, K / M1, -C / M1, C / M1], [K / M2, -K / M2, C / M2, -C / M2]])
    B = np.array([[0], [0], [1 / M1], [0]])
    mech = control.ss(A, B, np.array([[0, 1, 0, 0]]), 0)
    drive = control.tf([KT], [TAU, 1])
    plant = control.c2d(control.series(drive, mech), H, "zoh")  # input: current reference, output: x2
    Phi, Gam, Cp = (np.asarray(m) for m in (plant.A, plant.B, plant.C))
    npl = Phi.shape[0]
    # controller states: z (integral action), p_prev (differencing), delay lines
    nd_v, nd_p = velocity_delay, position_delay
    n = npl + 2 + nd_v + nd_p
    Acl = np.zeros((n, n))
    Bcl = np.zeros((n, 1))
    iz, ip, iv0, ipd0 = npl, npl + 1, npl + 2, npl + 2 + nd_v

    def row_y():  # measured position as a row over the state
        r = np.zeros(n)
        r[:npl] = Cp[0]
        return r

    y = row_y()
    # position loop: v_cmd = Kv (r - y), possibly delayed
    vcmd_x = -KV * y
    vcmd_r = KV
    if nd_p:
        # delay line states hold past v_cmd values; output = oldest
        out_x = np.zeros(n)
        out_x[ipd0 + nd_p - 1] = 1.0
        vc_x, vc_r = out_x, 0.0
    else:
        vc_x, vc_r = vcmd_x, vcmd_r
    vmeas = (y - np.eye(n)[ip]) / H
    e_x, e_r = vc_x - vmeas, vc_r
    u_x = kp * e_x + np.eye(n)[iz]
    u_r = kp * e_r
    iref_x, iref_r = u_x / KT, u_r / KT
    if nd_v:
        applied_x = np.eye(n)[iv0 + nd_v - 1]
        applied_r = 0.0
    else:
        applied_x, applied_r = iref_x, iref_r
    Acl[:npl, :] += np.outer(Gam[:, 0], applied_x)
    Acl[:npl, :npl] += Phi
    Bcl[:npl, 0] += Gam[:, 0] * applied_r
    Acl[iz] = np.eye(n)[iz] + kp * H / TI * e_x
    Bcl[iz, 0] = kp * H / TI * e_r
    Acl[ip] = y
    for j in range(nd_v):
        if j == 0:
            Acl[iv0], Bcl[iv0, 0] = iref_x, iref_r
        else:
            Acl[iv0 + j] = np.eye(n)[iv0 + j - 1]
    for j in range(nd_p):
        if j == 0:
            Acl[ipd0], Bcl[ipd0, 0] = vcmd_x, vcmd_r
        else:
            Acl[ipd0 + j] = np.eye(n)[ipd0 + j - 1]
    outputs = np.vstack([y, applied_x])
    D = np.array([[0.0], [applied_r]])
    return control.ss(Acl, Bcl, outputs, D, H)


@pytest.mark.parametrize("velocity_delay,position_delay", [(0, 0), (1, 0), (1, 1), (2, 1)])
def test_linear_single_rate_loop_equals_exact_discrete_closed_loop(velocity_delay, position_delay):
    loop = build_servo_loop(_machine(velocity_delay=velocity_delay, position_delay=position_delay))
    # a sum of two masses: one rounding
    np.testing.assert_allclose(loop.m_rigid, M1 + M2, rtol=1e-12)
    profile = trapezoid_profile(5e-3, 0.1, 2.0)
    series = simulate(loop, profile, 0.2, nonlinear=False)
    reference = _reference_closed_loop(loop.Kp, velocity_delay, position_delay)
    r = series["setpoint.position"]
    expected = control.forced_response(reference, T=series.time, U=r).outputs
    measured = series["setpoint.fine"] - series["following_error"]
    for got, want in ((measured, expected[0]), (series["current.applied"], expected[1])):
        # the kernel against python-control's exact discrete closed loop: both ZOH-discretise by expm (a few eps
        # per step) and run 0.2 s of a stable loop in different realisations; the rounding is amplified by the
        # realisations' conditioning (~1e3): 1e-9 of the signal's scale
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))


def test_step_metrics_of_a_settling_move():
    loop = build_servo_loop(_machine(position_period=4 * H))
    series = simulate(loop, step_profile(1e-3), 1.5, nonlinear=False)
    m = series.metrics
    # the step itself, up to the rounding of setpoint − measurement; the linear loop's final error after 1.5 s
    # decays like e^(-30·1.5) of the step: < 1e-8 m
    assert m.max_following_error == pytest.approx(1e-3, rel=1e-9)  # the step itself
    assert abs(m.final_error) < 1e-8
    # the measured position sampled at the position period follows the lifted closed loop exactly
    from sicomat.frequency.loops import LoopAnalysis

    an = LoopAnalysis.of(loop)
    A, B, C = an.velocity_closed_loop(loop.Kp, loop.Ti)
    Np = loop.position_ratio
    Ap = np.linalg.matrix_power(A, Np)
    Bp = sum(np.linalg.matrix_power(A, i) @ B[:, :1] for i in range(Np))
    x = np.zeros(A.shape[0])
    expected = []
    for _ in range(len(series.time[::Np])):
        y = C[0] @ x
        expected.append(y)
        x = Ap @ x + Bp[:, 0] * loop.Kv * (1e-3 - y)
    measured = (series["setpoint.fine"] - series["following_error"])[::Np]
    # the lifted closed loop (A^Np by repeated products) against the kernel: rounding ~Np·eps relative to the
    # 1e-3 m step, 1e-15 m; 1e-12 m slack. The rise time interpolates samples at the position period: two
    # periods
    np.testing.assert_allclose(measured, expected, atol=1e-12)
    t = series.time
    rise = np.interp([0.1e-3, 0.9e-3], np.maximum.accumulate(measured), t[::Np])
    assert m.rise_time == pytest.approx(rise[1] - rise[0], abs=2 * Np * H)


def test_bad_controller_inputs():
    with pytest.raises(ModelError, match="whole multiple"):
        _machine(position_period=2.5 * H)
    with pytest.raises(ModelError, match="greater than 0"):
        _machine(Kv=-1.0)
    with pytest.raises(ModelError, match="unknown sensor"):
        machine_from_dict({"axes": {"X": {
            "mechanics": {"type": "chain", "masses": [M1, M2], "stiffnesses": [K]},
            "drive": {"force_constant": KT, "time_constant": TAU},
            "controller": {"position_sensor": "nowhere", "Kv": KV, "Kp": 1.0, "Ti": TI}}}})
    loop = build_servo_loop(_machine(velocity_delay=40))
    with pytest.raises(ModelError, match="not shorter than the run"):
        simulate(loop, step_profile(1e-3), 0.005)


def test_batch_of_variants_equals_single_runs():
    from sicomat.simulation import simulate_batch

    base = build_servo_loop(_machine(position_period=4 * H))
    variants = [base.with_gains(Kp=base.Kp * f, Kv=base.Kv * g) for f, g in ((1.0, 1.0), (0.8, 1.1), (1.2, 0.9))]
    profile = trapezoid_profile(2e-3, 0.05, 1.0)
    batch = simulate_batch(variants, profile, 0.3)
    for i, loop in enumerate(variants):
        single = simulate(loop, profile, 0.3).metrics
        # the same kernel, batched: the same operations (1e-12 only allows another summation order)
        assert batch.max_following_error[i] == pytest.approx(single.max_following_error, rel=1e-12)
        assert batch.rms_following_error[i] == pytest.approx(single.rms_following_error, rel=1e-12)
    assert not batch.diverged.any()
    assert len(set(np.round(batch.max_following_error, 12))) == 3   # the variants really differ


def test_batch_variants_must_share_the_loop_timing():
    from sicomat.simulation import simulate_batch

    loops = [build_servo_loop(_machine(position_period=4 * H)), build_servo_loop(_machine(position_period=2 * H))]
    with pytest.raises(ModelError, match="variant 1: the loop periods differ") as err:
        simulate_batch(loops, trapezoid_profile(2e-3, 0.05, 1.0), 0.1)
    assert err.value.path == "axes.X.controller"


def test_at_rest_the_integral_action_holds_the_stuck_friction():
    """After a small move the axis sticks: the PI's integral action is the force the friction holds."""
    from pathlib import Path

    import sicomat

    loop = build_servo_loop(sicomat.load_model(Path(__file__).resolve().parents[1] / "examples" / "paper_5m4s.toml"))
    series = simulate(loop, step_profile(1e-4), 0.4)
    friction = series["friction.motor"][-1]
    # the holding force never exceeds the limit, up to the rounding of the force balance (~eps·142 N); the
    # integral action equals it to the settling of the structure's 80 Hz ringing after 0.4 s: 2 %; stuck bodies
    # move together exactly, 1e-12 m/s is rounding
    assert abs(friction) <= 142.0 + 1e-9                       # within the static limit (static = Coulomb here)
    # force balance on the rigid axis at rest: motor force + friction ≈ 0, the motor force being the integral
    assert series["velocity.integral"][-1] == pytest.approx(-friction, rel=0.02)
    # stuck: no sliding between primary and secondary (the structure itself still rings at 80 Hz)
    assert abs(series["primary.v"][-1] - series["secondary.v"][-1]) < 1e-12
