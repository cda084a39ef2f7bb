"""The compiled (numba) simulation kernel that executes a :class:`~sicomat.servo.program.HybridProgram`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit

from sicomat.errors import ModelError, SicomatError
from .continuous import DEFAULT_LEVELS
from .lowering import CLAMP as _CLAMP
from .lowering import CURLIM as _CURLIM
from .lowering import DELAY as _DELAY
from .lowering import LIN_OUT as _LIN_OUT
from .lowering import LIN_UPD as _LIN_UPD
from .lowering import QUANT as _QUANT
from .lowering import SAT as _SAT
from .lowering import SETPOINT as _SETPOINT
from .lowering import SUM as _SUM
from .lowering import block_patterns, kernel_matrices, lower, sparse_outputs
from ..servo.program import HybridProgram

__all__ = ["SimulationDiverged", "KernelResult", "BatchResult", "run", "run_batch", "batch_threads", "bare_loop",
           "DIVERGENCE_FACTOR", "DIVERGENCE_WARMUP", "MAX_EVENTS"]

DIVERGENCE_FACTOR = 1e9
"""Default divergence limit: ``|x_i| > DIVERGENCE_FACTOR * (1 + s)`` for any continuous state,
``s`` being the largest ``|x_i|`` over the states at ``t_0 .. t_DIVERGENCE_WARMUP``."""

DIVERGENCE_WARMUP = 10
"""Base steps observed to set the scale of the default divergence limit (only non-finite states
count as divergence before)."""

MAX_EVENTS = 8
"""Default cap on stick/slip events located inside one base step (guards against Zeno chatter)."""

_OK, _DIVERGED_STATE, _DIVERGED_RECORD = 0, 1, 2

_njit_unrefcounted = njit(cache=True, error_model="numpy", _nrt=False)  # type: ignore[call-overload]
"""The compilation of the kernel's allocation-free core (:func:`_simulate_steps`, :func:`_advance_with_events`,
:func:`_resolve`): without numba's reference counting (``_nrt=False``), see :func:`_simulate_steps`."""

_u = np.uint64
"""Index cast used in the kernel: numba skips its negative-index wrap-around for unsigned indices."""


class SimulationDiverged(SicomatError, ArithmeticError):
    """The simulated states grew without bound (or became non-finite): the loop is unstable.

    Attributes
    ----------
    time : float
        Simulated time (s) at which the divergence was detected.
    step : int
        Base step index of that time.
    variant : int or None
        Index of the diverged variant in :func:`run_batch`, else None.
    axis : str or None
        The machine axis that diverged, when a multi-axis run (:func:`sicomat.simulation.paths.simulate_path`)
        knows it, else None.
    """

    def __init__(self, message: str, *, time: float, step: int, variant: int | None = None,
                 axis: str | None = None) -> None:
        self.time = time
        self.step = step
        self.variant = variant
        self.axis = axis
        super().__init__(message)


@dataclass(frozen=True, eq=False)
class KernelResult:
    """One simulation run.

    Attributes
    ----------
    time : ndarray, shape (n_steps,)
        ``t_k = k h`` (s).
    records : ndarray, shape (n_steps, n_record)
        ``slots[program.record]`` after the ops of step k.
    record_names : tuple of str
        Names of the recorded slots.
    states : ndarray, shape (n_steps, nx)
        Continuous state at ``t_k`` (before the step).
    friction : ndarray, shape (n_steps, nf)
        Friction force acting at the start of ``[t_k, t_{k+1})`` (the constraint force of a stuck
        link, ``-coulomb * sign(v)`` of a sliding one; 0 for links without friction).
    stuck : ndarray of bool, shape (n_steps, nf)
        Whether each link is stuck at the start of ``[t_k, t_{k+1})``.
    final_state : ndarray, shape (nx,)
        Continuous state at ``t_{n_steps}``.
    events : int
        Number of stick/slip events located inside the steps (each costs a bisection).
    """

    time: np.ndarray
    records: np.ndarray
    record_names: tuple[str, ...]
    states: np.ndarray
    friction: np.ndarray
    stuck: np.ndarray
    final_state: np.ndarray
    events: int = 0


@dataclass(frozen=True, eq=False)
class BatchResult:
    """Runs of program variants of one structure.

    Attributes
    ----------
    time : ndarray, shape (n_records,)
        Times of the recorded rows, ``k h`` for ``k = 0, e, 2e, ...`` (``e = record_every``).
    records : ndarray, shape (n_variants, n_records, n_record)
        Recorded slots of each variant (rows from the divergence on are zero for a diverged
        variant when ``on_divergence="flag"``).
    record_names : tuple of str
    final_states : ndarray, shape (n_variants, nx)
        Continuous state at ``t_{n_steps}`` (zero for a diverged variant).
    diverged_step : ndarray of int, shape (n_variants,)
        Base step at which a variant diverged, -1 for a variant that did not.
    """

    time: np.ndarray
    records: np.ndarray
    record_names: tuple[str, ...]
    final_states: np.ndarray
    diverged_step: np.ndarray

    @property
    def diverged(self) -> np.ndarray:
        """Boolean mask of the variants that diverged."""
        return self.diverged_step >= 0


# --------------------------------------------------------------------------------------------
# numba kernel (the small helpers of the step are inlined: a call per step costs ~10 %)
# --------------------------------------------------------------------------------------------

@njit(cache=True)
def bare_loop(Phi, Gamma, K, n_steps):
    """The speed limit of a sampled loop: ``x+ = Phi x + Gamma u`` with ``u = -K x``, nothing else.

    Compiled with numba (call it with float64 arrays); starts from ``x = [1, 0, ..., 0]``. The
    products are computed column-wise, as in the kernel.

    Parameters
    ----------
    Phi : ndarray, shape (nx, nx)
    Gamma : ndarray, shape (nx, nu)
    K : ndarray, shape (nu, nx)
    n_steps : int

    Returns
    -------
    ndarray, shape (nx,)
        The final state.
    """
    nx = Phi.shape[0]
    nu = Gamma.shape[1]
    PhiT = np.ascontiguousarray(Phi.T)
    GammaT = np.ascontiguousarray(Gamma.T)
    x = np.zeros(nx)
    if nx > 0:
        x[0] = 1.0
    xn = np.empty(nx)
    u = np.empty(nu)
    for _ in range(n_steps):
        for i in range(nu):
            s = 0.0
            for j in range(nx):
                s -= K[i, j] * x[j]
            u[i] = s
        for i in range(nx):
            xn[i] = 0.0
        for j in range(nx):
            xj = x[j]
            for i in range(nx):
                xn[i] += PhiT[j, i] * xj
        for j in range(nu):
            uj = u[j]
            for i in range(nx):
                xn[i] += GammaT[j, i] * uj
        for i in range(nx):
            x[i] = xn[i]
    return x


@njit(cache=True, error_model="numpy", inline='always')
def _propagate(PGT, c, lev, z, out, nx):
    """``out[:nx] = PGT[c, lev].T @ z`` (``z = [x; u; f]``): :func:`_propagate_rows` on the level's matrix."""
    if z.shape[0] == 0:
        return
    _propagate_rows(PGT[c], lev, z, out, nx)


@njit(cache=True, error_model="numpy", inline='always')
def _propagate_rows(MT, c, z, out, nx):
    """``out[:nx] = MT[c].T @ z`` (column-wise, vectorisable).

    Each sum starts at 0.0 and adds the terms in column order (the first column is added in the
    initialising step). Rows are taken four at a time, their four sums kept in registers over the
    columns (a sum read and written back in memory at every column waited on the store at each one);
    the last one to three rows together the same way (one at a time, each waited on its own chain
    of additions: with 11 states, three rows cost as much as the eight before them). Each row's sum
    is the same sequence of operations as one row at a time.
    """
    nz = z.shape[0]
    z0 = z[0]
    i = 0
    while i + 4 <= nx:
        s0 = 0.0 + MT[c, 0, i] * z0
        s1 = 0.0 + MT[c, 0, i + 1] * z0
        s2 = 0.0 + MT[c, 0, i + 2] * z0
        s3 = 0.0 + MT[c, 0, i + 3] * z0
        for j in range(1, nz):
            zj = z[j]
            s0 += MT[c, j, i] * zj
            s1 += MT[c, j, i + 1] * zj
            s2 += MT[c, j, i + 2] * zj
            s3 += MT[c, j, i + 3] * zj
        out[i] = s0
        out[i + 1] = s1
        out[i + 2] = s2
        out[i + 3] = s3
        i += 4
    r = nx - i
    if r == 3:
        s0 = 0.0 + MT[c, 0, i] * z0
        s1 = 0.0 + MT[c, 0, i + 1] * z0
        s2 = 0.0 + MT[c, 0, i + 2] * z0
        for j in range(1, nz):
            zj = z[j]
            s0 += MT[c, j, i] * zj
            s1 += MT[c, j, i + 1] * zj
            s2 += MT[c, j, i + 2] * zj
        out[i] = s0
        out[i + 1] = s1
        out[i + 2] = s2
    elif r == 2:
        s0 = 0.0 + MT[c, 0, i] * z0
        s1 = 0.0 + MT[c, 0, i + 1] * z0
        for j in range(1, nz):
            zj = z[j]
            s0 += MT[c, j, i] * zj
            s1 += MT[c, j, i + 1] * zj
        out[i] = s0
        out[i + 1] = s1
    elif r == 1:
        s0 = 0.0 + MT[c, 0, i] * z0
        for j in range(1, nz):
            s0 += MT[c, j, i] * z[j]
        out[i] = s0


@njit(cache=True, error_model="numpy", inline='always')
def _dot1(A, j, b, n):
    """``A[j, :n] @ b[:n]`` in four partial sums: one chain of additions would wait on each one's
    latency (these dot products decide stick and slip at every step).

    The row is read in place by its indices (as :func:`_dot2` and :func:`_dot3` read theirs): a view
    ``A[j]`` would take and release a reference to ``A`` (two atomic operations) at every call, which
    cost the kernel as much as its arithmetic."""
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for i in range(0, m, 4):
        s0 += A[j, i] * b[i]
        s1 += A[j, i + 1] * b[i + 1]
        s2 += A[j, i + 2] * b[i + 2]
        s3 += A[j, i + 3] * b[i + 3]
    for i in range(m, n):
        s0 += A[j, i] * b[i]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy", inline='always')
def _dot2(A, c, j, b, n):
    """``A[c, j, :n] @ b[:n]``, summed as :func:`_dot1`."""
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for i in range(0, m, 4):
        s0 += A[c, j, i] * b[i]
        s1 += A[c, j, i + 1] * b[i + 1]
        s2 += A[c, j, i + 2] * b[i + 2]
        s3 += A[c, j, i + 3] * b[i + 3]
    for i in range(m, n):
        s0 += A[c, j, i] * b[i]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy", inline='always')
def _dot3(A, c, j, k, b, n):
    """``A[c, j, k, :n] @ b[:n]``, summed as :func:`_dot1`."""
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for i in range(0, m, 4):
        s0 += A[c, j, k, i] * b[i]
        s1 += A[c, j, k, i + 1] * b[i + 1]
        s2 += A[c, j, k, i + 2] * b[i + 2]
        s3 += A[c, j, k, i + 3] * b[i + 3]
    for i in range(m, n):
        s0 += A[c, j, k, i] * b[i]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy", inline='always')
def _holding_force(Lz, c, j, z):
    """Constraint force of link ``j`` in configuration ``c``: ``Lz[c, j] @ z``."""
    return _dot2(Lz, c, j, z, z.shape[0])


@njit(cache=True, error_model="numpy", inline='always')
def _holding_forces(Lz, c, stuck, z, hold):
    """``hold[j] = Lz[c, j] @ z`` for the stuck links ``j`` (the others are left alone)."""
    for j in range(stuck.shape[0]):
        if stuck[j]:
            hold[j] = _holding_force(Lz, c, j, z)


@_njit_unrefcounted
def _resolve(z, stuck, dirn, Proj, Lz, G, static, coulomb, nx, nu, zp):
    """Stick / slip decision at an event; projects the state, updates ``z``'s friction part.

    Candidates to stick: the stuck links and the sliding links whose velocity reached zero. The
    candidate whose holding force exceeds its static limit by the most is released (it slides
    against that force) and the others are re-evaluated, until every candidate holds.
    Returns the new configuration.
    """
    nf = stuck.shape[0]
    nz = z.shape[0]
    cand = 0
    for j in range(nf):
        if stuck[j]:
            cand |= 1 << j
        elif dirn[j] * _dot1(G, j, z, nx) <= 0.0:    # as in _link_values: same sum, same sign
            cand |= 1 << j
    while True:
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += Proj[cand, i, j] * z[j]
            zp[i] = s
        for i in range(nx, nx + nu):
            zp[i] = z[i]
        for j in range(nf):
            zp[nx + nu + j] = 0.0 if (cand >> j) & 1 else -coulomb[j] * dirn[j]
        worst = -1
        worst_excess = 0.0
        worst_lam = 0.0
        for j in range(nf):
            if (cand >> j) & 1:
                lam = _holding_force(Lz, cand, j, zp)
                excess = abs(lam) - static[j]
                if excess > worst_excess:
                    worst, worst_excess, worst_lam = j, excess, lam
        if worst < 0:
            break
        cand &= ~(1 << worst)
        dirn[worst] = 1.0 if worst_lam < 0.0 else -1.0   # slide against the holding force
    for i in range(nz):
        z[i] = zp[i]
    for j in range(nf):
        stuck[j] = (cand >> j) & 1 == 1
    return cand


@njit(cache=True, error_model="numpy", inline='always')
def _link_values(zc, c, stuck, dirn, Lz, G, static, nx, vals):
    """The event functions of every link at ``zc`` into ``vals`` (a stuck link's holding force, a
    sliding link's velocity times its direction); True when one is past its event (``|force| >
    static``, or the velocity opposes the direction of motion). Every link is evaluated (no early
    exit): the in-step envelope needs them all."""
    event = False
    for j in range(stuck.shape[0]):
        if stuck[j]:
            lam = _holding_force(Lz, c, j, zc)
            vals[j] = lam
            if abs(lam) > static[j]:
                event = True
        else:
            s = dirn[j] * _dot1(G, j, zc, nx)
            vals[j] = s
            if s < 0.0:
                event = True
    return event


@njit(cache=True, error_model="numpy", inline='always')
def _modal_magnitudes(PsiT, pair, c, z, nx, xi):
    """``xi = |Psi[c] z|``: the magnitudes of the modal coordinates of the state derivative
    (the Euclidean norm of each modal pair at its first index, 0 at its second), from which the
    in-step envelopes of every link follow (see :mod:`sicomat.simulation.envelope`)."""
    _propagate_rows(PsiT, c, z, xi, nx)
    for i in range(nx):
        if pair[c, i] == 1:
            xi[i] = np.sqrt(xi[i] * xi[i] + xi[i + 1] * xi[i + 1])
            xi[i + 1] = 0.0
        else:
            xi[i] = abs(xi[i])


@njit(cache=True, error_model="numpy", inline='always')
def _may_cross(a, b, U, C):
    """Whether ``p(τ) = a + (b - a) τ - U - C τ (1 - τ)`` (``U, C >= 0``) dips below 0 for some
    ``τ`` in [0, 1]: the chord of a function from ``a`` to ``b`` minus its envelope."""
    a -= U
    b -= U
    if a < 0.0 or b < 0.0:
        return True
    d = C - (b - a)
    if d <= 0.0 or d >= 2.0 * C:       # vertex outside (0, 1): the minimum is at an end
        return False
    return d * d > 4.0 * a * C


@njit(cache=True, error_model="numpy", inline='always')
def _envelope_clear(g0, g1, xi, KU, KP, c, lev, stuck, static, nx):
    """True when no link can pass its event inside a sub-step of level ``lev`` whose ends have
    the event values ``g0``, ``g1`` (none past its event), ``xi`` the modal magnitudes at the
    segment's start."""
    for j in range(stuck.shape[0]):
        U = 0.0
        C = 0.0
        for i in range(nx):
            U += KU[c, j, lev, i] * xi[i]
            C += KP[c, j, lev, i] * xi[i]
        if stuck[j]:
            s = static[j]
            if _may_cross(s - g0[j], s - g1[j], U, C) or _may_cross(s + g0[j], s + g1[j], U, C):
                return False
        elif _may_cross(g0[j], g1[j], U, C):
            return False
    return True


@njit(cache=True, error_model="numpy", inline='always')
def _cubic_positive(f0, f1, f2, M3, dt):
    """Whether ``f0 + f1 s + f2 s²/2 - M3 s³/6 > 0`` on (0, dt] (``f0 >= 0``, ``M3 >= 0``): the
    Taylor lower bound of a function from its value and first two derivatives at a sub-step's
    start and a bound ``M3`` on its third derivative."""
    if not f0 + dt * (f1 + dt * (0.5 * f2 - dt * M3 / 6.0)) > 0.0:
        return False
    if f0 == 0.0 and not (f1 > 0.0 or (f1 == 0.0 and f2 > 0.0)):
        return False
    # interior minima of the cubic: roots of f1 + f2 s - M3 s²/2 in (0, dt)
    if M3 > 0.0:
        disc = f2 * f2 + 2.0 * M3 * f1
        if disc >= 0.0:
            sq = np.sqrt(disc)
            for s in ((f2 - sq) / M3, (f2 + sq) / M3):
                if 0.0 < s < dt and not f0 + s * (f1 + s * (0.5 * f2 - s * M3 / 6.0)) > 0.0:
                    return False
    elif f2 != 0.0:            # a parabola: its vertex
        s = -f1 / f2
        if 0.0 < s < dt and not f0 + s * (f1 + 0.5 * f2 * s) > 0.0:
            return False
    return True


@njit(cache=True, error_model="numpy", inline='always')
def _taylor_clear(z, zc, g0, g1, xi, K3, D, c, dt, stuck, dirn, static, nx):
    """True when no link can pass its event within a sub-step of length ``dt`` from ``z`` to ``zc``
    (event values ``g0``, ``g1``), by the Taylor polynomials of degree 2 at both ends: the one at
    ``z`` over the first half, the one at ``zc`` (backwards in time) over the second, each within
    ``s³/6 K3 @ xi`` of the event function (``K3 @ xi`` bounds its third derivative over the whole
    segment from where ``xi`` was taken, so at either end). This proves the start of a segment where
    an event function starts at its threshold, which no chord can (a link that has just broken away
    slides from zero velocity), and a slow function that bends near its threshold, which the chord's
    envelope (its curvature bound over the whole sub-step) cannot: each polynomial is asked to hold
    over half the sub-step, with an eighth of the remainder."""
    nz = z.shape[0]
    half = 0.5 * dt
    for j in range(stuck.shape[0]):
        M3 = _dot2(K3, c, j, xi, nx)
        d1 = _dot3(D, c, j, 0, z, nz)
        d2 = _dot3(D, c, j, 1, z, nz)
        e1 = _dot3(D, c, j, 0, zc, nz)
        e2 = _dot3(D, c, j, 1, zc, nz)
        if stuck[j]:
            s = static[j]
            if not (_cubic_positive(s - g0[j], -d1, -d2, M3, half)
                    and _cubic_positive(s + g0[j], d1, d2, M3, half)
                    and _cubic_positive(s - g1[j], e1, -e2, M3, half)
                    and _cubic_positive(s + g1[j], -e1, e2, M3, half)):
                return False
        elif not (_cubic_positive(g0[j], dirn[j] * d1, dirn[j] * d2, M3, half)
                  and _cubic_positive(g1[j], -dirn[j] * e1, dirn[j] * e2, M3, half)):
            return False
    return True


@_njit_unrefcounted
def _advance_with_events(z, zc, zp, cfg, stuck, dirn, PGT, Lz, Proj, G, static, coulomb, nx, nu,
                         max_events, g0, g1, PsiT, KU, KP, K3, D, pair, xi, step, end_event):
    """Advance ``z`` over one base step whose full-step candidate ``zc`` (event values ``g1``,
    ``end_event`` whether one is past its event) contains an event or could.

    Sub-steps are binary fractions ``h / 2**l``, taken in time order: a fraction twice the last
    one taken (the whole step at first; after an event, the largest that fits in the rest of the
    step: events fall anywhere in a step, and most leave the rest of it free), or the largest
    that fits in the rest of the step, is tried and halved while it may hold an event, i.e. while an
    event function is past its event at its end, or its chord and interpolation envelope (from
    the modal magnitudes ``xi`` at the segment's start) cross the threshold inside. A finest sub-step is taken in any
    case; an event at its end is resolved there (and the bounds recomputed in the new
    configuration). So every point of the finest grid ``h / 2**levels`` where an event function
    is past its event, and every excursion inside the step that lasts longer than a finest
    sub-step, is found. A try refused because an event function is past its event at its end
    marks that grid point: until the next event, tries end before it (a try over it would be
    refused again: bisection without the failed try of twice the length after each half taken).
    Returns the new configuration and the number of events.
    """
    nz = z.shape[0]
    nf = stuck.shape[0]
    levels = PGT.shape[1] - 1
    total = 1 << levels
    pos = 0
    n_events = 0
    first = True
    _link_values(z, cfg, stuck, dirn, Lz, G, static, nx, g0)
    _modal_magnitudes(PsiT, pair, cfg, z, nx, xi)
    grow = 0                   # the level to try next: one coarser than the last one taken
    horizon = total + 1        # a finest-grid point known to hold an event (none yet)
    while pos < total:
        rem = total - pos
        if horizon - pos > 1:  # tries end before a point known to hold an event
            rem = min(rem, horizon - pos - 1)
        lev = grow
        while (1 << (levels - lev)) > rem:
            lev += 1
        while True:
            if first:
                first = False      # the caller's candidate: the whole step from pos = 0, level 0
                event = end_event
            else:
                _propagate(PGT, cfg, lev, z, zc, nx)
                event = _link_values(zc, cfg, stuck, dirn, Lz, G, static, nx, g1)
            if n_events >= max_events:
                event = False
                break
            if lev == levels:
                break
            if not event and (_envelope_clear(g0, g1, xi, KU, KP, cfg, lev, stuck, static, nx)
                              or _taylor_clear(z, zc, g0, g1, xi, K3, D, cfg, step / (1 << lev), stuck,
                                               dirn, static, nx)):
                break
            if event:
                horizon = min(horizon, pos + (1 << (levels - lev)))
            lev += 1
        for i in range(nx):
            z[i] = zc[i]
        pos += 1 << (levels - lev)
        grow = lev - 1 if lev > 0 and not event else 0
        if event:
            cfg = _resolve(z, stuck, dirn, Proj, Lz, G, static, coulomb, nx, nu, zp)
            for i in range(nx, nz):
                zc[i] = z[i]
            n_events += 1
            horizon = total + 1    # a new configuration: new event functions
            _link_values(z, cfg, stuck, dirn, Lz, G, static, nx, g0)
            _modal_magnitudes(PsiT, pair, cfg, z, nx, xi)
        else:
            for j in range(nf):
                g0[j] = g1[j]
    return cfg, n_events


@njit(cache=True, error_model="numpy")
def _current_limit(w, i_peak, u_max, R, ke, wl):
    """Admissible current interval ``[lo, hi]`` at speed ``w`` (see :class:`CurrentLimit`)."""
    lo, hi = -np.inf, np.inf
    if u_max < np.inf:
        a = R * R + (wl * w) * (wl * w)
        b = 2.0 * R * ke * w
        e = ke * w
        c = e * e - u_max * u_max
        if a > 0.0:
            disc = b * b - 4.0 * a * c
            if disc >= 0.0:
                sq = np.sqrt(disc)
                q = -0.5 * (b + sq) if b >= 0.0 else -0.5 * (b - sq)
                if q != 0.0:
                    r1 = q / a
                    r2 = c / q
                else:          # b = 0 and c = 0: double root at 0
                    r1 = 0.0
                    r2 = 0.0
                lo, hi = min(r1, r2), max(r1, r2)
            else:             # back-EMF beyond the supply: the current of least voltage
                lo = -b / (2.0 * a)
                hi = lo
        elif c > 0.0:         # R = 0 and wl w = 0: no current helps; brake as hard as allowed
            if w > 0.0:
                lo, hi = -i_peak, -i_peak
            elif w < 0.0:
                lo, hi = i_peak, i_peak
            else:
                lo, hi = 0.0, 0.0
    lo = min(max(lo, -i_peak), i_peak)
    hi = min(max(hi, -i_peak), i_peak)
    return lo, hi


@njit(cache=True, error_model="numpy", inline='always')
def _ops_state(op_code, op_period, op_phase, op_ip, n_delay):
    """The ops' run state at k = 0: ``count`` (executions of a Setpoint, ring position of a Delay),
    ``wait`` (steps until each op is first due: the first k >= 0 with (k - phase) % period == 0), the
    linear blocks' scratch rows and the delay lines' buffer."""
    n_ops = op_code.shape[0]
    count = np.zeros(n_ops, dtype=np.int64)
    wait = np.empty(n_ops, dtype=np.int64)
    scratch_n = 1
    for o in range(n_ops):
        wait[o] = op_phase[o] % op_period[o]
        if op_code[o] == _LIN_OUT or op_code[o] == _LIN_UPD:
            scratch_n = max(scratch_n, op_ip[o, 0])
    return count, wait, np.zeros(scratch_n), np.zeros(n_delay)


@njit(cache=True, error_model="numpy", inline='always')
def _divergence_limit(z, nx, k, warmup, limit, limit_abs, limit_factor, scale):
    """Whether a continuous state passed ``limit``, and the limit and scale after step ``k`` (without an
    absolute limit, ``limit_factor * (1 + s)`` once the first ``warmup`` steps have set the scale s)."""
    bad = False
    for i in range(nx):
        if not abs(z[i]) <= limit:
            bad = True
    if limit_abs <= 0.0 and k < warmup:
        for i in range(nx):
            scale = max(scale, abs(z[i]))
        if k == warmup - 1:
            limit = limit_factor * (1.0 + scale)
    return bad, limit, scale


@njit(cache=True, error_model="numpy", inline='always')
def _run_ops(op_code, op_period, op_ip, op_fp, idx, fdata, table, slots, xb, tb, delay_buf, count, wait):
    """Step (2) of a base step: the ops due now, in list order (``wait[o]``: steps until op o is due;
    ``count[o]``: executions of a Setpoint, ring position of a Delay). Shared by :func:`_simulate` and
    the nonlinear robot engine (:mod:`sicomat.simulation.nonlinear`)."""
    n_ops = op_code.shape[0]
    n_cols = table.shape[0]
    last_col = table.shape[1] - 1
    for o in range(n_ops):
        if wait[o] > 0:
            wait[o] -= 1
            continue
        wait[o] = op_period[o] - 1
        code = op_code[o]
        if code == _LIN_OUT or code == _LIN_UPD:
            # rows of y = C xb + D u or of xb+ = A xb + B u (all before any is written)
            n_rows, p = op_ip[o, 0], op_ip[o, 1]
            for r in range(n_rows):
                f, ns, ni = idx[_u(p)], idx[_u(p + 1)], idx[_u(p + 2)]
                p += 3
                s = 0.0
                for q in range(ns):
                    s += fdata[_u(f + q)] * xb[_u(idx[_u(p + q)])]
                for q in range(ns, ns + ni):
                    s += fdata[_u(f + q)] * slots[_u(idx[_u(p + q)])]
                tb[r] = s
                p += ns + ni
            if code == _LIN_OUT:
                oo = op_ip[o, 2]
                for r in range(n_rows):
                    slots[_u(idx[_u(oo + r)])] = tb[r]
            else:
                xo = op_ip[o, 2]
                for r in range(n_rows):
                    xb[_u(xo + r)] = tb[r]
        elif code == _SUM:
            n, io, wo = op_ip[o, 0], op_ip[o, 1], op_ip[o, 3]
            s = op_fp[o, 0]
            for i in range(n):
                s += fdata[_u(wo + i)] * slots[_u(idx[_u(io + i)])]
            slots[_u(op_ip[o, 2])] = s
        elif code == _SAT:
            v = slots[_u(op_ip[o, 0])]
            lo = slots[_u(op_ip[o, 2])] if op_ip[o, 2] >= 0 else op_fp[o, 0]
            hi = slots[_u(op_ip[o, 3])] if op_ip[o, 3] >= 0 else op_fp[o, 1]
            if v < lo:
                v = lo
            elif v > hi:
                v = hi
            slots[_u(op_ip[o, 1])] = v
        elif code == _QUANT:
            q = op_fp[o, 0]
            v = slots[_u(op_ip[o, 0])] / q
            slots[_u(op_ip[o, 1])] = q * (np.floor(v) if op_ip[o, 2] == 1 else np.rint(v))
        elif code == _DELAY:
            n = op_ip[o, 2]
            v = slots[_u(op_ip[o, 0])]
            if n == 0:
                slots[_u(op_ip[o, 1])] = v
            else:
                p = _u(op_ip[o, 3] + count[o])      # ring position
                old = delay_buf[p]
                delay_buf[p] = v
                slots[_u(op_ip[o, 1])] = old
                count[o] = count[o] + 1 if count[o] + 1 < n else 0
        elif code == _CURLIM:
            lo, hi = _current_limit(slots[_u(op_ip[o, 0])], op_fp[o, 0], op_fp[o, 1],
                                    op_fp[o, 2], op_fp[o, 3], op_fp[o, 4])
            slots[_u(op_ip[o, 1])] = lo
            slots[_u(op_ip[o, 2])] = hi
        elif code == _CLAMP:
            e = slots[_u(op_ip[o, 0])]
            us = slots[_u(op_ip[o, 1])]
            if us != slots[_u(op_ip[o, 2])] and e * us > 0.0:
                slots[_u(op_ip[o, 3])] = 0.0
            else:
                slots[_u(op_ip[o, 3])] = e
        elif code == _SETPOINT:
            col = op_ip[o, 0]
            j = count[o] if count[o] < last_col else last_col
            slots[_u(op_ip[o, 1])] = table[_u(col), _u(j)] if col < n_cols else 0.0
            count[o] += 1


@njit(cache=True, error_model="numpy")
def _simulate(n_steps, rec_every, store_full, max_events, limit_abs, limit_factor, warmup,
              op_code, op_period, op_phase, op_ip, op_fp, idx, fdata, xb0, table, n_delay,
              in_slots, out_slots, fr_slots, rec_slots, n_slots,
              PGT, Lz, Proj, PsiT, KU, KP, K3, D, pair, step, out_ptr, out_col, out_val, G, coulomb,
              static, x0, rec_out, states_out, fric_out, stuck_out, x_final):
    """Run ``n_steps`` base steps; returns ``(status, step, events)`` (status 0: completed).

    The op rows ``op_ip`` carry everything an op reads (slots, offsets into ``idx`` and
    ``fdata``, block sizes; see :func:`lower_ops`), so an op touches no other metadata.
    Indices read from the arrays are cast to unsigned (``_u``) where they are used: numba then
    omits its negative-index wrap-around, a fifth of the time of the ops.

    This allocates the run's state and scratch arrays and hands them to :func:`_simulate_steps`,
    which is compiled without numba's reference counting (see there).
    """
    nx = x0.shape[0]
    nu = in_slots.shape[0]
    nf = coulomb.shape[0]
    nz = nx + nu + nf
    count, wait, tb, delay_buf = _ops_state(op_code, op_period, op_phase, op_ip, n_delay)
    # z: [x; u; f]; zc: the candidate [x+; u; f]; hold: the holding forces of the stuck links at
    # the current z; g0, g1: event values of the links at z and at zc (see _link_values); xi: modal
    # magnitudes of the state derivative (_modal_magnitudes)
    return _simulate_steps(
        n_steps, rec_every, store_full, max_events, limit_abs, limit_factor, warmup,
        op_code, op_period, op_ip, op_fp, idx, fdata, table,
        in_slots, out_slots, fr_slots, rec_slots, n_slots,
        PGT, Lz, Proj, PsiT, KU, KP, K3, D, pair, step, out_ptr, out_col, out_val, G, coulomb,
        static, x0, rec_out, states_out, fric_out, stuck_out, x_final,
        np.zeros(n_slots), xb0.copy(), count, wait, tb, delay_buf, np.zeros(nz), np.zeros(nz),
        np.zeros(nz), np.zeros(nf, dtype=np.bool_), np.ones(nf), np.zeros(nf), np.zeros(nf),
        np.zeros(nf), np.zeros(nx))


@_njit_unrefcounted
def _simulate_steps(n_steps, rec_every, store_full, max_events, limit_abs, limit_factor, warmup,
                    op_code, op_period, op_ip, op_fp, idx, fdata, table,
                    in_slots, out_slots, fr_slots, rec_slots, n_slots,
                    PGT, Lz, Proj, PsiT, KU, KP, K3, D, pair, step, out_ptr, out_col, out_val, G,
                    coulomb, static, x0, rec_out, states_out, fric_out, stuck_out, x_final,
                    slots, xb, count, wait, tb, delay_buf, z, zc, zp, stuck, dirn, hold, g0, g1, xi):
    """The base steps of :func:`_simulate`, on state and scratch arrays allocated by it.

    Compiled without numba's reference counting (``_nrt=False``: it allocates nothing, and every
    array it reads is owned by its caller for the whole call): with it, each use of an array by an
    inlined helper took and released a reference (two atomic operations) that numba's pruning did
    not remove, about 40 % of the kernel's time.
    """
    nx = x0.shape[0]
    nu = in_slots.shape[0]
    ny = out_slots.shape[0]     # rows of the sparse [C D] (out_ptr, out_col, out_val) over z
    nf = coulomb.shape[0]
    nz = nx + nu + nf
    n_rec = rec_slots.shape[0]
    rec_all = n_rec == n_slots      # every slot recorded in order: rows are copies of the slots
    for i in range(n_rec):
        rec_all = rec_all and rec_slots[i] == i
    n_fr = fr_slots.shape[0]

    hold_ok = False
    for i in range(nx):
        z[i] = x0[i]
    # links at zero sliding velocity start stuck
    cfg = 0
    for j in range(nf):
        v = _dot1(G, j, z, nx)
        if v == 0.0:
            stuck[j] = True
            cfg |= 1 << j
        else:
            dirn[j] = 1.0 if v > 0.0 else -1.0
            z[nx + nu + j] = -coulomb[j] * dirn[j]
    if cfg != 0:
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += Proj[cfg, i, j] * z[j]
            zp[i] = s
        for i in range(nx):
            z[i] = zp[i]

    limit = limit_abs if limit_abs > 0.0 else np.inf
    scale = 0.0
    for i in range(nx):
        scale = max(scale, abs(z[i]))

    status = 0
    k_bad = -1
    total_events = 0
    rec_wait = 0
    row = -1
    for k in range(n_steps):
        # (1) continuous outputs with the held input; acting friction forces
        for r in range(ny):
            s = 0.0
            for q in range(out_ptr[r], out_ptr[r + 1]):
                s += out_val[_u(q)] * z[_u(out_col[_u(q)])]
            slots[_u(out_slots[r])] = s
        if n_fr > 0:
            if not hold_ok:
                _holding_forces(Lz, cfg, stuck, z, hold)
                hold_ok = True
            for j in range(nf):
                if fr_slots[j] >= 0:
                    slots[_u(fr_slots[j])] = hold[j] if stuck[j] else z[nx + nu + j]

        # (2) the ops due at k, in list order
        _run_ops(op_code, op_period, op_ip, op_fp, idx, fdata, table, slots, xb, tb, delay_buf, count, wait)

        # (3) latch the held input; a stuck link may break away at once
        for i in range(nu):
            v = slots[_u(in_slots[i])]
            z[nx + i] = v
        hold_ok = cfg == 0          # no stuck link: nothing to hold
        if cfg != 0:
            _holding_forces(Lz, cfg, stuck, z, hold)
            hold_ok = True
            for j in range(nf):
                if stuck[j] and abs(hold[j]) > static[j]:
                    cfg = _resolve(z, stuck, dirn, Proj, Lz, G, static, coulomb, nx, nu, zp)
                    hold_ok = False
                    break

        # (4) records
        if rec_wait > 0:
            rec_wait -= 1
        else:
            rec_wait = rec_every - 1
            row += 1
            bad = False
            if rec_all:
                for i in range(n_rec):
                    v = slots[i]
                    rec_out[_u(row), i] = v
                    bad |= v != v
            else:
                for i in range(n_rec):
                    v = slots[_u(rec_slots[i])]
                    rec_out[_u(row), i] = v
                    bad |= v != v
            if store_full:
                for i in range(nx):
                    states_out[k, i] = z[i]
                if nf > 0:
                    if not hold_ok:
                        _holding_forces(Lz, cfg, stuck, z, hold)
                        hold_ok = True
                    for j in range(nf):
                        fric_out[k, j] = hold[j] if stuck[j] else z[nx + nu + j]
                        stuck_out[k, j] = stuck[j]
            if bad:
                status = _DIVERGED_RECORD
                k_bad = k
                break

        # (5) advance the continuous state to t_{k+1}: the whole step, subdivided if it holds or
        # may hold an event
        for i in range(nx, nz):
            zc[i] = z[i]
        # (an event inside the step is possible when one is past its event at the step's end, or
        # when the chord and the curvature envelope of an event function cross its threshold)
        _propagate(PGT, cfg, 0, z, zc, nx)
        in_step = False
        end_ev = False
        if nf > 0:
            end_ev = _link_values(zc, cfg, stuck, dirn, Lz, G, static, nx, g1)
            in_step = end_ev
            if not end_ev:
                if not hold_ok:
                    _holding_forces(Lz, cfg, stuck, z, hold)
                for j in range(nf):
                    g0[j] = hold[j] if stuck[j] else dirn[j] * _dot1(G, j, z, nx)
                # the modal magnitudes at the step's start: one projection of the state (a bound
                # carried from the last step cost as much and cleared fewer steps: the latch of a new
                # input inflates it)
                _modal_magnitudes(PsiT, pair, cfg, z, nx, xi)
                in_step = not (_envelope_clear(g0, g1, xi, KU, KP, cfg, 0, stuck, static, nx)
                               or _taylor_clear(z, zc, g0, g1, xi, K3, D, cfg, step, stuck, dirn, static,
                                                nx))
        if in_step:
            cfg, n_events = _advance_with_events(z, zc, zp, cfg, stuck, dirn, PGT, Lz, Proj, G,
                                                 static, coulomb, nx, nu, max_events, g0, g1,
                                                 PsiT, KU, KP, K3, D, pair, xi, step,
                                                 end_ev)
            total_events += n_events
            hold_ok = False
        else:
            for i in range(nx):
                z[i] = zc[i]
            for j in range(nf):
                hold[j] = g1[j]
            hold_ok = True      # the event values at zc, now z, hold the stuck links' forces

        # divergence
        bad, limit, scale = _divergence_limit(z, nx, k, warmup, limit, limit_abs, limit_factor, scale)
        if bad:
            status = _DIVERGED_STATE
            k_bad = k
            break

    for i in range(nx):
        x_final[i] = z[i]
    return status, k_bad, total_events


@njit(cache=True, nogil=True)
def _simulate_batch(n_steps, rec_every, max_events, limit_abs, limit_factor, warmup,
                    op_code, op_period, op_phase, op_ip, op_fp, idx, fdata, xb0, tables, tix,
                    n_delay, in_slots, out_slots, fr_slots, rec_slots, n_slots,
                    PGT, Lz, Proj, PsiT, KU, KP, K3, D, pair, step, cont, out_ptr,
                    out_col,
                    out_val, G,
                    coulomb, static, x0, rec_out, x_final, status, k_bad, v_first, v_last):
    """:func:`_simulate` for the variants ``v_first <= v < v_last``; variant ``v`` uses
    ``PGT[cont[v]]``, ``Lz[cont[v]]``, ``Proj[cont[v]]`` (variants with the same continuous part
    share its discretisation) and the setpoint table ``tables[tix[v]]`` (usually one for all).

    Releases the GIL: :func:`run_batch` runs ranges of variants on several threads at once, each
    variant by the same compiled :func:`_simulate` and writing only its own rows, so a variant's
    results do not depend on the thread that ran it nor on the other variants of the batch."""
    nx = x0.shape[1]
    nf = coulomb.shape[1]
    states_dummy = np.zeros((1, nx))
    fric_dummy = np.zeros((1, nf))
    stuck_dummy = np.zeros((1, nf), dtype=np.bool_)
    for v in range(v_first, v_last):
        c = cont[v]
        st, kb, _ = _simulate(
            n_steps, rec_every, False, max_events, limit_abs, limit_factor, warmup,
            op_code, op_period, op_phase, op_ip, op_fp[v], idx, fdata[v], xb0[v], tables[tix[v]],
            n_delay, in_slots, out_slots, fr_slots, rec_slots, n_slots, PGT[c], Lz[c], Proj[c],
            PsiT[c], KU[c], KP[c], K3[c], D[c], pair[c], step,
            out_ptr, out_col, out_val[v], G[v], coulomb[v], static[v], x0[v], rec_out[v],
            states_dummy, fric_dummy, stuck_dummy, x_final[v])
        status[v] = st
        k_bad[v] = kb


def batch_threads(threads: int | None = None) -> int:
    """The thread count of a batch: ``threads``, or numba's in the calling thread
    (``numba.get_num_threads()``, which follows ``NUMBA_NUM_THREADS`` and ``numba.set_num_threads``)."""
    if threads is None:
        import numba

        return int(numba.get_num_threads())
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ModelError("threads must be a whole number >= 1", value=threads)
    return int(threads)


CHUNKS_PER_THREAD = 16
"""Ranges of variants queued per thread by :func:`_in_threads`: small enough that a thread finishing
early takes more (variants with more stick/slip events cost more), large enough to cost nothing."""


def _in_threads(work: Callable[[int, int], object], n: int, threads: int) -> None:
    """``work(first, last)`` over ranges covering ``0 .. n``, on ``threads`` threads (a compiled call
    that releases the GIL per range; in the calling thread when one suffices). The ranges are taken
    from one queue, so the threads share the work whatever each range costs."""
    threads = min(threads, n)
    if threads <= 1:
        work(0, n)
        return
    size = max(1, -(-n // (threads * CHUNKS_PER_THREAD)))
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="sicomat-batch") as pool:
        for future in [pool.submit(work, first, min(first + size, n)) for first in range(0, n, size)]:
            future.result()


PIECES = 16
"""Pieces a batch on several threads is prepared in (see :func:`_pipelined`): the threads wait only for
the first one (a sixteenth of the preparation) and the preparation of each next one overlaps the kernel."""

MIN_PIECE = 16
"""Fewest variants in a piece of a pipelined batch (smaller batches are prepared in one piece)."""


def _piece_size(n: int, threads: int) -> int:
    """Variants per prepared piece of a batch of ``n`` on ``threads`` threads (``n``: one piece)."""
    if threads <= 1 or n < 2 * MIN_PIECE:
        return n
    return max(MIN_PIECE, -(-n // PIECES))


def _pipelined(prepare: Callable[[int, int], tuple], kernel: Callable[..., object], n: int, size: int,
               threads: int) -> None:
    """``kernel(*prepare(a, b), first, last)`` over pieces ``[a, b)`` of ``0 .. n``: each piece is
    prepared in the calling thread and its ranges queued to ``threads`` threads, which run them while
    the next pieces are prepared. An error while preparing a piece (a variant of another structure)
    cancels what is queued, waits for what runs and is raised (the outputs are the caller's to drop)."""
    step = max(1, -(-n // (threads * CHUNKS_PER_THREAD)))
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="sicomat-batch") as pool:
        futures = []
        try:
            for a in range(0, n, size):
                b = min(a + size, n)
                args = prepare(a, b)
                futures += [pool.submit(kernel, *args, first, min(first + step, b - a))
                            for first in range(0, b - a, step)]
        except BaseException:
            for future in futures:
                future.cancel()
            raise
        for future in futures:
            future.result()


def _batch_arguments(programs: Sequence[HybridProgram], first: int, last: int, reference, rec_sel,
                     patterns, levels: int, step: float) -> tuple:
    """The kernel's arguments (all but the common head and the output rows) for the variants
    ``first .. last - 1``: lowered with the block patterns of the whole batch (so that their structure
    is variant 0's, ``reference``), checked, and discretised (equal continuous parts once)."""
    part = programs[first:last]
    lows = [lower(p, rec_sel, patterns) for p in part]
    key = reference.structure_key()
    for v, (p, low) in enumerate(zip(part, lows), start=first):
        if p.step != step:
            raise ModelError(f"variant {v}: base step differs from variant 0", value=p.step)
        if low.structure_key() != key:
            what = next(name for name, ref in reference.struct.items()
                        if low.struct[name].shape != ref.shape
                        or not np.array_equal(low.struct[name], ref))
            raise ModelError(f"variant {v} does not have the structure of variant 0 ({what} "
                             f"differs)")
    PG, Lz, Proj, cont, PsiT, KU, KP, K3, D, pair = kernel_matrices(part, reference.links, levels)
    nums = {name: np.ascontiguousarray(np.stack([low.nums[name] for low in lows]))
            for name in reference.nums if name != "table"}
    tables, tix = _shared([low.nums["table"] for low in lows])
    s = reference.struct
    # the outputs' sparsity pattern is this piece's: a coefficient zero in every variant of a piece adds
    # only +-0 where another piece keeps it (see run), so a variant's results do not depend on its piece
    out_ptr, out_col, out_val = sparse_outputs(nums["CD"])
    return (s["op_code"], s["op_period"], s["op_phase"], s["op_ip"], nums["op_fp"], s["idx"],
            nums["fdata"], nums["xb0"], tables, tix, int(s["shapes"][5]), s["in_slots"],
            s["out_slots"], s["fr_slots"], s["rec_slots"], int(programs[0].n_slots), PG, Lz, Proj, PsiT, KU,
            KP, K3, D, pair, float(step), cont,
            out_ptr, out_col, out_val, nums["G"], nums["coulomb"], nums["static"], nums["x0"])


def _shared(arrays: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Distinct arrays (by identity: the programs of one setpoint table share its array) stacked,
    and each one's index among them."""
    index: dict[int, int] = {}
    distinct: list[np.ndarray] = []
    tix = np.empty(len(arrays), dtype=np.int64)
    for v, a in enumerate(arrays):
        if id(a) not in index:
            index[id(a)] = len(distinct)
            distinct.append(a)
        tix[v] = index[id(a)]
    return np.ascontiguousarray(np.stack(distinct)), tix


def _divergence_args(divergence_limit: float | None) -> tuple[float, float]:
    if divergence_limit is None:
        return 0.0, DIVERGENCE_FACTOR
    if not divergence_limit > 0:
        raise ModelError("divergence_limit must be positive", value=divergence_limit)
    return float(divergence_limit), DIVERGENCE_FACTOR


def _check_run_args(n_steps: int, levels: int, max_events: int) -> None:
    if int(n_steps) < 0:
        raise ModelError("n_steps must be >= 0", value=n_steps)
    if not 0 <= int(levels) <= 30:
        raise ModelError("levels must be in 0..30", value=levels)
    if int(max_events) < 1:
        raise ModelError("max_events must be >= 1", value=max_events)


def _diverged(status: int, k: int, step: float, variant: int | None) -> SimulationDiverged:
    who = "" if variant is None else f"variant {variant}: "
    if status == _DIVERGED_RECORD:
        t = k * step
        why = "a recorded signal became NaN"
    else:
        t = (k + 1) * step
        why = "the continuous state became non-finite or exceeded the divergence limit"
    return SimulationDiverged(f"{who}simulation diverged at t = {t:.6g} s (base step {k}): {why}; "
                              f"the loop is probably unstable", time=t, step=k, variant=variant)


def _record_slots(program: HybridProgram, record: Sequence[int | str] | None) -> tuple[int, ...] | None:
    if record is None:
        return None
    names = program.slot_names
    out = []
    for r in record:
        if isinstance(r, str):
            if r not in names:
                raise ModelError("unknown slot name in record", value=r)
            out.append(names.index(r))
        else:
            out.append(int(r))
    return tuple(out)


def run(program: HybridProgram, n_steps: int, levels: int = DEFAULT_LEVELS, *,
        divergence_limit: float | None = None, max_events: int = MAX_EVENTS) -> KernelResult:
    """Simulate ``program`` for ``n_steps`` base steps.

    Parameters
    ----------
    program : HybridProgram
    n_steps : int
        Number of base steps; the records cover ``t_0 .. t_{n_steps-1}``.
    levels : int, default 10
        Stick/slip events are located to ``h / 2**levels``.
    divergence_limit : float, optional
        Absolute bound on ``|x_i|``; by default ``DIVERGENCE_FACTOR * (1 + s)`` with ``s`` the
        largest ``|x_i|`` over the first ``DIVERGENCE_WARMUP`` steps (non-finite states always count).
    max_events : int, default 8
        Stick/slip events located per base step; further ones wait for the next step.

    Returns
    -------
    KernelResult

    Raises
    ------
    SimulationDiverged
        The state diverged; the message gives the simulated time.
    ModelError
        The program is inconsistent (slot indices, shapes, more than 6 friction links).

    Notes
    -----
    Base step k follows :mod:`sicomat.servo.program`: (1) ``y = C x_k + D u_{k-1}`` (the input
    still held from the previous step, zero at k = 0) and the acting friction forces (with that
    same input) are written to their slots; (2) the due ops run in list order; (3) ``u_k`` is
    latched, and a stuck link whose holding force now exceeds its static limit breaks away;
    (4) records; (5) exact advance to ``t_{k+1}``. In (5) each friction link is stuck (its
    constraint force holds it) or slides with ``f = -coulomb * d`` (``d`` its direction of
    motion); a sliding link whose velocity reverses, or a stuck link whose force exceeds
    ``static``, is an event, located over binary fractions of h: a (sub-)step is halved while an
    event condition holds at its end or the in-step envelope of an event function (from the
    modal magnitudes of the state derivative, :mod:`sicomat.simulation.envelope`) cannot exclude
    one inside, so no point of the finest grid ``h / 2**levels`` where a condition holds is
    skipped, and an excursion lasting longer than one finest sub-step is always found. At an event, the
    links whose velocity reached zero are projected onto ``v = 0`` and stick if the holding force
    is within ``static``; otherwise they slide against that force. Links with ``coulomb = static
    = 0`` are ignored.

    Divergence is checked on the continuous state after every step and on the recorded slots
    (NaN); block states are not checked themselves (they act through the slots).

    Exact-zero coefficients of the linear blocks and of the continuous outputs ``[C D]`` are
    skipped (a batch keeps those non-zero in any variant): adding their ``±0`` products leaves a
    sum unchanged, so only an infinite or NaN input met by a zero coefficient no longer yields NaN.
    """
    _check_run_args(n_steps, levels, max_events)
    n_steps = int(n_steps)
    low = lower(program)
    PG, Lz, Proj, _, PsiT, KU, KP, K3, D, pair = kernel_matrices([program], low.links, int(levels))
    s, m = low.struct, low.nums
    out_ptr, out_col, out_val = sparse_outputs(m["CD"][None])
    nf = low.links.size
    # every row is written by the kernel (or the run raises): no need to zero them
    rec = np.empty((n_steps, s["rec_slots"].size))
    states = np.empty((n_steps, low.nx))
    fric = np.empty((n_steps, nf))
    stuck = np.empty((n_steps, nf), dtype=np.bool_)
    x_final = np.zeros(low.nx)
    limit_abs, factor = _divergence_args(divergence_limit)
    status, k_bad, n_events = _simulate(
        n_steps, 1, True, int(max_events), limit_abs, factor, DIVERGENCE_WARMUP,
        s["op_code"], s["op_period"], s["op_phase"], s["op_ip"], m["op_fp"], s["idx"], m["fdata"],
        m["xb0"], m["table"], int(s["shapes"][5]), s["in_slots"], s["out_slots"],
        s["fr_slots"], s["rec_slots"], int(program.n_slots), PG[0], Lz[0], Proj[0], PsiT[0], KU[0], KP[0],
        K3[0], D[0], pair[0], float(program.step), out_ptr, out_col,
        out_val[0], m["G"], m["coulomb"], m["static"], m["x0"], rec, states, fric, stuck, x_final)
    if status != _OK:
        raise _diverged(status, k_bad, program.step, None)
    if nf == low.n_links:          # every link acts: the kernel's columns are the links
        friction, stuck_all = fric, stuck
    else:
        friction = np.zeros((n_steps, low.n_links))
        stuck_all = np.zeros((n_steps, low.n_links), dtype=bool)
        friction[:, low.links] = fric
        stuck_all[:, low.links] = stuck
    names = tuple(program.slot_names[i] for i in s["rec_slots"])
    return KernelResult(time=np.arange(n_steps) * program.step, records=rec, record_names=names,
                        states=states, friction=friction, stuck=stuck_all, final_state=x_final,
                        events=int(n_events))


def run_batch(programs: Sequence[HybridProgram], n_steps: int, levels: int = DEFAULT_LEVELS,
              record_every: int = 1, *, record: Sequence[int | str] | None = None,
              divergence_limit: float | None = None, max_events: int = MAX_EVENTS,
              on_divergence: str = "raise", threads: int | None = None) -> BatchResult:
    """Simulate variants of one program structure in a single compiled call.

    The variants must share the op list (kinds, periods, phases, slots, delay lengths, quantizer
    modes), the block and continuous shapes, the table shape and the friction links in use; only
    numbers differ (matrices, gains, limits, setpoints, friction forces, initial states).

    Parameters
    ----------
    programs : sequence of HybridProgram
    n_steps : int
    levels : int, default 10
    record_every : int, default 1
        Keep every ``record_every``-th base step (``k = 0, e, 2e, ...``).
    record : sequence of int or str, optional
        Slots (indices or names) to record instead of ``programs[0].record``.
    divergence_limit : float, optional
        As in :func:`run`.
    max_events : int, default 8
    on_divergence : {"raise", "flag"}
        ``"raise"``: :class:`SimulationDiverged` for the first diverged variant; ``"flag"``: mark
        it in :attr:`BatchResult.diverged_step` and zero its records from the divergence on.
    threads : int, optional
        Threads the variants are shared over (default: numba's thread count in the calling thread,
        ``numba.get_num_threads()``: ``NUMBA_NUM_THREADS``, the machine's cores unless set, or what
        ``numba.set_num_threads`` set; a Dask worker sets 1). A variant's results are bit-identical
        whatever the thread count and whatever the other variants of the batch.

    Returns
    -------
    BatchResult

    Raises
    ------
    SimulationDiverged
        A variant diverged and ``on_divergence="raise"``.
    ModelError
        Variants of different structures, or an inconsistent program.
    """
    _check_run_args(n_steps, levels, max_events)
    if on_divergence not in ("raise", "flag"):
        raise ModelError("on_divergence must be 'raise' or 'flag'", value=on_divergence)
    if int(record_every) < 1:
        raise ModelError("record_every must be >= 1", value=record_every)
    programs = list(programs)
    if not programs:
        raise ModelError("run_batch needs at least one program")
    n_threads = batch_threads(threads)
    n_steps, every = int(n_steps), int(record_every)
    rec_sel = _record_slots(programs[0], record)
    step = programs[0].step
    patterns = block_patterns(programs)
    nv = len(programs)
    n_rec = -(-n_steps // every)
    limit_abs, factor = _divergence_args(divergence_limit)
    head = (n_steps, every, int(max_events), limit_abs, factor, DIVERGENCE_WARMUP)
    reference = lower(programs[0], rec_sel, patterns)
    s = reference.struct
    # rows from a divergence on are zeroed below; the others are all written by the kernel
    rec = np.empty((nv, n_rec, s["rec_slots"].size))
    x_final = np.zeros((nv, reference.nx))
    status = np.zeros(nv, dtype=np.int64)
    k_bad = np.zeros(nv, dtype=np.int64)

    def prepare(first: int, last: int) -> tuple:
        """The kernel's arguments for the variants ``first .. last - 1`` (lowered, checked against
        variant 0's structure, discretised) and their output rows."""
        return _batch_arguments(programs, first, last, reference, rec_sel, patterns, int(levels), step) + (
            rec[first:last], x_final[first:last], status[first:last], k_bad[first:last])

    size = _piece_size(nv, n_threads)
    if size >= nv:
        args = head + prepare(0, nv)
        compiled: Callable[..., object] = _simulate_batch
        _in_threads(lambda a, b: compiled(*args, a, b), nv, n_threads)
    else:
        # pieces: each one prepared in this thread (Python, under the GIL) while the threads run the
        # compiled kernel (without the GIL) on the pieces before it
        _pipelined(lambda a, b: head + prepare(a, b), _simulate_batch, nv, size, n_threads)
    diverged_step = np.where(status != _OK, k_bad, -1)
    for v in np.flatnonzero(status != _OK).tolist():
        if on_divergence == "raise":
            raise _diverged(int(status[v]), int(k_bad[v]), step, int(v))
        rec[v, -(-int(k_bad[v]) // every):] = 0.0
        x_final[v] = 0.0
    names = tuple(programs[0].slot_names[i] for i in s["rec_slots"])
    return BatchResult(time=np.arange(n_rec) * every * step, records=rec, record_names=names,
                       final_states=x_final, diverged_step=diverged_step)
