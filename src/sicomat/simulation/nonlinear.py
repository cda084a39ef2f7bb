"""Large motions of a robot machine: the coupled servo loops on the robot's nonlinear dynamics.

The linear simulation (:mod:`sicomat.simulation.kernel`) advances ``M0 q̈ + D q̇ + K q = E i + W f``
exactly between samples with ``M0 = A(q0)``, the inertia matrix at the configuration the machine is
linearised about. Over a large motion the inertia matrix changes with the configuration and the
Coriolis and centrifugal forces appear. This engine runs the **same hybrid program** (the coupled
program of :func:`sicomat.servo.coupled.coupled_program`: the same discrete ops, compiled once, and the
same drives, sensors and friction links) but advances the mechanics by

    ``A(q0 + δq) δq̈ + c(q0 + δq, q̇) = M0 (A_lin z + B u)_q̈ + W f``

where ``z = (δq, q̇, i)`` is the program's continuous state and ``M0 (A_lin z + B u)_q̈`` the linear
model's generalised forces (springs, viscous friction, the drives' efforts: exact, they are linear in the
joint coordinates); ``c`` the Newton–Euler torques at zero acceleration without gravity and friction
(Coriolis and centrifugal). Gravity stays compensated, as in the linear model every axis is tuned on
(``docs/robotics.md``). At ``δq = 0, q̇ = 0`` the two right-hand sides agree.

Integration: classical Runge–Kutta (RK4) on ``n_sub`` equal sub-steps of each base step, the held input
constant over the step, ``n_sub`` chosen so that ``ρ h / n_sub <= STEP_SCALE`` with ``ρ`` the spectral
radius of the linear continuous part (RK4's local error on a mode ``λ`` is ``(λh)^5 / 120``: 1e-7 of
the state at the bound). Coulomb friction: a link slides with ``f = -coulomb · sign(v)`` or sticks
(its constraint force, from the constrained dynamics, holds ``v = 0``); a sliding link whose velocity
reverses over a sub-step is projected onto ``v = 0`` (the momentum-consistent projection) and sticks if
its holding force is within ``static``, else slides against it; a stuck link breaks away when its holding
force exceeds ``static``. Events are located to the sub-step, where the linear kernel bisects to
``h / 2**levels``.

Timing of a base step as in the kernel (:mod:`sicomat.servo.program`): outputs, ops, latch, records,
advance. The result is a :class:`~sicomat.simulation.kernel.KernelResult`, read back like a linear run.
"""

from __future__ import annotations

import math
import numpy as np
from numba import njit

from ..errors import ModelError
from ..robotics.path_model import RigidBodyDynamics
from ..robotics._kernels import _crba_one, _local, flat_arrays, mass_and_bias
from ..servo.program import HybridProgram
from .kernel import (DIVERGENCE_WARMUP, KernelResult, _check_run_args, _divergence_args, _diverged,
                     _divergence_limit, _ops_state, _run_ops)
from .lowering import lower

__all__ = ["run_nonlinear", "substeps", "STEP_SCALE"]

STEP_SCALE = 0.1
"""The largest ``ρ h_sub`` of the RK4 sub-steps (``ρ`` the spectral radius of the linear part): a local
error ``(0.1)^5 / 120 ≈ 1e-7`` relative on the fastest mode, far less on the mechanical ones."""

_OK, _DIVERGED_STATE, _DIVERGED_RECORD = 0, 1, 2


def substeps(A: np.ndarray, step: float) -> int:
    """The RK4 sub-steps per base step: ``ceil(ρ h / STEP_SCALE)``, ``ρ`` the spectral radius of ``A``."""
    rho = float(np.max(np.abs(np.linalg.eigvals(A)), initial=0.0)) if A.size else 0.0
    return max(1, int(math.ceil(rho * step / STEP_SCALE)))


@njit(cache=True, error_model="numpy", inline="always")
def _cholesky(A, L, n):
    """``L`` (lower) with ``L Lᵀ = A[:n, :n]`` (A symmetric positive definite; small: no pivoting needed)."""
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d


@njit(cache=True, error_model="numpy", inline="always")
def _solve(L, b, n):
    """``b <- (L Lᵀ)⁻¹ b`` in place."""
    for i in range(n):
        t = b[i]
        for k in range(i):
            t -= L[i, k] * b[k]
        b[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):
        t = b[i]
        for k in range(i + 1, n):
            t -= L[k, i] * b[k]
        b[i] = t / L[i, i]


@njit(cache=True, error_model="numpy")
def _constrained(L, x, W, stuck, Y, S, LS, lam, hold, n, project):
    """``x <- x + M⁻¹ W_sᵀ λ`` with ``λ = -(W_s M⁻¹ W_sᵀ)⁻¹ W_s x``, so that ``W_s x = 0`` for the stuck
    links' constraint rows ``W_s`` (``L`` the Cholesky factor of M): ``x`` an acceleration, ``λ`` the
    constraint forces (written into ``hold`` unless ``project``), or ``x`` a velocity (``project``), the
    M-orthogonal projection: the constraint impulse."""
    nf = W.shape[0]
    m = 0
    for j in range(nf):
        if stuck[j]:
            for i in range(n):
                Y[m, i] = W[j, i]
            _solve(L, Y[m], n)                      # row m: M⁻¹ w_j
            m += 1
    if m == 0:
        return
    a = 0
    for j in range(nf):
        if stuck[j]:
            b = 0
            for jj in range(nf):
                if stuck[jj]:
                    t = 0.0
                    for i in range(n):
                        t += W[j, i] * Y[b, i]
                    S[a, b] = t
                    b += 1
            t = 0.0
            for i in range(n):
                t += W[j, i] * x[i]
            lam[a] = -t
            a += 1
    _cholesky(S, LS, m)
    _solve(LS, lam, m)
    for b in range(m):
        for i in range(n):
            x[i] += Y[b, i] * lam[b]
    if not project:
        a = 0
        for j in range(nf):
            if stuck[j]:
                hold[j] = lam[a]
                a += 1


@njit(cache=True, error_model="numpy")
def _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
         rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, out, L, Y, S, LS, lam, acc):
    """``out = ż`` at ``z`` with the held input ``u``, the sliding links' forces ``f``; the stuck links'
    constraint forces into ``hold``."""
    nx = z.shape[0]
    nu = u.shape[0]
    for i in range(2 * n, nx):
        s = 0.0
        for j in range(nx):
            s += Ax[i, j] * z[j]
        for j in range(nu):
            s += Bx[i, j] * u[j]
        out[i] = s
    for i in range(n):
        qa[i] = q0[i] + z[i]
    mass_and_bias(ints, geo, chi, grav, qa, z[n:2 * n], zeros, mass, bias, rot, pos, w, wd, vd, fa, na,
                  jp, msp, mp)
    for i in range(n):
        s = -bias[i]
        for j in range(nx):
            s += Kq[i, j] * z[j]
        for j in range(nu):
            s += Bq[i, j] * u[j]
        acc[i] = s
    nf = W.shape[0]
    for j in range(nf):
        if not stuck[j]:
            for i in range(n):
                acc[i] += W[j, i] * f[j]
    _cholesky(mass, L, n)
    _solve(L, acc, n)
    _constrained(L, acc, W, stuck, Y, S, LS, lam, hold, n, False)
    for i in range(n):
        out[i] = z[n + i]
        out[n + i] = acc[i]


@njit(cache=True, error_model="numpy")
def _project(z, stuck, W, n, q0, ints, geo, chi, mass, rot, pos, jp, msp, mp, qa, L, Y, S, LS, lam, hold):
    """Project the velocities onto the stuck links' constraints ``W_s q̇ = 0``, M-orthogonally (the
    impulse of the constraint forces: momentum-consistent)."""
    for i in range(n):
        qa[i] = q0[i] + z[i]
    _local(ints, geo, qa, rot, pos)
    mass[:, :] = 0.0
    _crba_one(ints, chi, rot, pos, mass, jp, msp, mp)
    _cholesky(mass, L, n)
    _constrained(L, z[n:2 * n], W, stuck, Y, S, LS, lam, hold, n, True)


@njit(cache=True, error_model="numpy")
def _break_away(stuck, dirn, f, hold, coulomb, static):
    """Stuck links whose holding force exceeds ``static`` slide against it; True if any did."""
    changed = False
    for j in range(stuck.shape[0]):
        if stuck[j] and abs(hold[j]) > static[j]:
            stuck[j] = False
            dirn[j] = -1.0 if hold[j] > 0.0 else 1.0
            f[j] = -coulomb[j] * dirn[j]
            changed = True
    return changed


@njit(cache=True, error_model="numpy")
def _simulate_nonlinear(n_steps, n_sub, limit_abs, limit_factor, warmup,
                        op_code, op_period, op_phase, op_ip, op_fp, idx, fdata, xb0, table, n_delay,
                        in_slots, out_slots, fr_slots, rec_slots, n_slots, CD,
                        Ax, Bx, Kq, Bq, W, coulomb, static, x0, q0, ints, geo, chi, grav, step,
                        rec_out, states_out, fric_out, stuck_out, x_final):
    """Run ``n_steps`` base steps (see the module); returns ``(status, step)``, status 0: completed."""
    nx = x0.shape[0]
    nu = in_slots.shape[0]
    ny = out_slots.shape[0]
    nf = coulomb.shape[0]
    n = q0.shape[0]
    n_rec = rec_slots.shape[0]
    nframes = ints.shape[0]

    slots = np.zeros(n_slots)
    xb = xb0.copy()
    count, wait, tb, delay_buf = _ops_state(op_code, op_period, op_phase, op_ip, n_delay)

    # work arrays of the robot's recursions
    zeros = np.zeros(n)
    mass = np.zeros((n, n))
    bias = np.zeros(n)
    rot = np.empty((nframes, 3, 3))
    pos = np.empty((nframes, 3))
    w = np.empty((nframes + 1, 3))
    wd = np.empty((nframes + 1, 3))
    vd = np.empty((nframes + 1, 3))
    fa = np.empty((nframes, 3))
    na = np.empty((nframes, 3))
    jp = np.empty((nframes, 3, 3))
    msp = np.empty((nframes, 3))
    mp = np.empty(nframes)
    qa = np.empty(n)
    L = np.zeros((n, n))
    acc = np.empty(n)
    nfc = max(coulomb.shape[0], 1)
    Y = np.empty((nfc, n))
    S = np.empty((nfc, nfc))
    LS = np.zeros((nfc, nfc))
    lam = np.empty(nfc)

    z = x0.copy()
    u = np.zeros(nu)
    f = np.zeros(nf)
    hold = np.zeros(nf)
    stuck = np.zeros(nf, dtype=np.bool_)
    dirn = np.ones(nf)
    k1 = np.zeros(nx)
    k2 = np.zeros(nx)
    k3 = np.zeros(nx)
    k4 = np.zeros(nx)
    zs = np.zeros(nx)
    for j in range(nf):
        v = 0.0
        for i in range(n):
            v += W[j, i] * z[n + i]
        if v == 0.0:
            stuck[j] = True
        else:
            dirn[j] = 1.0 if v > 0.0 else -1.0
            f[j] = -coulomb[j] * dirn[j]
    if np.any(stuck):
        _project(z, stuck, W, n, q0, ints, geo, chi, mass, rot, pos, jp, msp, mp, qa, L, Y, S, LS, lam, hold)

    hs = step / n_sub
    limit = limit_abs if limit_abs > 0.0 else np.inf
    scale = 0.0
    for i in range(nx):
        scale = max(scale, abs(z[i]))
    for k in range(n_steps):
        # (1) continuous outputs with the held input; acting friction forces
        for r in range(ny):
            s = 0.0
            for i in range(nx):
                s += CD[r, i] * z[i]
            for i in range(nu):
                s += CD[r, nx + i] * u[i]
            slots[out_slots[r]] = s
        if fr_slots.shape[0] > 0:
            if np.any(stuck):
                _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                     rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k1, L, Y, S, LS, lam, acc)
            for j in range(nf):
                if fr_slots[j] >= 0:
                    slots[fr_slots[j]] = hold[j] if stuck[j] else f[j]

        # (2) the ops due at k
        _run_ops(op_code, op_period, op_ip, op_fp, idx, fdata, table, slots, xb, tb, delay_buf, count, wait)

        # (3) latch the held input; a stuck link may break away at once
        for i in range(nu):
            u[i] = slots[in_slots[i]]
        _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
             rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k1, L, Y, S, LS, lam, acc)
        if _break_away(stuck, dirn, f, hold, coulomb, static):
            _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                 rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k1, L, Y, S, LS, lam, acc)

        # (4) records
        bad = False
        for i in range(n_rec):
            v = slots[rec_slots[i]]
            rec_out[k, i] = v
            bad |= v != v
        for i in range(nx):
            states_out[k, i] = z[i]
        for j in range(nf):
            fric_out[k, j] = hold[j] if stuck[j] else f[j]
            stuck_out[k, j] = stuck[j]
        if bad:
            return _DIVERGED_RECORD, k

        # (5) advance to t_{k+1}: n_sub RK4 sub-steps, the stick/slip state fixed over each
        for sub in range(n_sub):
            if sub > 0:
                _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                     rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k1, L, Y, S, LS, lam, acc)
                if _break_away(stuck, dirn, f, hold, coulomb, static):
                    _rhs(z, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass,
                         bias, rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k1, L, Y, S, LS, lam, acc)
            for i in range(nx):
                zs[i] = z[i] + 0.5 * hs * k1[i]
            _rhs(zs, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                 rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k2, L, Y, S, LS, lam, acc)
            for i in range(nx):
                zs[i] = z[i] + 0.5 * hs * k2[i]
            _rhs(zs, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                 rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k3, L, Y, S, LS, lam, acc)
            for i in range(nx):
                zs[i] = z[i] + hs * k3[i]
            _rhs(zs, u, f, stuck, Ax, Bx, Kq, Bq, W, n, q0, ints, geo, chi, grav, zeros, mass, bias,
                 rot, pos, w, wd, vd, fa, na, jp, msp, mp, qa, hold, k4, L, Y, S, LS, lam, acc)
            for i in range(nx):
                z[i] += hs / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            # a sliding link whose velocity reversed (or reached zero) sticks
            reversed_ = False
            for j in range(nf):
                if not stuck[j]:
                    v = 0.0
                    for i in range(n):
                        v += W[j, i] * z[n + i]
                    if dirn[j] * v <= 0.0:
                        stuck[j] = True
                        reversed_ = True
            if reversed_:
                _project(z, stuck, W, n, q0, ints, geo, chi, mass, rot, pos, jp, msp, mp, qa, L, Y, S, LS, lam, hold)

        # divergence
        bad, limit, scale = _divergence_limit(z, nx, k, warmup, limit, limit_abs, limit_factor, scale)
        if bad:
            return _DIVERGED_STATE, k
    for i in range(nx):
        x_final[i] = z[i]
    return _OK, -1


def run_nonlinear(program: HybridProgram, n_steps: int, dynamics: RigidBodyDynamics, *,
                  divergence_limit: float | None = None) -> KernelResult:
    """Simulate ``program`` for ``n_steps`` base steps with the robot's nonlinear dynamics (the module).

    ``program``'s continuous part must be the coupled program's: states ``(δq, q̇, ...)`` over every
    joint of ``dynamics`` in frame order, ``δq̇ = q̇``, the friction links acting on ``q̇`` only.

    Raises
    ------
    ModelError
        The program does not fit the robot (state layout, friction links).
    SimulationDiverged
        The state diverged.
    """
    _check_run_args(n_steps, 1, 1)
    n_steps = int(n_steps)
    low = lower(program)
    s, m = low.struct, low.nums
    cont = program.continuous
    A = np.asarray(cont.A, dtype=float)
    B = np.asarray(cont.B, dtype=float).reshape(A.shape[0], -1)
    nx = A.shape[0]
    q0 = np.asarray(dynamics.q0, dtype=float)
    n = q0.size
    M0 = np.asarray(dynamics.mass0, dtype=float)
    _check_layout(A, B, np.asarray(cont.F, dtype=float).reshape(nx, -1), m["G"], low.links, M0, n)
    robot = dynamics.robot
    ints, geo, chi = flat_arrays(robot)
    chi = np.array(chi)
    chi[:, 11:13] = 0.0                        # friction: the program's links and viscous terms have it
    Kq = np.ascontiguousarray(M0 @ A[n:2 * n])
    Bq = np.ascontiguousarray(M0 @ B[n:2 * n])
    W = np.ascontiguousarray(m["G"][:, n:2 * n])
    n_sub = substeps(A, float(program.step))
    nf = low.links.size
    rec = np.empty((n_steps, s["rec_slots"].size))
    states = np.empty((n_steps, nx))
    fric = np.empty((n_steps, nf))
    stuck = np.empty((n_steps, nf), dtype=np.bool_)
    x_final = np.zeros(nx)
    limit_abs, factor = _divergence_args(divergence_limit)
    status, k_bad = _simulate_nonlinear(
        n_steps, n_sub, limit_abs, factor, DIVERGENCE_WARMUP,
        s["op_code"], s["op_period"], s["op_phase"], s["op_ip"], m["op_fp"], s["idx"], m["fdata"],
        m["xb0"], m["table"], int(s["shapes"][5]), s["in_slots"], s["out_slots"], s["fr_slots"],
        s["rec_slots"], int(program.n_slots), np.ascontiguousarray(m["CD"]), np.ascontiguousarray(A),
        np.ascontiguousarray(B), Kq, Bq, W, m["coulomb"], m["static"], m["x0"], q0, ints, geo, chi,
        np.zeros(3), float(program.step), rec, states, fric, stuck, x_final)
    if status != _OK:
        raise _diverged(int(status), int(k_bad), program.step, None)
    friction = np.zeros((n_steps, low.n_links))
    stuck_all = np.zeros((n_steps, low.n_links), dtype=bool)
    friction[:, low.links] = fric
    stuck_all[:, low.links] = stuck
    names = tuple(program.slot_names[i] for i in s["rec_slots"])
    return KernelResult(time=np.arange(n_steps) * program.step, records=rec, record_names=names, states=states,
                        friction=friction, stuck=stuck_all, final_state=x_final, events=0)


def _check_layout(A: np.ndarray, B: np.ndarray, F: np.ndarray, G: np.ndarray, links: np.ndarray,
                  M0: np.ndarray, n: int) -> None:
    """The continuous part is ``(δq, q̇, rest)`` with ``δq̇ = q̇`` and friction acting on ``q̇`` through
    ``M0⁻¹ Wᵀ`` (the coupled program of this robot); else a ModelError."""
    nx = A.shape[0]
    what = "the program's continuous part is not the coupled mechanics of this robot"
    if nx < 2 * n or M0.shape != (n, n):
        raise ModelError(f"{what}: {nx} states for {n} joints", path="program.continuous")
    eye = np.zeros((n, nx))
    eye[:, n:2 * n] = np.eye(n)
    if not (np.array_equal(A[:n], eye) and not np.any(B[:n])):
        raise ModelError(f"{what}: its first {n} states are not positions whose rates are the next {n}",
                         path="program.continuous.A")
    Fa = F[:, links]
    W = G[:, n:2 * n]
    # the force enters as M0^-1 w_j: rounding of the mass factor's solve, ~eps cond(M0) relative
    scale = max(float(np.max(np.abs(W), initial=0.0)), 1e-300)
    if (np.any(G[:, :n]) or np.any(G[:, 2 * n:]) or np.any(Fa[:n]) or np.any(Fa[2 * n:])
            or np.max(np.abs(M0 @ Fa[n:2 * n] - W.T), initial=0.0) > 1e-8 * scale):
        raise ModelError(f"{what}: a friction link acts on other states than the joint velocities",
                         path="program.continuous.F")
