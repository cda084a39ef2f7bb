"""sicomat.simulate: stick/slip events inside a base step (the in-step envelopes of envelope.py)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from accuracy import EPS

import sicomat
from sicomat.servo.loop import build_servo_loop
from sicomat.io.modelfile import with_overrides
from sicomat.motion.setpoints import Profile, trapezoid_profile
from sicomat.simulation import loop_program
from sicomat.servo import program as p
from sicomat.simulation.continuous import constrained_dynamics, discretize
from sicomat.simulation.envelope import curvature_bounds
from sicomat.simulation.kernel import run

LEVELS = 10


# ------------------------------------------------------------------ a stuck mass shaken by a fast mode

def _shaken_mass(h, m1=1.0, m2=0.2, f2=1500.0, zeta=0.01, k1=1000.0, force=9.0, amplitude=2.0,
                 Fs=10.0, Fc=5.0, period=1):
    """Mass 1 (friction to the ground, spring k1 to the ground, a held force) carries mass 2 on a
    stiff spring whose mode (``f2`` Hz, faster than the step) makes the spring force swing by
    ``amplitude`` around 0 from the start; states (x1, x2, v1, v2)."""
    k = m2 * (2 * np.pi * f2) ** 2
    c = 2 * zeta * np.sqrt(k * m2)
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                  [-(k + k1) / m1, k / m1, -c / m1, c / m1],
                  [k / m2, -k / m2, c / m2, -c / m2]])
    e = np.array([[0.0], [0.0], [1.0 / m1], [0.0]])
    x0 = np.array([0.0, 0.0, 0.0, amplitude * np.sqrt(1.0 / (k * m2))])  # k x2 = amplitude sin(w t)
    cont = p.ContinuousPart(A=A, B=e, C=np.zeros((0, 4)), D=np.zeros((0, 1)), F=e.copy(),
                            G=np.array([[0.0, 0.0, 1.0, 0.0]]), coulomb=np.array([Fc]),
                            static=np.array([Fs]), x0=x0, input_slots=(0,), output_slots=())
    prog = p.HybridProgram(step=h, slot_names=("force",), continuous=cont,
                           ops=(p.Setpoint(period=period, column=0, output=0),),
                           table=np.array([[force]]))
    return prog, dict(m1=m1, m2=m2, k=k, c=c, k1=k1, force=force, Fs=Fs, Fc=Fc, x0=x0)


def _shaken_mass_reference(par, t_end):
    """Event-driven solution (DOP853, rtol 1e-12) written from the mechanics, not from the kernel's
    matrices: mass 1 held (v1 = 0) while |spring + damper + force - k1 x1| <= Fs, sliding against
    Fc otherwise; breakaway and v1 = 0 located by solve_ivp's root finding."""
    m1, m2, k, c, k1, force, Fs, Fc = (par[n] for n in ("m1", "m2", "k", "c", "k1", "force", "Fs", "Fc"))

    def drive(y):                       # every force on mass 1 but friction
        return k * (y[1] - y[0]) + c * (y[3] - y[2]) - k1 * y[0] + force

    def rhs_of(stuck, d):
        def rhs(_, y):
            a2 = (-k * (y[1] - y[0]) - c * (y[3] - y[2])) / m2
            a1 = 0.0 if stuck else (drive(y) - Fc * d) / m1
            return [y[2], y[3], a1, a2]
        return rhs

    stuck, d = True, 0.0
    t, y = 0.0, np.array(par["x0"], dtype=float)
    pieces, switches = [], []
    while True:
        if stuck:
            ev = lambda _, yy: abs(drive(yy)) - Fs  # noqa: E731
            ev.direction = 1
        else:
            ev = (lambda dd: lambda _, yy: dd * yy[2])(d)
            ev.direction = -1
        ev.terminal = True
        # the oracle's accuracy: DOP853 at rtol 1e-12 (atol 1e-15 below the µm/mm-per-s states), events
        # located by its root finder to ~1e-15 s; both far below the h/2^10 location bound asserted below
        sol = solve_ivp(rhs_of(stuck, d), (t, t_end), y, events=[ev], rtol=1e-12, atol=1e-15,
                        dense_output=True, method="DOP853", max_step=1e-5)
        pieces.append((t, sol.t[-1], sol.sol))
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            break
        switches.append(t)
        if stuck:
            stuck, d = False, np.sign(drive(y))
        else:
            y[2] = 0.0
            if abs(drive(y)) <= Fs:
                stuck = True
            else:
                d = np.sign(drive(y))

    def state(times):
        return np.array([next(s(ti) for a, b, s in pieces if a <= ti <= b) for ti in times])

    return state, np.array(switches)


def test_breakaway_inside_a_step_matches_an_event_driven_reference():
    # the spring force peaks at force + amplitude = 11 N > Fs = 10 N a sixth of a period after
    # the start (0.11 ms), inside the first 1 ms step, and is back to 9 N at every step end: an
    # end-of-step test never sees it, and mass 1 would stay stuck for ever
    h, n = 1e-3, 300
    prog, par = _shaken_mass(h)
    state, switches = _shaken_mass_reference(par, n * h)
    assert len(switches) >= 2 and switches[0] < h           # breakaway in step 0, then re-stick
    res = run(prog, n, LEVELS)
    ref = state(res.time)
    # error analysis: each event is taken at the first point of the grid h / 2**10 past it, so
    # late by dt <= h / 1024 ~ 1e-6 s; over that interval the acceleration of mass 1 is wrong by
    # at most (Fs + Fc + amplitude) / m1 = 17 m/s² (held instead of sliding, or the reverse),
    # i.e. a velocity error of 1.7e-5 m/s per event, which the k1-spring oscillator (period
    # 0.2 s) turns into position errors of at most that times the remaining 0.3 s: 5e-6 m per
    # event. The oracle (rtol 1e-12 on strokes of ~4 mm) is exact at this scale.
    dv = (par["Fs"] + par["Fc"] + 2.0) / par["m1"] * h / 2 ** LEVELS
    n_events = len(switches)
    assert np.abs(res.states[:, 2] - ref[:, 2]).max() < n_events * dv * 2
    assert np.abs(res.states[:, 0] - ref[:, 0]).max() < n_events * dv * n * h
    assert np.abs(ref[:, 0]).max() > 1e-3                   # mass 1 really moves (mm)
    # the same stick/slip sequence, step by step
    stuck = res.stuck[:, 0]
    changes = np.flatnonzero(stuck[1:] != stuck[:-1]) + 1
    assert len(changes) == len(switches)
    assert np.all(np.ceil(switches / h) == changes)


def test_refining_the_base_step_never_changes_the_event_count():
    # the same motion at h, h/2, h/4 (the held force changes at the same instants): an exact
    # event location finds the same events whatever the step. Parameters are drawn so that the
    # fast mode (1.1 to 3 kHz) is faster than the coarse step and the force peaks (force +
    # amplitude >= 10.3 N) cross the breakaway force (10 N) inside steps.
    rng = np.random.default_rng(11)
    h = 1e-3
    for case in range(6):
        force = rng.uniform(8.0, 9.5)
        kw = dict(f2=rng.uniform(1100.0, 3000.0), force=force,
                  amplitude=rng.uniform(10.3 - force, 3.5), zeta=rng.uniform(0.005, 0.05))
        counts = []
        for r in (1, 2, 4):
            prog, _ = _shaken_mass(h / r, period=r, **kw)
            counts.append(run(prog, 200 * r, LEVELS).events)
        assert counts[0] >= 1, kw
        assert counts == [counts[0]] * 3, (kw, counts)


# -------------------------------------------------------------------- the bounds hold (rigour)

def test_envelopes_bound_the_event_functions_of_every_configuration():
    # against the exact solution sampled densely: |g - chord| <= KU @ |xi| + tau (1 - tau) KP @ |xi|
    # on every level's sub-steps, and the Taylor remainder of degree 2 at either end of a sub-step
    # <= s^3 / 6 K3 @ |xi|; 1e-12 of the function's scale is left for the rounding of the samples
    # themselves
    h = 1e-3
    prog, _ = _shaken_mass(h)
    cont = prog.continuous
    d = [constrained_dynamics(cont, c) for c in (0, 1)]
    PE = np.array([[np.hstack([dc.A, dc.B]) for dc in d]])
    L = np.array([[np.hstack([dc.Lx, dc.Lu, dc.Lf]) for dc in d]])
    PsiT, KU, KP, K3, D, pair = curvature_bounds(PE, L, np.asarray(cont.G)[None], h, LEVELS)
    rng = np.random.default_rng(5)
    nx, nz = 4, 6
    for c in (0, 1):
        r = L[0, c, 0] if c else np.concatenate([cont.G[0], np.zeros(2)])
        M = np.zeros((nz, nz))
        M[:nx] = PE[0, c]
        for _ in range(30):
            z = rng.normal(size=nz) * np.array([1e-3, 1e-3, 1e-2, 1e-2, 5.0, 5.0])
            xi = PsiT[0, c].T @ z
            mag = np.abs(xi)
            for i in np.flatnonzero(pair[0, c]):
                mag[i], mag[i + 1] = np.hypot(xi[i], xi[i + 1]), 0.0
            lev = int(rng.integers(0, LEVELS + 1))
            dl = h / 2 ** lev
            za = scipy.linalg.expm(M * dl * int(rng.integers(0, 2 ** lev))) @ z
            ts = np.linspace(0.0, dl, 201)
            g = np.array([r @ scipy.linalg.expm(M * t) @ za for t in ts])
            tau = ts / dl
            tol = 1e-12 * np.abs(g).max()
            chord = g[0] + (g[-1] - g[0]) * tau
            env = KU[0, c, 0, lev] @ mag + tau * (1 - tau) * (KP[0, c, 0, lev] @ mag)
            assert np.all(np.abs(g - chord) <= env + tol)
            taylor = g[0] + (D[0, c, 0, 0] @ za) * ts + (D[0, c, 0, 1] @ za) * ts ** 2 / 2
            assert np.all(np.abs(g - taylor) <= ts ** 3 / 6 * (K3[0, c, 0] @ mag) + tol)
            # and backwards from the sub-step's end (the kernel's second half of _taylor_clear)
            ze = scipy.linalg.expm(M * dl) @ za
            back = g[-1] - (D[0, c, 0, 0] @ ze) * ts + (D[0, c, 0, 1] @ ze) * ts ** 2 / 2
            assert np.all(np.abs(g[::-1] - back) <= ts ** 3 / 6 * (K3[0, c, 0] @ mag) + tol)


def test_far_from_the_threshold_no_step_is_subdivided():
    # cheap when far: the stuck mass's force swings 9 +- 0.5 N against Fs = 10 N, which the
    # mode's amplitude bound (twice 0.5 N from any chord) proves unreachable at the whole step
    h = 1e-3
    prog, _ = _shaken_mass(h, amplitude=0.5, force=8.0)
    res = run(prog, 100, LEVELS)
    assert res.events == 0 and res.stuck.all()
    disc = discretize(prog.continuous, h, LEVELS)
    x = prog.continuous.x0.copy()
    Phi, Gamma, u = disc.Phi[1, 0], disc.Gamma[1, 0], np.array([8.0, 0.0])
    # the same recursion summed in another order (numba loops against BLAS gemv, FMA or not): a running
    # rounding bound, componentwise: each step adds n·eps of its terms' size |Φ||x| + |Γ||u| and carries
    # the earlier error with |Φ| (the held mass's Jordan block at z = 1 makes κ(V) ~ 1e13 useless here);
    # twice that (both sides round), 4 times for slack
    bound = np.zeros_like(x)
    for k in range(100):                       # the plain ZOH steps in the stuck configuration
        assert np.all(np.abs(res.states[k] - x) <= 8 * bound)
        bound = np.abs(Phi) @ bound + x.size * EPS * (np.abs(Phi) @ np.abs(x) + np.abs(Gamma) @ np.abs(u))
        x = Phi @ x + Gamma @ u


# ------------------------------------------------------------------------------ the 5M4S case

def _there_and_back(d=0.002, v=0.5, a=5.0):
    """+d then back to 0 (triangular velocity profiles, no dwell)."""
    p1 = trapezoid_profile(d, v, a)
    p2 = trapezoid_profile(-d, v, a, p1.end_time)
    return Profile(p1.breaks[:-1] + p2.breaks, p1.positions[:-1] + tuple(d + x for x in p2.positions),
                   p1.velocities[:-1] + p2.velocities, p1.accelerations[:-1] + p2.accelerations)


def _mechanics_reference(cont, x0, u, t_span):
    """The link's motion over ``t_span`` from x0 (stuck) with the held input u: the ODE
    ``ẋ = A x + B u + F f`` integrated by DOP853 (rtol 1e-12), f the holding force while stuck
    (``λ = Lx x + Lu u``, the constraint force of constrained_dynamics) and ``-Fc sign(v)`` while
    sliding, breakaway and v = 0 located by solve_ivp's root finding. Returns the end state and
    the event times."""
    A, B, F, G = (np.asarray(a, dtype=float) for a in (cont.A, cont.B, cont.F, cont.G))
    Fs, Fc = float(cont.static[0]), float(cont.coulomb[0])
    held = constrained_dynamics(cont, 1)
    t, t_end = t_span
    y, stuck, d, events = np.array(x0, dtype=float), True, 0.0, []
    while True:
        if stuck:
            def rhs(_, x):
                lam = held.Lx[0] @ x + held.Lu[0] @ u
                return A @ x + B @ u + F[:, 0] * lam
            ev = lambda _, x: abs(held.Lx[0] @ x + held.Lu[0] @ u) - Fs  # noqa: E731
            ev.direction = 1
        else:
            def rhs(_, x, d=d):
                return A @ x + B @ u - F[:, 0] * Fc * d
            ev = (lambda dd: lambda _, x: dd * (G[0] @ x))(d)
            ev.direction = -1
        ev.terminal = True
        # the oracle's accuracy: rtol 1e-12 (atol 1e-16 for the ~1e-7 m/s sliding velocities), events to ~1e-15 s;
        # the caller's bounds (1e-11 m, 5e-8 m/s) are four orders above
        sol = solve_ivp(rhs, (t, t_end), y, events=[ev], rtol=1e-12, atol=1e-16, method="DOP853")
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            return y, np.array(events)
        events.append(t)
        if stuck:
            lam = held.Lx[0] @ y + held.Lu[0] @ u
            stuck, d = False, -np.sign(lam)           # slides against the holding force
        else:
            y = held.projection @ y
            lam = held.Lx[0] @ y + held.Lu[0] @ u
            stuck = abs(lam) <= Fs
            d = -np.sign(lam)


@pytest.fixture(scope="module")
def static_5m4s():
    machine = sicomat.load_model("examples/paper_5m4s.toml")
    machine = with_overrides(machine, {"axes.X.mechanics.frictions.motor.static": "200 N"})
    prog, _ = loop_program(build_servo_loop(machine), _there_and_back(), 0.14)
    return prog


def test_5m4s_breakaway_inside_a_step_against_the_mechanics(static_5m4s):
    # issue 10: with static = 200 N, the 10.8 kHz mode (period 93 us < the 125 us step) drives
    # the stuck motor link's holding force over 200 N for a few microseconds inside a step and
    # back below at its end
    prog = static_5m4s
    cont = prog.continuous
    h = prog.step
    res = run(prog, int(round(0.14 / h)), LEVELS)
    held = constrained_dynamics(cont, 1)
    u_slot = prog.record.index(cont.input_slots[0])
    Fs = float(cont.static[0])
    # the first step that starts stuck and whose holding force passes Fs inside but not at its
    # end (scanned on 64 points of the exact solution)
    nx = held.A.shape[0]
    M = np.zeros((nx + 2, nx + 2))
    M[:nx, :nx], M[:nx, nx:] = held.A, held.B
    grid = [scipy.linalg.expm(M * h * s) for s in np.linspace(0.0, 1.0, 65)]
    k = None
    for j in range(1, len(res.time)):
        if res.stuck[j, 0]:
            z = np.concatenate([res.states[j], res.records[j, [u_slot]], [0.0]])
            lam = np.array([held.Lx[0] @ (E @ z)[:nx] + held.Lu[0] @ z[nx:nx + 1] for E in grid])
            if np.abs(lam).max() > Fs and abs(lam[-1]) < Fs:
                k = j
                break
    assert k is not None
    u = res.records[k, [u_slot]]
    x0 = res.states[k].copy()
    G = np.asarray(cont.G)[0]
    i, j = np.flatnonzero(G)
    assert G[i] == -G[j]
    x0[j] = x0[i]                      # exactly zero sliding velocity: the link starts stuck
    x_end, events = _mechanics_reference(cont, x0, u, (0.0, h))
    assert len(events) == 1            # the breakaway; the link then slides to the step's end
    # the same step alone, from the same state with the same held input
    one = p.ContinuousPart(A=cont.A, B=cont.B, C=np.zeros((0, nx)), D=np.zeros((0, 1)), F=cont.F,
                           G=cont.G, coulomb=cont.coulomb, static=cont.static, x0=x0,
                           input_slots=(0,), output_slots=())
    step = p.HybridProgram(step=h, slot_names=("u",), continuous=one,
                           ops=(p.Setpoint(column=0, output=0),), table=np.array([u]))
    n = nx // 2                        # positions, then velocities, then the drive's current
    # error analysis: the breakaway is taken at the first point of the grid h / 2**levels past
    # the crossing (0.12 us at 10 levels, 7.6 ns at 14); meanwhile the link is held with at most
    # Fs - Fc ~ 60 N more than sliding gives, on a reduced mass of ~140 kg (0.43 m/s²): a relative
    # velocity error of 5e-8 m/s at 10 levels, 3.3e-9 m/s at 14, i.e. positions within
    # 5e-8 m/s * 125 us ~ 1e-11 m by the step's end. After the breakaway the oracle's sliding
    # velocity stays between 5e-8 and 1.2e-7 m/s: at 10 levels the late breakaway may make the
    # kernel's velocity touch 0 (a re-stick, within the same error bounds); at 14 levels it
    # cannot. The oracle's own error (rtol 1e-12 on ~2 mm and on the velocities, atol 1e-16) is
    # far below these.
    for levels, dv in ((LEVELS, 5e-8), (14, 3.3e-9)):
        alone = run(step, 1, levels)
        assert np.abs(alone.final_state[:n] - x_end[:n]).max() < 1e-10
        assert np.abs(alone.final_state[n:2 * n] - x_end[n:2 * n]).max() < 3 * dv
    assert run(step, 1, 14).events == 1
    # inside the closed loop too, the step holds the event (an end-of-step test finds none)
    assert run(prog, k + 1, LEVELS).events > run(prog, k, LEVELS).events


def test_the_envelope_tests_never_clear_a_crossing():
    # the two closed-form tests of the kernel against dense sampling of their own polynomials:
    # a chord minus its envelope (U + C tau (1 - tau)), and the degree-2 Taylor polynomial minus
    # M3 s^3 / 6; a "clear" answer must mean the polynomial stays positive (zero coefficients,
    # touching ends and vertices at the ends included by the draws)
    from sicomat.simulation.kernel import _cubic_positive, _may_cross

    rng = np.random.default_rng(2)
    tau = np.linspace(0.0, 1.0, 2001)
    for _ in range(5000):
        a, b = np.abs(rng.normal(size=2)) * rng.choice([0.0, 1.0], size=2)
        U, C = np.abs(rng.normal(size=2)) * rng.choice([0.0, 0.1, 3.0], size=2)
        p_min = (a + (b - a) * tau - U - C * tau * (1 - tau)).min()
        if not _may_cross(a, b, U, C):
            # the dense evaluation rounds by a few eps of its terms' size: 1e-12 of it
            assert p_min >= -1e-12 * (a + b + U + C)
        f0 = abs(rng.normal()) * rng.choice([0.0, 1.0])
        f1, f2 = rng.normal(size=2) * rng.choice([0.0, 1.0, 10.0], size=2)
        M3 = abs(rng.normal()) * rng.choice([0.0, 1.0, 10.0])
        dt = abs(rng.normal()) + 1e-3
        s = tau[1:] * dt
        if _cubic_positive(f0, f1, f2, M3, dt):
            # the same: 1e-12 of the terms' size (up to ~300 for M3 = 40, dt = 4.7)
            size = f0 + abs(f1) * dt + abs(f2) * dt ** 2 / 2 + M3 * dt ** 3 / 6
            assert (f0 + f1 * s + f2 * s ** 2 / 2 - M3 * s ** 3 / 6).min() >= -1e-12 * size


# -------------------------------------------------- the compiled decomposition = the reference one

def _decomposition_cases():
    """Continuous parts of every kind the decomposition meets: the shaken mass (fast pair, slow
    block), the 5M4S in both stick configurations (a slow block of six, two fast pairs, a real mode),
    a matrix of slow eigenvalues only, and one with a cluster of fast eigenvalues (general
    block)."""
    h = 1e-3
    prog, _ = _shaken_mass(h)
    cases = [(constrained_dynamics(prog.continuous, c).A, h) for c in (0, 1)]
    machine = sicomat.load_model("examples/paper_5m4s.toml")
    prog5, _ = loop_program(build_servo_loop(machine), trapezoid_profile(0.001, 0.1, 1.0), 0.01)
    cases += [(constrained_dynamics(prog5.continuous, c).A, prog5.step) for c in (0, 1)]
    cases.append((np.array([[0.0, 1.0], [0.0, 0.0]]), h))                 # slow only
    w = 2 * np.pi * 3000.0
    rot = np.array([[-1.0, w], [-w, -1.0]])
    cases.append((scipy.linalg.block_diag(rot, rot * (1 + 1e-6)), h))      # clustered pair
    return cases


@pytest.mark.parametrize("case", range(6))
def test_compiled_decomposition_matches_the_reference(case):
    # the compiled path (LAPACK called directly, the modal basis and S, Y assembled by numba)
    # must give the reference path's blocks and, within rounding, its S and Y: both evaluate the
    # same formulas on the same Schur and eigenvector factors, so they differ only in the
    # summation order of products of size n and in the solve for Y, i.e. by at most
    # ~n * eps * cond(S) relative to the norms (10x that is left for the Sylvester solve)
    from sicomat.simulation.envelope import _KINDS, _decompose, _decompose_arrays

    A, h = _decomposition_cases()[case]
    S_ref, Y_ref, blocks = _decompose(A, h)
    S, Y, bstart, bsize, bkind = _decompose_arrays(A, h)
    assert [(int(a), int(b), int(c)) for a, b, c in zip(bstart, bsize, bkind)] == \
        [(st, sz, _KINDS[kind]) for st, sz, kind in blocks]
    n = A.shape[0]
    cond = np.abs(S_ref).sum(axis=0).max() * np.abs(Y_ref).sum(axis=0).max()
    tol = 10 * n * np.finfo(float).eps * cond
    assert np.abs(S - S_ref).max() <= tol * np.abs(S_ref).max()
    assert np.abs(Y - Y_ref).max() <= tol * np.abs(Y_ref).max()


def test_the_reference_decomposition_does_not_recurse_on_non_finite_input():
    # the compiled path hands non-finite matrices to the reference one, which must decide by itself
    # (scipy's own check), not hand them back (a RecursionError before)
    from sicomat.simulation.envelope import _decompose_arrays

    with pytest.raises(ValueError, match="infs or NaNs"):
        _decompose_arrays(np.array([[0.0, 1.0], [np.nan, 0.0]]), 1e-3)
