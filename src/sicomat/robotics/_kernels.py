"""Compiled (numba) recursions of :mod:`sicomat.robotics.dynamics`: Newton–Euler inverse dynamics
(one state, or a batch with the loop over states inside the compiled code) and the inertia matrix by
composite links.

The robot enters as three flat arrays prepared once per robot by :func:`flat_arrays` (cached on the
robot; :class:`~sicomat.robotics.MDHRobot` is frozen):

- ``ints`` (NF, 3) int64: antecedent frame number (0 = base), sigma, index of the joint variable (-1
  for a fixed frame);
- ``geo`` (NF, 14) float: ``C = Rz(gamma) Rx(alpha)`` row-major (9), ``p0 = [0, 0, b] + C [d, 0, 0]``
  (3), ``theta``, ``r`` (the constant parts);
- ``chi`` (NF, 13): the standard parameters ``XX XY XZ YY YZ ZZ MX MY MZ M IA FV FS``.

Per frame, ``R = C Rz(theta + sigmabar q)`` and ``p = p0 + C[:, 2] (r + sigma q)``. The kernels check
that the joint values are finite and return False otherwise (the caller raises): the check costs
nothing here, ``np.isfinite`` on the Python side cost about a microsecond a call.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["flat_arrays", "rnea", "rnea_batch", "crba", "crba_batch"]

_CACHE_KEY = "_kernel_arrays"


def flat_arrays(robot: "MDHRobot") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ints, geo, chi)`` of the robot (see the module), built on first use and kept on the robot."""
    cached = robot.__dict__.get(_CACHE_KEY)
    if cached is not None:
        return cached
    nf = robot.n_frames
    ints = np.empty((nf, 3), dtype=np.int64)
    ints[:, 0] = robot.ant
    ints[:, 1] = robot.sigma
    ints[:, 2] = robot.joint_of_frame
    cg, sg = np.cos(robot.gamma), np.sin(robot.gamma)
    ca, sa = np.cos(robot.alpha), np.sin(robot.alpha)
    geo = np.empty((nf, 14))
    for row in range(nf):
        rz = np.array([[cg[row], -sg[row], 0.0], [sg[row], cg[row], 0.0], [0.0, 0.0, 1.0]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, ca[row], -sa[row]], [0.0, sa[row], ca[row]]])
        c = rz @ rx
        p0 = c[:, 0] * robot.d[row] + np.array([0.0, 0.0, robot.b[row]])
        geo[row, :9] = c.reshape(-1)
        geo[row, 9:12] = p0
        geo[row, 12] = robot.theta[row]
        geo[row, 13] = robot.r[row]
    out = (ints, geo, np.ascontiguousarray(robot.chi, dtype=float))
    for array in out:
        array.setflags(write=False)
    robot.__dict__[_CACHE_KEY] = out      # frozen dataclass: its __dict__ is the cache (as cached_property does)
    return out


@njit(cache=True, inline="always")
def _local(ints, geo, q, rot, pos):
    """``a(j)R_j`` (NF, 3, 3) and ``a(j)P_j`` (NF, 3) into ``rot``, ``pos``."""
    for row in range(ints.shape[0]):
        sigma = ints[row, 1]
        joint = ints[row, 2]
        th = geo[row, 12]
        r = geo[row, 13]
        if sigma == 0:
            th += q[joint]
        elif sigma == 1:
            r += q[joint]
        ct = np.cos(th)
        st = np.sin(th)
        for i in range(3):
            c0 = geo[row, 3 * i]
            c1 = geo[row, 3 * i + 1]
            c2 = geo[row, 3 * i + 2]
            rot[row, i, 0] = c0 * ct + c1 * st
            rot[row, i, 1] = c1 * ct - c0 * st
            rot[row, i, 2] = c2
            pos[row, i] = geo[row, 9 + i] + c2 * r


@njit(cache=True, inline="always")
def _rnea_one(ints, geo, chi, gravity, q, qd, qdd, tau, rot, pos, w, wd, vd, f, n):
    """Torques of one state into ``tau`` (rotor inertia and friction included). Work arrays: rot
    (NF, 3, 3), pos (NF, 3), w, wd, vd (NF+1, 3) with row 0 the base, f, n (NF, 3)."""
    nf = ints.shape[0]
    _local(ints, geo, q, rot, pos)
    for i in range(3):
        w[0, i] = 0.0
        wd[0, i] = 0.0
        vd[0, i] = -gravity[i]
    for row in range(nf):
        a = ints[row, 0]
        sigma = ints[row, 1]
        joint = ints[row, 2]
        p0, p1, p2 = pos[row, 0], pos[row, 1], pos[row, 2]
        wa0, wa1, wa2 = w[a, 0], w[a, 1], w[a, 2]
        da0, da1, da2 = wd[a, 0], wd[a, 1], wd[a, 2]
        # acceleration of O_j in frame a(j): vd_a + wd_a x p + w_a x (w_a x p)
        u0 = wa1 * p2 - wa2 * p1
        u1 = wa2 * p0 - wa0 * p2
        u2 = wa0 * p1 - wa1 * p0
        acc0 = vd[a, 0] + da1 * p2 - da2 * p1 + wa1 * u2 - wa2 * u1
        acc1 = vd[a, 1] + da2 * p0 - da0 * p2 + wa2 * u0 - wa0 * u2
        acc2 = vd[a, 2] + da0 * p1 - da1 * p0 + wa0 * u1 - wa1 * u0
        j = row + 1
        for i in range(3):     # R^T x: the columns of R dotted with x
            w[j, i] = rot[row, 0, i] * wa0 + rot[row, 1, i] * wa1 + rot[row, 2, i] * wa2
            wd[j, i] = rot[row, 0, i] * da0 + rot[row, 1, i] * da1 + rot[row, 2, i] * da2
            vd[j, i] = rot[row, 0, i] * acc0 + rot[row, 1, i] * acc1 + rot[row, 2, i] * acc2
        if sigma == 0:
            v = qd[joint]
            # wi x (v ez) = (wi1 v, -wi0 v, 0), wi before adding v ez
            wd[j, 0] += w[j, 1] * v
            wd[j, 1] -= w[j, 0] * v
            wd[j, 2] += qdd[joint]
            w[j, 2] += v
        elif sigma == 1:
            v = qd[joint]
            vd[j, 0] += 2.0 * w[j, 1] * v
            vd[j, 1] -= 2.0 * w[j, 0] * v
            vd[j, 2] += qdd[joint]
    for row in range(nf):
        for i in range(3):
            f[row, i] = 0.0
            n[row, i] = 0.0
    for row in range(nf - 1, -1, -1):
        j = row + 1
        xx, xy, xz, yy, yz, zz = chi[row, 0], chi[row, 1], chi[row, 2], chi[row, 3], chi[row, 4], chi[row, 5]
        mx, my, mz, m = chi[row, 6], chi[row, 7], chi[row, 8], chi[row, 9]
        w0, w1, w2 = w[j, 0], w[j, 1], w[j, 2]
        d0, d1, d2 = wd[j, 0], wd[j, 1], wd[j, 2]
        a0, a1, a2 = vd[j, 0], vd[j, 1], vd[j, 2]
        # F = M vd + wd x MS + w x (w x MS)
        u0 = w1 * mz - w2 * my
        u1 = w2 * mx - w0 * mz
        u2 = w0 * my - w1 * mx
        f0 = f[row, 0] + m * a0 + d1 * mz - d2 * my + w1 * u2 - w2 * u1
        f1 = f[row, 1] + m * a1 + d2 * mx - d0 * mz + w2 * u0 - w0 * u2
        f2 = f[row, 2] + m * a2 + d0 * my - d1 * mx + w0 * u1 - w1 * u0
        # N = J wd + w x (J w) + MS x vd
        jw0 = xx * w0 + xy * w1 + xz * w2
        jw1 = xy * w0 + yy * w1 + yz * w2
        jw2 = xz * w0 + yz * w1 + zz * w2
        n0 = n[row, 0] + xx * d0 + xy * d1 + xz * d2 + w1 * jw2 - w2 * jw1 + my * a2 - mz * a1
        n1 = n[row, 1] + xy * d0 + yy * d1 + yz * d2 + w2 * jw0 - w0 * jw2 + mz * a0 - mx * a2
        n2 = n[row, 2] + xz * d0 + yz * d1 + zz * d2 + w0 * jw1 - w1 * jw0 + mx * a1 - my * a0
        sigma = ints[row, 1]
        joint = ints[row, 2]
        if joint >= 0:
            v = qd[joint]
            extra = chi[row, 10] * qdd[joint] + chi[row, 11] * v + chi[row, 12] * np.sign(v)
            tau[joint] = (f2 if sigma == 1 else n2) + extra
        a = ints[row, 0]
        if a > 0:
            k = a - 1
            fr0 = rot[row, 0, 0] * f0 + rot[row, 0, 1] * f1 + rot[row, 0, 2] * f2
            fr1 = rot[row, 1, 0] * f0 + rot[row, 1, 1] * f1 + rot[row, 1, 2] * f2
            fr2 = rot[row, 2, 0] * f0 + rot[row, 2, 1] * f1 + rot[row, 2, 2] * f2
            p0, p1, p2 = pos[row, 0], pos[row, 1], pos[row, 2]
            f[k, 0] += fr0
            f[k, 1] += fr1
            f[k, 2] += fr2
            n[k, 0] += rot[row, 0, 0] * n0 + rot[row, 0, 1] * n1 + rot[row, 0, 2] * n2 + p1 * fr2 - p2 * fr1
            n[k, 1] += rot[row, 1, 0] * n0 + rot[row, 1, 1] * n1 + rot[row, 1, 2] * n2 + p2 * fr0 - p0 * fr2
            n[k, 2] += rot[row, 2, 0] * n0 + rot[row, 2, 1] * n1 + rot[row, 2, 2] * n2 + p0 * fr1 - p1 * fr0


@njit(cache=True, inline="always")
def _finite(x):
    for i in range(x.shape[0]):
        if not np.isfinite(x[i]):
            return False
    return True


@njit(cache=True)
def rnea(ints, geo, chi, gravity, q, qd, qdd, tau):
    """One state: ``tau`` (n,) filled; False (tau untouched) if a joint value is not finite. The batch
    kernel on one-row views (contiguous: no copy)."""
    n = q.shape[0]
    return rnea_batch(ints, geo, chi, gravity, q.reshape(1, n), qd.reshape(1, n), qdd.reshape(1, n),
                      tau.reshape(1, n))


@njit(cache=True)
def rnea_batch(ints, geo, chi, gravity, q, qd, qdd, tau):
    """Many states, (S, n) each: ``tau`` filled; False if a joint value is not finite."""
    for s in range(q.shape[0]):
        if not (_finite(q[s]) and _finite(qd[s]) and _finite(qdd[s])):
            return False
    nf = ints.shape[0]
    rot = np.empty((nf, 3, 3))
    pos = np.empty((nf, 3))
    w = np.empty((nf + 1, 3))
    wd = np.empty((nf + 1, 3))
    vd = np.empty((nf + 1, 3))
    f = np.empty((nf, 3))
    n = np.empty((nf, 3))
    for s in range(q.shape[0]):
        _rnea_one(ints, geo, chi, gravity, q[s], qd[s], qdd[s], tau[s], rot, pos, w, wd, vd, f, n)
    return True


@njit(cache=True, inline="always")
def _crba_one(ints, chi, rot, pos, out, jp, msp, mp):
    """Inertia matrix into ``out`` (n, n) from the local transforms. Work: jp (NF, 3, 3), msp (NF, 3),
    mp (NF,)."""
    nf = ints.shape[0]
    for row in range(nf):
        c = chi[row]
        jp[row, 0, 0] = c[0]
        jp[row, 0, 1] = c[1]
        jp[row, 0, 2] = c[2]
        jp[row, 1, 0] = c[1]
        jp[row, 1, 1] = c[3]
        jp[row, 1, 2] = c[4]
        jp[row, 2, 0] = c[2]
        jp[row, 2, 1] = c[4]
        jp[row, 2, 2] = c[5]
        msp[row, 0] = c[6]
        msp[row, 1] = c[7]
        msp[row, 2] = c[8]
        mp[row] = c[9]
    rj = np.empty((3, 3))
    for row in range(nf - 1, -1, -1):
        a = ints[row, 0]
        if a == 0:
            continue
        k = a - 1
        m = mp[row]
        p = pos[row]
        # S = R MS+_j
        s0 = rot[row, 0, 0] * msp[row, 0] + rot[row, 0, 1] * msp[row, 1] + rot[row, 0, 2] * msp[row, 2]
        s1 = rot[row, 1, 0] * msp[row, 0] + rot[row, 1, 1] * msp[row, 1] + rot[row, 1, 2] * msp[row, 2]
        s2 = rot[row, 2, 0] * msp[row, 0] + rot[row, 2, 1] * msp[row, 1] + rot[row, 2, 2] * msp[row, 2]
        # R J+ (3x3), then (R J+) R^T
        for i in range(3):
            for l in range(3):
                rj[i, l] = rot[row, i, 0] * jp[row, 0, l] + rot[row, i, 1] * jp[row, 1, l] + rot[row, i, 2] * jp[row, 2, l]
        ps = p[0] * s0 + p[1] * s1 + p[2] * s2
        pp = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
        sv = (s0, s1, s2)
        for i in range(3):
            for l in range(3):
                # -(p^ S^ + S^ p^) = 2 (p.S) I - p S^T - S p^T ;  -M p^ p^ = M (|p|^2 I - p p^T)
                val = rj[i, 0] * rot[row, l, 0] + rj[i, 1] * rot[row, l, 1] + rj[i, 2] * rot[row, l, 2]
                val -= p[i] * sv[l] + sv[i] * p[l] + m * p[i] * p[l]
                if i == l:
                    val += 2.0 * ps + m * pp
                jp[k, i, l] += val
        msp[k, 0] += s0 + m * p[0]
        msp[k, 1] += s1 + m * p[1]
        msp[k, 2] += s2 + m * p[2]
        mp[k] += m
    for row in range(nf):
        col = ints[row, 2]
        if col < 0:
            continue
        if ints[row, 1] == 0:       # f = ez x MS+, n = J+ ez
            f0, f1, f2 = -msp[row, 1], msp[row, 0], 0.0
            n0, n1, n2 = jp[row, 0, 2], jp[row, 1, 2], jp[row, 2, 2]
            out[col, col] = n2 + chi[row, 10]
        else:                       # f = M+ ez, n = MS+ x ez
            f0, f1, f2 = 0.0, 0.0, mp[row]
            n0, n1, n2 = msp[row, 1], -msp[row, 0], 0.0
            out[col, col] = f2 + chi[row, 10]
        k = row
        while ints[k, 0] > 0:
            fr0 = rot[k, 0, 0] * f0 + rot[k, 0, 1] * f1 + rot[k, 0, 2] * f2
            fr1 = rot[k, 1, 0] * f0 + rot[k, 1, 1] * f1 + rot[k, 1, 2] * f2
            fr2 = rot[k, 2, 0] * f0 + rot[k, 2, 1] * f1 + rot[k, 2, 2] * f2
            p0, p1, p2 = pos[k, 0], pos[k, 1], pos[k, 2]
            m0 = rot[k, 0, 0] * n0 + rot[k, 0, 1] * n1 + rot[k, 0, 2] * n2 + p1 * fr2 - p2 * fr1
            m1 = rot[k, 1, 0] * n0 + rot[k, 1, 1] * n1 + rot[k, 1, 2] * n2 + p2 * fr0 - p0 * fr2
            m2 = rot[k, 2, 0] * n0 + rot[k, 2, 1] * n1 + rot[k, 2, 2] * n2 + p0 * fr1 - p1 * fr0
            f0, f1, f2, n0, n1, n2 = fr0, fr1, fr2, m0, m1, m2
            k = ints[k, 0] - 1
            other = ints[k, 2]
            if other >= 0:
                value = f2 if ints[k, 1] == 1 else n2
                out[other, col] = value
                out[col, other] = value


@njit(cache=True)
def crba(ints, geo, chi, q, out):
    """Inertia matrix of one state into ``out`` (n, n, zeroed here); False if ``q`` is not finite. The batch
    kernel on one-row views."""
    n = q.shape[0]
    return crba_batch(ints, geo, chi, q.reshape(1, n), out.reshape(1, n, n))


@njit(cache=True)
def crba_batch(ints, geo, chi, q, out):
    """Inertia matrices of many states, q (S, n), out (S, n, n); False if ``q`` is not finite."""
    for s in range(q.shape[0]):
        if not _finite(q[s]):
            return False
    nf = ints.shape[0]
    rot = np.empty((nf, 3, 3))
    pos = np.empty((nf, 3))
    jp = np.empty((nf, 3, 3))
    msp = np.empty((nf, 3))
    mp = np.empty(nf)
    out[:, :, :] = 0.0
    for s in range(q.shape[0]):
        _local(ints, geo, q[s], rot, pos)
        _crba_one(ints, chi, rot, pos, out[s], jp, msp, mp)
    return True


@njit(cache=True, inline="always")
def mass_and_bias(ints, geo, chi, gravity, q, qd, zeros, mass, bias, rot, pos, w, wd, vd, f, n, jp, msp, mp):
    """The inertia matrix at ``q`` into ``mass`` and the Newton–Euler torques at ``(q, qd, 0)`` into
    ``bias`` (Coriolis, centrifugal, gravity and friction terms as ``chi`` and ``gravity`` have them),
    sharing one pass of local transforms; the caller's work arrays (see :func:`rnea_batch`,
    :func:`crba_batch`), ``zeros`` (n,) of zeros. For an integrator's right-hand side: no allocation,
    no finiteness check."""
    _rnea_one(ints, geo, chi, gravity, q, qd, zeros, bias, rot, pos, w, wd, vd, f, n)
    mass[:, :] = 0.0
    _crba_one(ints, chi, rot, pos, mass, jp, msp, mp)
