"""sicomat.simulation.kernel: exact sampled loops, op semantics, stick-slip, divergence, batches."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg
from numpy.testing import assert_allclose, assert_array_equal
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from sicomat.errors import ModelError, SicomatError
from sicomat.servo import program as p
from sicomat.simulation.continuous import constrained_dynamics, discretize, discretize_many
from sicomat.simulation.kernel import SimulationDiverged, bare_loop, run, run_batch


# ------------------------------------------------------------------------------------------ helpers

def _no_plant(input_slots=(), output_slots=()):
    """A trivial continuous part (one decaying state) for op tests."""
    nu, ny = len(input_slots), len(output_slots)
    return p.ContinuousPart(A=np.array([[-1.0]]), B=np.zeros((1, nu)), C=np.zeros((ny, 1)),
                            D=np.zeros((ny, nu)), F=np.zeros((1, 0)), G=np.zeros((0, 1)),
                            coulomb=np.zeros(0), static=np.zeros(0), x0=np.zeros(1),
                            input_slots=tuple(input_slots), output_slots=tuple(output_slots))


def _ops_program(names, ops, table, record, blocks=()):
    return p.HybridProgram(step=1e-3, slot_names=tuple(names), continuous=_no_plant(),
                           blocks=tuple(blocks), ops=tuple(ops), table=np.asarray(table, dtype=float),
                           record=tuple(record))


def _two_mass(m1=2.0, m2=1.0, k=1000.0, c=2.0):
    """Two masses, one spring-damper, force on mass 1; states (x1, x2, v1, v2)."""
    A = np.array([[0, 0, 1, 0],
                  [0, 0, 0, 1],
                  [-k / m1, k / m1, -c / m1, c / m1],
                  [k / m2, -k / m2, c / m2, -c / m2]])
    B = np.array([[0.0], [0.0], [1.0 / m1], [0.0]])
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    return A, B, C


def _pid(h, kp=75.0, ki=40.0, kd=21.0, tf=0.01):
    """Discrete (Tustin) PID with a filtered derivative, as a state space with dt = h."""
    s = control.tf("s")
    return control.ss(control.c2d(kp + ki / s + kd * s / (tf * s + 1), h, "tustin"))


def _closed_loop_program(h, r, ctrl, A, B, C, scale=1.0):
    names = ("y1", "y2", "r", "e", "u")
    blk = p.LinearBlock(A=ctrl.A, B=ctrl.B, C=ctrl.C, D=ctrl.D, inputs=(3,), outputs=(4,))
    cont = p.ContinuousPart(A=A, B=B * scale, C=C, D=np.zeros((2, 1)), F=np.zeros((4, 0)),
                            G=np.zeros((0, 4)), coulomb=np.zeros(0), static=np.zeros(0),
                            x0=np.zeros(4), input_slots=(4,), output_slots=(0, 1))
    ops = (p.Setpoint(column=0, output=2),
           p.Sum(inputs=(2, 0), weights=(1.0, -1.0), output=3),
           p.LinearOutput(block=0),
           p.LinearUpdate(block=0))
    return p.HybridProgram(step=h, slot_names=names, continuous=cont, blocks=(blk,), ops=ops,
                           table=np.asarray(r, dtype=float)[None, :], record=(0, 1, 4))


# ------------------------------------------------------------------------------------ exactness

def test_single_rate_linear_loop_matches_python_control():
    h, n = 1e-3, 3000
    A, B, C = _two_mass()
    ctrl = _pid(h)
    t = np.arange(n) * h
    r = 0.01 * (t >= 0.01) + 0.002 * np.sin(2 * np.pi * 1.5 * t)

    # independent model: ZOH plant sampled at t_k, controller output held over [t_k, t_k+1)
    plant_d = control.c2d(control.ss(A, B, C, np.zeros((2, 1)), inputs="u", outputs=["y1", "y2"]),
                          h, "zoh")
    ctrl_d = control.ss(ctrl.A, ctrl.B, ctrl.C, ctrl.D, h, inputs="e", outputs="u")
    error = control.summing_junction(inputs=["r", "-y1"], output="e", dt=h)
    loop = control.interconnect([plant_d, ctrl_d, error], inplist="r", outlist=["y1", "y2", "u"])
    assert np.max(np.abs(np.linalg.eigvals(loop.A))) < 1.0       # the reference loop is stable
    expected = control.forced_response(loop, T=t, U=r).outputs.T   # (n, 3)

    res = run(_closed_loop_program(h, r, ctrl, A, B, C), n)
    assert res.record_names == ("y1", "y2", "u")
    # t_k = k h is one rounding: |error| <= eps·t_max/2 = 3.3e-16 for t <= 3 s
    assert_allclose(res.time, t, rtol=0, atol=1e-15)
    for i in range(3):
        scale = np.max(np.abs(expected[:, i]))
        assert scale > 0
        # both sides discretise by expm (a few eps per step) and run 3000 steps of a stable loop; python-
        # control's interconnect realises the loop in another basis, so the rounding is amplified by the
        # realisations' conditioning: n·eps ≈ 7e-13 per unit of conditioning, 1e-9 of the signal's scale allows
        # a conditioning of ~1e3
        assert_allclose(res.records[:, i], expected[:, i], rtol=0, atol=1e-9 * scale)
    assert_allclose(res.states[:, :2], expected[:, :2], rtol=0, atol=1e-9 * np.abs(expected).max())


def test_feedthrough_uses_the_input_held_over_the_previous_step():
    # y = C x + D u is written before the ops: D acts on the input latched at the previous step
    h = 0.01
    cont = p.ContinuousPart(A=np.array([[-1.0]]), B=np.array([[1.0]]), C=np.array([[0.5]]),
                            D=np.array([[2.0]]), F=np.zeros((1, 0)), G=np.zeros((0, 1)),
                            coulomb=np.zeros(0), static=np.zeros(0), x0=np.array([1.0]),
                            input_slots=(1,), output_slots=(0,))
    u = np.array([3.0, -1.0, 4.0, 1.0, 5.0, 9.0])
    prog = p.HybridProgram(step=h, slot_names=("y", "u"), continuous=cont,
                           ops=(p.Setpoint(column=0, output=1),), table=u[None, :], record=(0, 1))
    res = run(prog, len(u))
    a = np.exp(-h)
    x, u_prev, y = 1.0, 0.0, []
    for uk in u:
        y.append(0.5 * x + 2.0 * u_prev)
        x = a * x + (1 - a) * uk
        u_prev = uk
    # six steps of a scalar recurrence, a few roundings each, and exp(-h) by expm vs np.exp (<= 2 ulp): ~30 eps
    # = 7e-15
    assert_allclose(res.records[:, 0], y, rtol=1e-13)
    # a copied input: exact (default rtol irrelevant)
    assert_allclose(res.records[:, 1], u)
    assert_allclose(res.final_state, [x], rtol=1e-13)


# ------------------------------------------------------------------------------- op semantics

def test_delay_shifts_by_whole_executions_of_the_op():
    n = 20
    ramp = np.arange(1.0, n + 1)
    ops = [p.Setpoint(column=0, output=0),
           p.Delay(input=0, output=1, samples=3),
           p.Delay(period=2, input=0, output=2, samples=2),
           p.Delay(input=0, output=3, samples=0)]
    res = run(_ops_program(["a", "d3", "d2x2", "d0"], ops, ramp[None, :], (0, 1, 2, 3)), n)
    a, d3, d2, d0 = res.records.T
    assert_array_equal(a, ramp)
    assert_array_equal(d3, np.concatenate([np.zeros(3), ramp[:-3]]))
    assert_array_equal(d0, ramp)
    # executed at k = 0, 2, 4, ...: the value of 2 executions (4 steps) ago, held between executions
    expected = [0.0 if k < 4 else ramp[k - k % 2 - 4] for k in range(n)]
    assert_array_equal(d2, expected)


def test_period_and_phase_select_the_steps_and_setpoints_count_executions():
    n = 17
    table = np.array([10.0 + np.arange(4.0), 100.0 + np.arange(4.0)])   # 4 samples, then held
    ops = [p.Setpoint(column=0, output=0),
           p.Sum(period=4, phase=1, inputs=(0,), weights=(2.0,), output=1, offset=0.5),
           p.Setpoint(period=4, column=1, output=2)]
    res = run(_ops_program(["a", "s", "sp"], ops, table, (0, 1, 2)), n)
    a, s, sp = res.records.T
    assert_array_equal(a, [10.0 + min(k, 3) for k in range(n)])
    exp_s = [0.0 if k < 1 else 2.0 * a[k - (k - 1) % 4] + 0.5 for k in range(n)]
    assert_array_equal(s, exp_s)
    # executions j = 0, 1, 2, ... at k = 0, 4, 8, ...; the table holds its last sample
    exp_sp = [100.0 + min(k // 4, 3) for k in range(n)]
    assert_array_equal(sp, exp_sp)


def test_quantize_round_and_floor():
    x = np.array([-1.26, -0.74, -0.2, 0.24, 0.26, 0.74, 1.01, 2.49])
    ops = [p.Setpoint(column=0, output=0),
           p.Quantize(input=0, output=1, step=0.5, mode="round"),
           p.Quantize(input=0, output=2, step=0.5, mode="floor")]
    res = run(_ops_program(["x", "r", "f"], ops, x[None, :], (1, 2)), len(x))
    # sums and delays of binary fractions: exact in floating point
    assert_allclose(res.records[:, 0], [-1.5, -0.5, 0.0, 0.0, 0.5, 0.5, 1.0, 2.5])
    assert_allclose(res.records[:, 1], [-1.5, -1.0, -0.5, 0.0, 0.0, 0.5, 1.0, 2.0])


def test_saturate_with_constant_and_slot_bounds():
    x = np.array([-5.0, -1.0, 0.0, 0.5, 2.0, 7.0])
    lo = np.array([-2.0, -2.0, 0.5, -1.0, -3.0, 1.0])
    hi = np.array([3.0, 3.0, 1.0, 0.2, 1.5, 6.0])
    ops = [p.Setpoint(column=0, output=0), p.Setpoint(column=1, output=1),
           p.Setpoint(column=2, output=2),
           p.Saturate(input=0, output=3, lower_slot=1, upper_slot=2),
           p.Saturate(input=0, output=4, lower=-1.0, upper=1.0),
           p.Saturate(input=0, output=5, lower=-0.5, upper_slot=2)]
    res = run(_ops_program(["x", "lo", "hi", "s1", "s2", "s3"], ops, np.array([x, lo, hi]),
                           (3, 4, 5)), len(x))
    assert_array_equal(res.records[:, 0], [-2.0, -1.0, 0.5, 0.2, 1.5, 6.0])
    assert_array_equal(res.records[:, 1], [-1.0, -1.0, 0.0, 0.5, 1.0, 1.0])
    assert_array_equal(res.records[:, 2], [-0.5, -0.5, 0.0, 0.2, 1.5, 6.0])


def _current_limit_expected(w, i_peak, u_max, R, ke, wl):
    """Hand computation: roots of (R i + ke w)^2 + (wl w i)^2 - u_max^2 (vertex when none)."""
    a, b, c = R ** 2 + (wl * w) ** 2, 2 * R * ke * w, (ke * w) ** 2 - u_max ** 2
    roots = np.roots([a, b, c])
    if np.all(np.isreal(roots)):
        lo, hi = np.sort(roots.real)
    else:
        lo = hi = -b / (2 * a)
    return np.clip(lo, -i_peak, i_peak), np.clip(hi, -i_peak, i_peak)


def test_current_limit_against_hand_computed_bounds():
    R, ke, wl, u_max, i_peak = 0.5, 1.0, 0.01, 300.0, 50.0
    w = np.array([0.0, 100.0, 250.0, 290.0, 310.0, -250.0, -310.0])
    ops = [p.Setpoint(column=0, output=0),
           p.CurrentLimit(speed=0, lower=1, upper=2, i_peak=i_peak, u_max=u_max, resistance=R,
                          ke=ke, wl=wl),
           p.CurrentLimit(speed=0, lower=3, upper=4, i_peak=i_peak),                 # u_max = inf
           p.CurrentLimit(speed=0, lower=5, upper=6, i_peak=i_peak, u_max=u_max, ke=ke)]  # R = wl = 0
    res = run(_ops_program(["w", "lo", "hi", "lo2", "hi2", "lo3", "hi3"], ops, w[None, :],
                           range(1, 7)), len(w))
    lo, hi, lo2, hi2, lo3, hi3 = res.records.T
    for k, wk in enumerate(w):
        exp_lo, exp_hi = _current_limit_expected(wk, i_peak, u_max, R, ke, wl)
        # the same quadratic, in closed form in the kernel and by np.roots (companion eigenvalues) here; its
        # roots are simple, each with condition |r|/|r1 - r2| < 0.8 at these speeds, so both are accurate to a
        # few eps: 1e-12 is ~4500 eps
        assert lo[k] == pytest.approx(exp_lo, rel=1e-12, abs=1e-12)
        assert hi[k] == pytest.approx(exp_hi, rel=1e-12, abs=1e-12)
    # at 250 rad/s the upper bound is voltage-limited: the voltage is exactly u_max there
    assert hi[2] < i_peak
    # an identity of the root, a few eps × the root's condition (< 1): the default rel 1e-6 is loose on purpose
    assert (R * hi[2] + ke * 250) ** 2 + (wl * 250 * hi[2]) ** 2 == pytest.approx(u_max ** 2)
    # at 310 rad/s the back-EMF exceeds the supply: both bounds at the least-voltage current
    assert lo[4] == hi[4] == pytest.approx(-R * ke * 310 / (R ** 2 + (wl * 310) ** 2))
    assert_array_equal(lo2, -i_peak)
    assert_array_equal(hi2, i_peak)
    # no resistance nor inductance: unbounded by voltage below u_max / ke, braking beyond
    assert_array_equal(lo3, [-i_peak] * 4 + [-i_peak, -i_peak, i_peak])
    assert_array_equal(hi3, [i_peak] * 4 + [-i_peak, i_peak, i_peak])


def test_clamp_gate_truth_table():
    #               e     unsat  sat   -> out
    cases = np.array([[1.0, 2.0, 1.0, 0.0],     # saturated, error pushes further: clamp
                      [-1.0, 2.0, 1.0, -1.0],   # saturated, error pulls back: integrate
                      [1.0, 1.0, 1.0, 1.0],     # not saturated
                      [-1.0, -2.0, -1.0, 0.0],  # saturated low, error pushes lower
                      [1.0, -2.0, -1.0, 1.0],   # saturated low, error pulls back
                      [0.0, 2.0, 1.0, 0.0],
                      [-3.0, -3.0, -3.0, -3.0]])
    ops = [p.Setpoint(column=0, output=0), p.Setpoint(column=1, output=1),
           p.Setpoint(column=2, output=2), p.ClampGate(input=0, unsaturated=1, saturated=2, output=3)]
    res = run(_ops_program(["e", "u", "s", "o"], ops, cases[:, :3].T, (3,)), len(cases))
    assert_array_equal(res.records[:, 0], cases[:, 3])


def test_linear_block_output_and_update_order():
    # an accumulator: y = x + u (output before update), x+ = x + u
    blk = p.LinearBlock(A=np.eye(1), B=np.eye(1), C=np.eye(1), D=np.eye(1), inputs=(0,),
                        outputs=(1,), x0=np.array([10.0]))
    u = np.array([1.0, 2.0, 3.0, 4.0])
    ops = [p.Setpoint(column=0, output=0), p.LinearOutput(block=0), p.LinearUpdate(block=0)]
    res = run(_ops_program(["u", "y"], ops, u[None, :], (1,), blocks=(blk,)), len(u))
    assert_array_equal(res.records[:, 0], 10.0 + np.cumsum(u))


# ---------------------------------------------------------------------------------- stick-slip

def _stick_slip_program(h, m, k, V, Fs, Fc):
    """Mass m pulled through spring k by a driver moving at V; states (p driver, x mass, v mass)."""
    A = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [k / m, -k / m, 0.0]])
    cont = p.ContinuousPart(A=A, B=np.array([[1.0], [0.0], [0.0]]), C=np.array([[1.0, -1.0, 0.0]]),
                            D=np.zeros((1, 1)), F=np.array([[0.0], [0.0], [1.0 / m]]),
                            G=np.array([[0.0, 0.0, 1.0]]), coulomb=np.array([Fc]),
                            static=np.array([Fs]), x0=np.zeros(3), input_slots=(0,),
                            output_slots=(1,), friction_slots=(2,))
    return p.HybridProgram(step=h, slot_names=("V", "extension", "friction"), continuous=cont,
                           ops=(p.Setpoint(column=0, output=0),), table=np.array([[V]]),
                           record=(1, 2))


def _stick_slip_events(m, k, V, Fs, Fc, t_end):
    """Closed form: (slip start, slip end) times and the mass position x(t) of the pulled mass."""
    w = np.sqrt(k / m)
    A = (Fs - Fc) / k

    def xdot(t):
        return V * (1 - np.cos(w * t)) + A * w * np.sin(w * t)

    t_slip = brentq(xdot, 1e-6 / w, 2 * np.pi / w)      # first zero of the mass velocity
    e_end = Fc / k + A * np.cos(w * t_slip) + V / w * np.sin(w * t_slip)
    assert abs(k * e_end) <= Fs                       # it does stick again
    t_stick = (Fs - k * e_end) / (k * V)
    events, t = [], Fs / (k * V)                      # starts stuck at zero extension
    while t < t_end:
        events.append((t, t + t_slip))
        t += t_slip + t_stick

    def position(tt):
        x = np.zeros_like(tt)
        for i, ti in enumerate(tt):
            x[i] = 0.0
            for t0, t1 in events:
                if ti <= t0:
                    break
                tau = min(ti, t1) - t0
                x[i] = V * (t0 + tau) - (Fc / k + A * np.cos(w * tau) + V / w * np.sin(w * tau))
        return x

    return events, position


def test_stick_slip_matches_closed_form():
    h, m, k, V, Fs, Fc = 1e-3, 1.0, 100.0, 0.01, 2.0, 1.0
    n = 7500
    res = run(_stick_slip_program(h, m, k, V, Fs, Fc), n)
    events, position = _stick_slip_events(m, k, V, Fs, Fc, n * h)
    assert len(events) >= 3
    stuck = res.stuck[:, 0]
    starts = np.flatnonzero(stuck[:-1] & ~stuck[1:]) + 1      # first step of each slip
    ends = np.flatnonzero(~stuck[:-1] & stuck[1:]) + 1        # first step stuck again
    assert len(starts) == len(events) and len(ends) == len(events)
    for (t0, t1), k0, k1 in zip(events, starts, ends):
        # stuck[k] describes [t_k, t_k+1): the first sliding step starts within one step of t0
        # event times are quantised to the step h (stuck[k] is per step) plus half a step for the sub-step
        # location
        assert abs(k0 * h - t0) <= 1.5 * h
        assert abs(k1 * h - t1) <= 1.5 * h
    # the trajectory itself: events are located to h / 2**levels; each breakaway overshoots the
    # static force by at most k V h / 2**levels, which delays the next cycles a little more
    error = np.abs(res.states[:, 1] - position(res.time)).max()
    # error analysis: a breakaway is located to h/2**10 ≈ 1e-6 s; the slip then runs late by at most that, at
    # most 0.12 m/s (V + A w): 1.2e-7 m per slip, ~5 slips in 7.5 s: 6e-7 m
    assert error < 1e-6                                       # (the stroke is 0.07 m)
    fine = run(_stick_slip_program(h, m, k, V, Fs, Fc), n, levels=14)
    # that error is linear in the sub-step: 16 times finer must give at least 8 times smaller (factor 2 margin)
    assert np.abs(fine.states[:, 1] - position(fine.time)).max() < error / 8
    # friction: the holding force -k (p - x) while stuck, -Fc (against v > 0) while sliding
    ext = res.states[:, 0] - res.states[:, 1]
    # the same holding force by another formula: rounding of k·(p - x) with |p|, |x| <= 0.1 m is <= k·eps·0.1 ≈
    # 2e-15 N; 1e-12 N absolute, 1e-9 relative are slack
    assert_allclose(res.friction[stuck, 0], -k * ext[stuck], rtol=1e-9, atol=1e-12)
    # a copied constant: exact
    assert_allclose(res.friction[~stuck, 0], -Fc)
    # recorded forces are those after each step's events are resolved: <= Fs up to the rounding above (1e-9 N
    # slack)
    assert np.all(np.abs(res.friction[:, 0]) <= Fs + 1e-9)
    # a stick is located and the velocity zeroed at the event: only rounding of v ~ 0.1 m/s (1e-17) may go below
    # 0
    assert np.all(res.states[~stuck, 2] >= -1e-9)                 # never slides backwards
    # C x = p - x by the same operations: the rounding of a difference of <= 0.1 m values, 1.4e-17 m
    assert_allclose(res.records[:, 0], np.concatenate([[0.0], ext[1:]]), atol=1e-15)
    # the friction slot is written before the ops with the same acting force
    # as the friction check above
    assert_allclose(res.records[1:, 1][stuck[1:]], -k * ext[1:][stuck[1:]], rtol=1e-9, atol=1e-12)


def _two_link_program(h, m, k, V, Fs, Fc):
    """Driver -(k1)- mass 1 -(k2)- mass 2, each mass on its own friction; states (p, x1, x2, v1, v2)."""
    (m1, m2), (k1, k2) = m, k
    A = np.zeros((5, 5))
    A[1, 3] = A[2, 4] = 1.0
    A[3, :3] = [k1 / m1, -(k1 + k2) / m1, k2 / m1]
    A[4, :3] = [0.0, k2 / m2, -k2 / m2]
    F = np.zeros((5, 2))
    F[3, 0], F[4, 1] = 1 / m1, 1 / m2
    G = np.zeros((2, 5))
    G[0, 3] = G[1, 4] = 1.0
    cont = p.ContinuousPart(A=A, B=np.eye(5, 1), C=np.zeros((0, 5)), D=np.zeros((0, 1)), F=F, G=G,
                            coulomb=np.array(Fc), static=np.array(Fs), x0=np.zeros(5),
                            input_slots=(0,), output_slots=())
    return p.HybridProgram(step=h, slot_names=("V",), continuous=cont,
                           ops=(p.Setpoint(column=0, output=0),), table=np.array([[V]]))


def _two_link_reference(m, k, V, Fs, Fc, t_end):
    """Event-driven reference with solve_ivp: one ODE per stick mode, events at v = 0 / breakaway."""
    (m1, m2), (k1, k2) = m, k
    masses = np.array([m1, m2])

    def spring(y):                      # spring forces on the masses, y = (p, x1, x2, v1, v2)
        return np.array([k1 * (y[0] - y[1]) + k2 * (y[2] - y[1]), k2 * (y[1] - y[2])])

    stuck, d = [True, True], [0.0, 0.0]
    t, y = 0.0, np.zeros(5)
    pieces, switches = [], []
    while True:
        def rhs(_, yy):
            f = spring(yy)
            acc = [0.0 if stuck[i] else (f[i] - Fc[i] * d[i]) / masses[i] for i in range(2)]
            return [V, yy[3], yy[4], acc[0], acc[1]]

        events = []
        for i in range(2):
            if stuck[i]:
                ev = (lambda i: lambda _, yy: abs(spring(yy)[i]) - Fs[i])(i)
                ev.direction = 1
            else:
                ev = (lambda i: lambda _, yy: d[i] * yy[3 + i])(i)
                ev.direction = -1
            ev.terminal = True
            events.append(ev)
        # the reference's own accuracy: DOP853 at rtol 1e-12 and event location to ~1e-12 s, far below the
        # kernel's 1e-6 s event location, so the comparison below measures the kernel
        sol = solve_ivp(rhs, (t, t_end), y, events=events, rtol=1e-12, atol=1e-15,
                        dense_output=True, method="DOP853", max_step=0.01)
        pieces.append((t, sol.t[-1], sol.sol))
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            break
        i = next(i for i in range(2) if len(sol.t_events[i]))
        f = spring(y)
        switches.append(t)
        if stuck[i]:                    # breakaway, sliding along the spring force
            stuck[i], d[i] = False, np.sign(f[i])
        else:                           # velocity reached zero: stick or reverse
            y[3 + i] = 0.0
            if abs(f[i]) <= Fs[i]:
                stuck[i] = True
            else:
                d[i] = np.sign(f[i])

    def state(times):
        out = np.zeros((len(times), 5))
        for n, ti in enumerate(times):
            out[n] = next(s(ti) for a, b, s in pieces if a <= ti <= b)
        return out

    return state, np.array(switches)


def test_two_coupled_friction_links_match_an_event_driven_reference():
    h, n = 1e-3, 6000
    m, k, V, Fs, Fc = (1.0, 0.5), (100.0, 50.0), 0.01, (2.0, 0.8), (1.0, 0.5)
    res = run(_two_link_program(h, m, k, V, Fs, Fc), n)
    state, switches = _two_link_reference(m, k, V, Fs, Fc, n * h)
    assert len(switches) >= 5                      # both links stick and slip, also together
    ref = state(res.time)
    error = np.abs(res.states[:, 1:3] - ref[:, 1:3]).max()
    # as the single-link case: located to h/2**10, slips at ~0.1 m/s, twice as many switches (>= 5 per link
    # pair): ~1e-6 m
    assert error < 2e-6                            # (strokes about 0.045 m)
    fine = run(_two_link_program(h, m, k, V, Fs, Fc), n, levels=14)
    # 16 times finer sub-steps: at least 4 times smaller (the reference ODE solver's rtol 1e-12 stays far below)
    assert np.abs(fine.states[:, 1:3] - ref[:, 1:3]).max() < error / 4
    changes = np.flatnonzero(np.any(res.stuck[1:] != res.stuck[:-1], axis=1)) + 1
    assert len(changes) == len(switches)
    # step quantisation plus half a step, as above
    assert_allclose(changes * h, switches, atol=1.5 * h)


def test_stick_projection_conserves_momentum_and_freezes_the_link():
    rng = np.random.default_rng(3)
    n = 3
    M = np.diag(rng.uniform(1, 3, n))
    K = np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 1]]) * 50
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -0.1 * Minv @ K]])
    g = np.array([[1.0, -1.0, 0.0], [0.0, 0.0, 1.0]])          # a relative and an absolute link
    F = np.vstack([np.zeros((n, 2)), Minv @ g.T])
    G = np.hstack([np.zeros((2, n)), g])
    cont = p.ContinuousPart(A=A, B=np.zeros((2 * n, 0)), C=np.zeros((0, 2 * n)), D=np.zeros((0, 0)),
                            F=F, G=G, coulomb=np.array([1.0, 2.0]), static=np.array([1.5, 2.5]),
                            x0=np.zeros(2 * n), input_slots=(), output_slots=())
    x = rng.normal(size=2 * n)
    for mask in (1, 2, 3):
        d = constrained_dynamics(cont, mask)
        xp = d.projection @ x
        stuck = [(mask >> j) & 1 for j in range(2)]
        # the projection has an identity block on the positions: exact
        assert_allclose(xp[:n], x[:n])                          # positions unchanged
        for j in range(2):
            if stuck[j]:
                # O(1) velocities through a solve with M (condition <= 3): rounding ~10 eps = 2e-15; 1e-12 slack
                assert abs(g[j] @ xp[n:]) < 1e-12              # stuck links do not slide
                # relative to the acceleration scale: rounding ~κ(G M⁻¹ Gᵀ)·eps ≈ 1e-15 (κ <= 10 here); 1e-9
                # slack
                assert abs(G[j] @ d.A @ x) < 1e-9 * np.abs(A @ x).max()
        # the momentum changes only along the stuck links' directions (impulses g_j * p_j)
        dp = M @ (xp[n:] - x[n:])
        gs = g[np.array(stuck, dtype=bool)]
        coef = np.linalg.lstsq(gs.T, dp, rcond=None)[0]
        # an O(1) least-squares fit of an exact combination: residual ~κ(g)·eps ≈ 1e-15
        assert_allclose(gs.T @ coef, dp, atol=1e-12)
        # the holding force keeps the stuck links' accelerations at zero
        f_slip = np.array([0.0 if s else 1.0 for s in stuck])
        lam = d.Lx @ x + d.Lf @ f_slip
        acc = A @ x + F @ (f_slip + lam)
        for j in range(2):
            if stuck[j]:
                # as above: rounding relative to the acceleration scale
                assert abs(G[j] @ acc) < 1e-9 * np.abs(A @ x).max()
            else:
                assert lam[j] == 0.0


def test_discretisation_levels_are_exact_fractions():
    A, B, _ = _two_mass()
    cont = p.ContinuousPart(A=A, B=B, C=np.zeros((0, 4)), D=np.zeros((0, 1)), F=B.copy(),
                            G=np.array([[0.0, 0.0, 1.0, 0.0]]), coulomb=np.array([1.0]),
                            static=np.array([1.0]), x0=np.zeros(4), input_slots=(0,), output_slots=())
    h = 1e-3
    disc = discretize(cont, h, levels=4)
    assert disc.Phi.shape == (2, 5, 4, 4) and disc.Gamma.shape == (2, 5, 4, 2)
    for lev in range(5):
        E = scipy.linalg.expm(np.block([[A, B, B], [np.zeros((2, 6))]]) * h / 2 ** lev)
        # expm's error is normwise (a few eps of ||E||, scaling and squaring), not per entry: Gamma's
        # entries (~h²/m) are compared at the scale of the whole block, as in the squaring test below
        scale = np.abs(E[:4]).max()
        assert_allclose(disc.Phi[0, lev], E[:4, :4], rtol=0, atol=1e-14 * scale)
        assert_allclose(disc.Gamma[0, lev], E[:4, 4:], rtol=0, atol=1e-14 * scale)
    # stuck: the mass-1 velocity is frozen
    # the frozen row is set exactly; 1e-15 is rounding of a unit entry
    assert_allclose(disc.Phi[1, 0][2], [0, 0, 1, 0], atol=1e-15)


def test_more_than_six_friction_links_is_refused():
    nx, nf = 2, 7
    cont = p.ContinuousPart(A=np.zeros((nx, nx)), B=np.zeros((nx, 0)), C=np.zeros((0, nx)),
                            D=np.zeros((0, 0)), F=np.ones((nx, nf)), G=np.ones((nf, nx)),
                            coulomb=np.ones(nf), static=np.ones(nf), x0=np.zeros(nx),
                            input_slots=(), output_slots=())
    with pytest.raises(ValueError, match="at most 6"):
        discretize(cont, 1e-3)
    with pytest.raises(ModelError, match="at most 6"):
        run(p.HybridProgram(step=1e-3, slot_names=(), continuous=cont), 10)


# ---------------------------------------------------------------------------------- divergence

def test_unstable_loop_raises_with_the_time():
    h, n = 1e-3, 3000
    A, B, C = _two_mass()
    ctrl = control.ss([], [], [], [[-400.0]], h)             # positive position feedback
    prog = _closed_loop_program(h, np.full(n, 0.01), ctrl, A, B, C)
    with pytest.raises(SimulationDiverged, match=r"diverged at t = [0-9.]+(e[-+]?\d+)? s") as info:
        run(prog, n)
    err = info.value
    assert isinstance(err, ArithmeticError) and isinstance(err, SicomatError)
    assert 0 < err.time < n * h
    # the same product k·h, one rounding: default rel 1e-6 is slack
    assert err.time == pytest.approx((err.step + 1) * h)


def test_exponential_growth_stops_at_the_documented_limit():
    # x' = x from x0 = 1: the limit is 1e9 * (1 + e^(10 h)), crossed at t = ln(limit)
    h = 0.01
    cont = p.ContinuousPart(A=np.array([[1.0]]), B=np.zeros((1, 0)), C=np.zeros((0, 1)),
                            D=np.zeros((0, 0)), F=np.zeros((1, 0)), G=np.zeros((0, 1)),
                            coulomb=np.zeros(0), static=np.zeros(0), x0=np.array([1.0]),
                            input_slots=(), output_slots=())
    prog = p.HybridProgram(step=h, slot_names=(), continuous=cont)
    with pytest.raises(SimulationDiverged) as info:
        run(prog, 5000)
    t_cross = np.log(1e9 * (1 + np.exp(10 * h)))
    # divergence is tested at step ends: the crossing is reported at the end of its step, within one step
    assert info.value.time == pytest.approx(np.ceil(t_cross / h) * h, abs=1.01 * h)
    with pytest.raises(SimulationDiverged):
        run(prog, 5000, divergence_limit=100.0)
    # 100 multiplications by expm(h) = e^h (<= 2 ulp each): <= 200 eps = 4.4e-14
    assert run(prog, 100).final_state[0] == pytest.approx(np.e, rel=1e-12)


def test_nan_setpoint_raises_instead_of_returning_nan():
    n = 10
    table = np.array([[1.0, 2.0, np.nan, 4.0] + [5.0] * 6])
    prog = _ops_program(["a", "b"], [p.Setpoint(column=0, output=0),
                                     p.Sum(inputs=(0,), weights=(2.0,), output=1)], table, (1,))
    with pytest.raises(SimulationDiverged, match=r"t = 0.002 s"):
        run(prog, n)


# ------------------------------------------------------------------------------------- batches

def test_batch_equals_single_runs():
    h, n = 1e-3, 1500
    _, _, C = _two_mass()
    t = np.arange(n) * h
    progs = []
    for i in range(5):
        A, B, _ = _two_mass(m1=2.0 + 0.3 * i, k=1000.0 * (1 + 0.1 * i))
        r = 0.01 * (t >= 0.01) * (1 + 0.1 * i)
        prog = _closed_loop_program(h, r, _pid(h, kp=75.0 + 10 * i), A, B, C)
        # add a friction link on mass 2 so that the event machinery is exercised too
        cont = prog.continuous
        F = np.array([[0.0], [0.0], [0.0], [1.0]])
        G = np.array([[0.0, 0.0, 0.0, 1.0]])
        cont = p.ContinuousPart(A=cont.A, B=cont.B, C=cont.C, D=cont.D, F=F, G=G,
                                coulomb=np.array([0.05 * (i + 1)]), static=np.array([0.08 * (i + 1)]),
                                x0=cont.x0, input_slots=cont.input_slots,
                                output_slots=cont.output_slots)
        progs.append(p.HybridProgram(step=h, slot_names=prog.slot_names, continuous=cont,
                                     blocks=prog.blocks, ops=prog.ops, table=prog.table,
                                     record=prog.record))
    batch = run_batch(progs, n)
    assert batch.records.shape == (5, n, 3)
    assert not batch.diverged.any()
    singles = [run(pr, n) for pr in progs]
    for i, single in enumerate(singles):
        assert_array_equal(batch.records[i], single.records)
        assert_array_equal(batch.final_states[i], single.final_state)
        assert single.stuck.any() and not single.stuck.all()
    sub = run_batch(progs, n, record_every=7, record=["u", "y2"])
    assert sub.record_names == ("u", "y2")
    # the same k·h: exact
    assert_allclose(sub.time, t[::7])
    for i, single in enumerate(singles):
        assert_array_equal(sub.records[i], single.records[::7][:, [2, 1]])


def test_batch_refuses_different_structures_and_flags_divergence():
    h, n = 1e-3, 2000
    A, B, C = _two_mass()
    r = np.full(n, 0.01)
    good = _closed_loop_program(h, r, _pid(h), A, B, C)
    bad = _closed_loop_program(h, r, control.ss([], [], [], [[-400.0]], h), A, B, C)
    with pytest.raises(ModelError, match="structure"):
        run_batch([good, bad], n)
    unstable = _closed_loop_program(h, r, _pid(h), A, B, C, scale=-50.0)
    with pytest.raises(SimulationDiverged, match="variant 1"):
        run_batch([good, unstable], n)
    res = run_batch([good, unstable, good], n, on_divergence="flag")
    assert list(res.diverged) == [False, True, False]
    assert np.all(np.isfinite(res.records))
    k = res.diverged_step[1]
    assert 0 < k < n and np.all(res.records[1, k:] == 0.0) and np.all(res.final_states[1] == 0.0)
    assert np.any(res.records[1, :k] != 0.0)
    assert_array_equal(res.records[0], res.records[2])


def test_bare_loop_matches_numpy():
    rng = np.random.default_rng(0)
    Phi = 0.3 * rng.normal(size=(5, 5)) / np.sqrt(5)
    Gamma = rng.normal(size=(5, 2))
    K = 0.1 * rng.normal(size=(2, 5))
    x = np.zeros(5)
    x[0] = 1.0
    for _ in range(50):
        x = Phi @ x + Gamma @ (-K @ x)
    # 50 steps of the same products in another summation order, through a contraction (ρ < 1): rounding <= 50
    # steps × 5 terms × eps ≈ 6e-14 relative
    assert_allclose(bare_loop(Phi, Gamma, K, 50), x, rtol=1e-12, atol=1e-300)


# ------------------------------------------------------------------- discretisation by squaring

def test_every_level_matches_the_matrix_exponential():
    # levels 9, 8, 6, 5, 3, 2, 0 are squares of finer levels: each must still be expm's value
    A, B, _ = _two_mass(k=4.0e5, c=20.0)                 # stiff: ||A h|| well above 1
    cont = p.ContinuousPart(A=A, B=B, C=np.zeros((0, 4)), D=np.zeros((0, 1)), F=B.copy(),
                            G=np.array([[0.0, 0.0, 1.0, 0.0]]), coulomb=np.array([1.0]),
                            static=np.array([1.0]), x0=np.zeros(4), input_slots=(0,), output_slots=())
    h, levels = 1e-3, 10
    disc = discretize(cont, h, levels)
    for mask in (0, 1):
        d = constrained_dynamics(cont, mask)
        M = np.zeros((6, 6))
        M[:4, :4], M[:4, 4:] = d.A, d.B
        for lev in range(levels + 1):
            E = scipy.linalg.expm(M * h / 2 ** lev)
            scale = np.abs(E[:4]).max()
            # expm is accurate to a few eps of ||E|| (observed 2 eps); a level is at most two squarings
            # away from a direct expm (see above), each doubles the error and adds 2 eps with ||E|| ~ 1
            # (lightly damped rotations): <= 4 × few + 6 eps ≈ 20 eps; 1e-14 is 45 eps
            assert_allclose(disc.Phi[mask, lev], E[:4, :4], rtol=0, atol=1e-14 * scale)
            assert_allclose(disc.Gamma[mask, lev], E[:4, 4:], rtol=0, atol=1e-14 * scale)


def test_equal_continuous_parts_are_discretised_once_with_the_same_result():
    A, B, _ = _two_mass()
    parts = [p.ContinuousPart(A=A * s, B=B, C=np.zeros((0, 4)), D=np.zeros((0, 1)), F=B.copy(),
                              G=np.array([[0.0, 0.0, 1.0, 0.0]]), coulomb=np.array([1.0]),
                              static=np.array([1.5]), x0=np.zeros(4), input_slots=(0,),
                              output_slots=())
             for s in (1.0, 1.1, 1.0, 1.0, 1.1)]
    many = discretize_many(parts, 1e-3, 6)
    for v, part in enumerate(parts):
        one = discretize(part, 1e-3, 6)
        for name in ("Phi", "Gamma", "Lx", "Lu", "Lf", "projection"):
            assert_array_equal(getattr(many, name)[v], getattr(one, name))


def test_batch_of_gain_variants_sharing_the_plant_equals_single_runs():
    # controller variants of one plant (one discretisation for all) and another plant, with friction
    h, n = 1e-3, 1500
    _, _, C = _two_mass()
    t = np.arange(n) * h
    progs = []
    for i, (m1, kp) in enumerate([(2.0, 60.0), (2.0, 75.0), (2.6, 75.0), (2.0, 90.0)]):
        A, B, _ = _two_mass(m1=m1)
        prog = _closed_loop_program(h, 0.01 * (t >= 0.01), _pid(h, kp=kp), A, B, C)
        cont = prog.continuous
        cont = p.ContinuousPart(A=cont.A, B=cont.B, C=cont.C, D=cont.D,
                                F=np.array([[0.0], [0.0], [0.0], [1.0]]),
                                G=np.array([[0.0, 0.0, 0.0, 1.0]]), coulomb=np.array([0.1]),
                                static=np.array([0.15]), x0=cont.x0, input_slots=cont.input_slots,
                                output_slots=cont.output_slots)
        progs.append(p.HybridProgram(step=h, slot_names=prog.slot_names, continuous=cont,
                                     blocks=prog.blocks, ops=prog.ops, table=prog.table,
                                     record=prog.record))
    batch = run_batch(progs, n)
    for i, prog in enumerate(progs):
        single = run(prog, n)
        assert single.events > 0
        assert_array_equal(batch.records[i], single.records)
        assert_array_equal(batch.final_states[i], single.final_state)


# ------------------------------------------------------------ zero coefficients of linear blocks

def _block_program(B, D, inputs, table):
    names = ("a", "b", "c", "y")
    blk = p.LinearBlock(A=np.array([[0.5]]), B=np.atleast_2d(B), C=np.array([[2.0]]),
                        D=np.atleast_2d(D), inputs=inputs, outputs=(3,), x0=np.array([0.25]))
    ops = [p.Setpoint(column=i, output=i) for i in range(3)] + [p.LinearOutput(block=0),
                                                                 p.LinearUpdate(block=0)]
    return _ops_program(names, ops, table, (3,), blocks=(blk,))


def test_zero_block_coefficients_are_left_out_exactly():
    rng = np.random.default_rng(5)
    table = rng.normal(size=(3, 40))
    # inputs a, b, c with zero weights on b: the same results as the block reading a and c only
    full = run(_block_program([[1.5, 0.0, -0.25]], [[0.0, 0.0, 3.0]], (0, 1, 2), table), 40)
    dense = run(_block_program([[1.5, -0.25]], [[0.0, 3.0]], (0, 2), table), 40)
    assert_array_equal(full.records, dense.records)
    # a batch keeps a coefficient that is non-zero in any variant: each variant as if alone
    progs = [_block_program([[1.5, 0.0, -0.25]], [[0.0, 0.0, 3.0]], (0, 1, 2), table),
             _block_program([[1.5, 0.7, -0.25]], [[0.0, 0.0, 3.0]], (0, 1, 2), table),
             _block_program([[1.5, 0.0, 0.0]], [[2.0, 0.0, 3.0]], (0, 1, 2), table)]
    batch = run_batch(progs, 40)
    for i, prog in enumerate(progs):
        assert_array_equal(batch.records[i], run(prog, 40).records)

