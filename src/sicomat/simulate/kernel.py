"""The compiled (numba) simulation kernel that executes a :class:`~sicomat.simulate.program.HybridProgram`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from sicomat.errors import ModelError, SicomatError
from sicomat.simulate.continuous import DEFAULT_LEVELS, active_links, discretize_many
from sicomat.simulate.program import (ClampGate, CurrentLimit, Delay, HybridProgram, LinearOutput,
                                      LinearUpdate, Quantize, Saturate, Setpoint, Sum)

__all__ = ["SimulationDiverged", "KernelResult", "BatchResult", "run", "run_batch", "bare_loop",
           "DIVERGENCE_FACTOR", "DIVERGENCE_WARMUP", "MAX_EVENTS"]

DIVERGENCE_FACTOR = 1e9
"""Default divergence limit: ``|x_i| > DIVERGENCE_FACTOR * (1 + s)`` for any continuous state,
``s`` being the largest ``|x_i|`` over the states at ``t_0 .. t_DIVERGENCE_WARMUP``."""

DIVERGENCE_WARMUP = 10
"""Base steps observed to set the scale of the default divergence limit (only non-finite states
count as divergence before)."""

MAX_EVENTS = 8
"""Default cap on stick/slip events located inside one base step (guards against Zeno chatter)."""

# op codes
_LIN_OUT, _LIN_UPD, _SUM, _SAT, _QUANT, _DELAY, _CURLIM, _CLAMP, _SETPOINT = range(9)
_NIP = 4   # int params per op
_NFP = 5   # float params per op
_NBI = 10  # int params per block

_OK, _DIVERGED_STATE, _DIVERGED_RECORD = 0, 1, 2


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
    """

    def __init__(self, message: str, *, time: float, step: int, variant: int | None = None) -> None:
        self.time = time
        self.step = step
        self.variant = variant
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
# numba kernel
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


@njit(cache=True)
def _dot_row(M, c, r, z):
    """``M[c, r, :] @ z``."""
    s = 0.0
    for j in range(z.shape[0]):
        s += M[c, r, j] * z[j]
    return s


@njit(cache=True)
def _propagate(PGT, c, lev, z, out, nx):
    """``out[:nx] = PGT[c, lev].T @ z`` (``z = [x; u; f]``; column-wise, vectorisable)."""
    for i in range(nx):
        out[i] = 0.0
    for j in range(z.shape[0]):
        zj = z[j]
        for i in range(nx):
            out[i] += PGT[c, lev, j, i] * zj


@njit(cache=True)
def _has_event(zc, c, stuck, dirn, Lz, G, static, nx):
    """A sliding link's velocity opposes its direction, or a stuck link's force exceeds static."""
    for j in range(stuck.shape[0]):
        if stuck[j]:
            if abs(_dot_row(Lz, c, j, zc)) > static[j]:
                return True
        else:
            v = 0.0
            for i in range(nx):
                v += G[j, i] * zc[i]
            if dirn[j] * v < 0.0:
                return True
    return False


@njit(cache=True)
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
        else:
            v = 0.0
            for i in range(nx):
                v += G[j, i] * z[i]
            if dirn[j] * v <= 0.0:
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
                lam = _dot_row(Lz, cand, j, zp)
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


@njit(cache=True)
def _acting_friction(z, c, stuck, Lz, nx, nu, out):
    for j in range(stuck.shape[0]):
        out[j] = _dot_row(Lz, c, j, z) if stuck[j] else z[nx + nu + j]


@njit(cache=True)
def _advance_with_events(z, zc, zp, cfg, stuck, dirn, PGT, Lz, Proj, G, static, coulomb, nx, nu,
                         max_events):
    """Advance ``z`` over one base step, locating stick/slip events by bisection.

    Sub-steps are binary fractions ``h / 2**l``: the largest fraction that fits in the rest of
    the step is tried; if it contains an event it is halved until the event is bracketed by one
    finest sub-step, which is taken, and the event is resolved at its end. Returns the new
    configuration and the number of events.
    """
    nz = z.shape[0]
    levels = PGT.shape[1] - 1
    total = 1 << levels
    for i in range(nx, nz):
        zc[i] = z[i]
    pos = 0
    n_events = 0
    while pos < total:
        rem = total - pos
        lev = 0
        while (1 << (levels - lev)) > rem:
            lev += 1
        _propagate(PGT, cfg, lev, z, zc, nx)
        if n_events >= max_events or not _has_event(zc, cfg, stuck, dirn, Lz, G, static, nx):
            for i in range(nx):
                z[i] = zc[i]
            pos += 1 << (levels - lev)
            continue
        # an event inside [pos, pos + 2^(levels-lev)): bisect down to one finest sub-step
        have = lev == levels
        while lev < levels:
            lev += 1
            _propagate(PGT, cfg, lev, z, zc, nx)
            if _has_event(zc, cfg, stuck, dirn, Lz, G, static, nx):
                have = lev == levels
            else:
                for i in range(nx):
                    z[i] = zc[i]
                pos += 1 << (levels - lev)
                have = False
        if not have:
            _propagate(PGT, cfg, levels, z, zc, nx)
        for i in range(nx):
            z[i] = zc[i]
        pos += 1
        cfg = _resolve(z, stuck, dirn, Proj, Lz, G, static, coulomb, nx, nu, zp)
        for i in range(nx, nz):
            zc[i] = z[i]
        n_events += 1
    return cfg, n_events


@njit(cache=True)
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


@njit(cache=True)
def _simulate(n_steps, rec_every, store_full, max_events, limit_abs, limit_factor, warmup,
              op_code, op_period, op_phase, op_ip, op_fp, idx, fdata, blk_i, xb0, table, n_delay,
              in_slots, out_slots, fr_slots, rec_slots, n_slots,
              PGT, Lz, Proj, out_ptr, out_col, out_val, G, coulomb, static, x0,
              rec_out, states_out, fric_out, stuck_out, x_final):
    """Run ``n_steps`` base steps; returns ``(status, step)`` (status 0: completed)."""
    nx = x0.shape[0]
    nu = in_slots.shape[0]
    ny = out_slots.shape[0]     # rows of the sparse [C D] (out_ptr, out_col, out_val) over z
    nf = coulomb.shape[0]
    nz = nx + nu + nf
    n_ops = op_code.shape[0]
    n_rec = rec_slots.shape[0]
    n_cols = table.shape[0]
    last_col = table.shape[1] - 1

    slots = np.zeros(n_slots)
    xb = xb0.copy()
    delay_buf = np.zeros(n_delay)
    count = np.zeros(n_ops, dtype=np.int64)     # executions (Setpoint) or ring position (Delay)
    wait = np.empty(n_ops, dtype=np.int64)
    for o in range(n_ops):
        wait[o] = op_phase[o] % op_period[o]    # first k >= 0 with (k - phase) % period == 0
    scratch_n = 1
    for b in range(blk_i.shape[0]):
        scratch_n = max(scratch_n, blk_i[b, 0], blk_i[b, 1], blk_i[b, 2])
    ub = np.zeros(scratch_n)
    tb = np.zeros(scratch_n)
    z = np.zeros(nz)           # [x; u; f]
    zc = np.zeros(nz)          # candidate [x+; u; f]
    zp = np.zeros(nz)
    fr = np.zeros(nf)
    stuck = np.zeros(nf, dtype=np.bool_)
    dirn = np.ones(nf)
    for i in range(nx):
        z[i] = x0[i]
    # links at zero sliding velocity start stuck
    cfg = 0
    for j in range(nf):
        v = 0.0
        for i in range(nx):
            v += G[j, i] * z[i]
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
    PGT0 = PGT[0, 0]

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
                s += out_val[q] * z[out_col[q]]
            slots[out_slots[r]] = s
        if nf > 0 and fr_slots.shape[0] > 0:
            _acting_friction(z, cfg, stuck, Lz, nx, nu, fr)
            for j in range(nf):
                if fr_slots[j] >= 0:
                    slots[fr_slots[j]] = fr[j]

        # (2) the ops due at k, in list order (wait[o]: steps until op o is due)
        for o in range(n_ops):
            if wait[o] > 0:
                wait[o] -= 1
                continue
            wait[o] = op_period[o] - 1
            code = op_code[o]
            if code == _SUM:
                n = op_ip[o, 0]
                io = op_ip[o, 1]
                wo = op_ip[o, 3]
                s = op_fp[o, 0]
                for i in range(n):
                    s += fdata[wo + i] * slots[idx[io + i]]
                slots[op_ip[o, 2]] = s
            elif code == _LIN_OUT or code == _LIN_UPD:
                b = op_ip[o, 0]
                nxb = blk_i[b, 0]
                nin = blk_i[b, 1]
                nout = blk_i[b, 2]
                xo = blk_i[b, 9]
                io = blk_i[b, 7]
                for i in range(nin):
                    ub[i] = slots[idx[io + i]]
                if code == _LIN_OUT:
                    co = blk_i[b, 5]
                    do = blk_i[b, 6]
                    for r in range(nout):
                        s = 0.0
                        for j in range(nxb):
                            s += fdata[co + r * nxb + j] * xb[xo + j]
                        for j in range(nin):
                            s += fdata[do + r * nin + j] * ub[j]
                        tb[r] = s
                    oo = blk_i[b, 8]
                    for r in range(nout):
                        slots[idx[oo + r]] = tb[r]
                else:
                    ao = blk_i[b, 3]
                    bo = blk_i[b, 4]
                    for r in range(nxb):
                        s = 0.0
                        for j in range(nxb):
                            s += fdata[ao + r * nxb + j] * xb[xo + j]
                        for j in range(nin):
                            s += fdata[bo + r * nin + j] * ub[j]
                        tb[r] = s
                    for r in range(nxb):
                        xb[xo + r] = tb[r]
            elif code == _SAT:
                v = slots[op_ip[o, 0]]
                lo = slots[op_ip[o, 2]] if op_ip[o, 2] >= 0 else op_fp[o, 0]
                hi = slots[op_ip[o, 3]] if op_ip[o, 3] >= 0 else op_fp[o, 1]
                if v < lo:
                    v = lo
                elif v > hi:
                    v = hi
                slots[op_ip[o, 1]] = v
            elif code == _QUANT:
                q = op_fp[o, 0]
                v = slots[op_ip[o, 0]] / q
                slots[op_ip[o, 1]] = q * (np.floor(v) if op_ip[o, 2] == 1 else np.rint(v))
            elif code == _DELAY:
                n = op_ip[o, 2]
                v = slots[op_ip[o, 0]]
                if n == 0:
                    slots[op_ip[o, 1]] = v
                else:
                    p = op_ip[o, 3] + count[o]          # ring position
                    old = delay_buf[p]
                    delay_buf[p] = v
                    slots[op_ip[o, 1]] = old
                    count[o] = count[o] + 1 if count[o] + 1 < n else 0
            elif code == _CURLIM:
                lo, hi = _current_limit(slots[op_ip[o, 0]], op_fp[o, 0], op_fp[o, 1], op_fp[o, 2],
                                        op_fp[o, 3], op_fp[o, 4])
                slots[op_ip[o, 1]] = lo
                slots[op_ip[o, 2]] = hi
            elif code == _CLAMP:
                e = slots[op_ip[o, 0]]
                us = slots[op_ip[o, 1]]
                if us != slots[op_ip[o, 2]] and e * us > 0.0:
                    slots[op_ip[o, 3]] = 0.0
                else:
                    slots[op_ip[o, 3]] = e
            elif code == _SETPOINT:
                col = op_ip[o, 0]
                j = count[o] if count[o] < last_col else last_col
                slots[op_ip[o, 1]] = table[col, j] if col < n_cols else 0.0
                count[o] += 1

        # (3) latch the held input; a stuck link may break away at once
        for i in range(nu):
            z[nx + i] = slots[in_slots[i]]
        if cfg != 0:
            for j in range(nf):
                if stuck[j] and abs(_dot_row(Lz, cfg, j, z)) > static[j]:
                    cfg = _resolve(z, stuck, dirn, Proj, Lz, G, static, coulomb, nx, nu, zp)
                    break

        # (4) records
        if rec_wait > 0:
            rec_wait -= 1
        else:
            rec_wait = rec_every - 1
            row += 1
            bad = False
            for i in range(n_rec):
                v = slots[rec_slots[i]]
                rec_out[row, i] = v
                if v != v:
                    bad = True
            if store_full:
                for i in range(nx):
                    states_out[k, i] = z[i]
                if nf > 0:
                    _acting_friction(z, cfg, stuck, Lz, nx, nu, fr)
                    for j in range(nf):
                        fric_out[k, j] = fr[j]
                        stuck_out[k, j] = stuck[j]
            if bad:
                status = _DIVERGED_RECORD
                k_bad = k
                break

        # (5) advance the continuous state to t_{k+1}
        if nf == 0:
            for i in range(nx):
                zc[i] = 0.0
            for j in range(nz):
                zj = z[j]
                for i in range(nx):
                    zc[i] += PGT0[j, i] * zj
            for i in range(nx):
                z[i] = zc[i]
        else:
            for i in range(nx, nz):
                zc[i] = z[i]
            for i in range(nx):
                zc[i] = 0.0
            for j in range(nz):
                zj = z[j]
                for i in range(nx):
                    zc[i] += PGT[cfg, 0, j, i] * zj
            if _has_event(zc, cfg, stuck, dirn, Lz, G, static, nx):
                cfg, n_events = _advance_with_events(z, zc, zp, cfg, stuck, dirn, PGT, Lz, Proj, G,
                                                     static, coulomb, nx, nu, max_events)
                total_events += n_events
            else:
                for i in range(nx):
                    z[i] = zc[i]

        # divergence
        bad = False
        for i in range(nx):
            v = abs(z[i])
            if not v <= limit:
                bad = True
        if bad:
            status = _DIVERGED_STATE
            k_bad = k
            break
        if limit_abs <= 0.0 and k < warmup:
            for i in range(nx):
                scale = max(scale, abs(z[i]))
            if k == warmup - 1:
                limit = limit_factor * (1.0 + scale)

    for i in range(nx):
        x_final[i] = z[i]
    return status, k_bad, total_events


@njit(cache=True)
def _simulate_batch(n_steps, rec_every, max_events, limit_abs, limit_factor, warmup,
                    op_code, op_period, op_phase, op_ip, op_fp, idx, fdata, blk_i, xb0, table,
                    n_delay, in_slots, out_slots, fr_slots, rec_slots, n_slots,
                    PGT, Lz, Proj, out_ptr, out_col, out_val, G, coulomb, static, x0,
                    rec_out, x_final, status, k_bad):
    nx = x0.shape[1]
    nf = coulomb.shape[1]
    states_dummy = np.zeros((1, nx))
    fric_dummy = np.zeros((1, nf))
    stuck_dummy = np.zeros((1, nf), dtype=np.bool_)
    for v in range(x0.shape[0]):
        st, kb, _ = _simulate(
            n_steps, rec_every, False, max_events, limit_abs, limit_factor, warmup,
            op_code, op_period, op_phase, op_ip, op_fp[v], idx, fdata[v], blk_i, xb0[v], table[v],
            n_delay, in_slots, out_slots, fr_slots, rec_slots, n_slots, PGT[v], Lz[v], Proj[v],
            out_ptr, out_col, out_val[v], G[v], coulomb[v], static[v], x0[v], rec_out[v],
            states_dummy, fric_dummy, stuck_dummy, x_final[v])
        status[v] = st
        k_bad[v] = kb


# --------------------------------------------------------------------------------------------
# lowering of a program to flat arrays
# --------------------------------------------------------------------------------------------

@dataclass(eq=False)
class _Lowered:
    """A program as flat arrays: ``struct`` (must agree across batch variants) and ``nums``."""

    struct: dict[str, np.ndarray]
    nums: dict[str, np.ndarray]
    nx: int
    links: np.ndarray
    n_links: int


def _slot(value: int, n_slots: int, what: str) -> int:
    v = int(value)
    if not 0 <= v < n_slots:
        raise ModelError(f"{what} must be a slot index in [0, {n_slots})", value=value)
    return v


def _lower(program: HybridProgram, record: Sequence[int] | None = None) -> _Lowered:
    n_slots = program.n_slots
    cont = program.continuous
    A = np.atleast_2d(np.asarray(cont.A, dtype=float))
    nx = A.shape[0]
    in_slots = np.array([_slot(s, n_slots, "continuous input slot") for s in cont.input_slots],
                        dtype=np.int64)
    out_slots = np.array([_slot(s, n_slots, "continuous output slot") for s in cont.output_slots],
                         dtype=np.int64)
    nu, ny = in_slots.size, out_slots.size
    try:
        np.asarray(cont.B, dtype=float).reshape(nx, nu)
        C = np.asarray(cont.C, dtype=float).reshape(ny, nx)
        D = np.asarray(cont.D, dtype=float).reshape(ny, nu)
    except ValueError:
        raise ModelError(f"continuous part: B, C, D must have shapes ({nx}, {nu}), ({ny}, {nx}), "
                         f"({ny}, {nu}) for {nx} states, {nu} input slots and {ny} output slots",
                         value=(np.shape(cont.B), np.shape(cont.C), np.shape(cont.D))) from None
    links = active_links(cont)
    n_links = np.asarray(cont.coulomb).size
    try:
        G_all = np.asarray(cont.G, dtype=float).reshape(n_links, nx) if n_links else np.zeros((0, nx))
        x0 = np.asarray(cont.x0, dtype=float).reshape(nx)
    except ValueError:
        raise ModelError(f"continuous part: G must have shape ({n_links}, {nx}) and x0 ({nx},)",
                         value=(np.shape(cont.G), np.shape(cont.x0))) from None
    G = np.ascontiguousarray(G_all[links])
    coulomb = np.asarray(cont.coulomb, dtype=float).reshape(-1)[links]
    static = np.asarray(cont.static, dtype=float).reshape(-1)[links]
    fr_all = tuple(cont.friction_slots)
    if fr_all and len(fr_all) != n_links:
        raise ModelError(f"friction_slots must name one slot (or -1) per friction link "
                         f"({n_links})", value=fr_all)
    fr_slots = np.array([-1 if int(fr_all[j]) < 0 else _slot(fr_all[j], n_slots, "friction slot")
                         for j in links] if fr_all else [], dtype=np.int64)

    rec = program.record if record is None else tuple(record)
    rec_slots = np.array([_slot(s, n_slots, "recorded slot") for s in rec], dtype=np.int64)

    table = np.atleast_2d(np.asarray(program.table, dtype=float))
    if table.shape[1] == 0:
        table = np.zeros((table.shape[0], 1))

    idx: list[int] = []
    fdata: list[np.ndarray] = []
    f_len = 0

    def add_floats(a: np.ndarray) -> int:
        nonlocal f_len
        off = f_len
        flat = np.asarray(a, dtype=float).reshape(-1)
        fdata.append(flat)
        f_len += flat.size
        return off

    def add_ints(values: Sequence[int], what: str) -> int:
        off = len(idx)
        idx.extend(_slot(v, n_slots, what) for v in values)
        return off

    blk_i = np.zeros((len(program.blocks), _NBI), dtype=np.int64)
    xb0: list[np.ndarray] = []
    xs = 0
    for b, blk in enumerate(program.blocks):
        Ab = np.atleast_2d(np.asarray(blk.A, dtype=float)) if np.size(blk.A) else np.zeros((0, 0))
        nxb, nin, nout = Ab.shape[0], len(blk.inputs), len(blk.outputs)
        try:
            Ab = Ab.reshape(nxb, nxb)
            Bb = np.asarray(blk.B, dtype=float).reshape(nxb, nin)
            Cb = np.asarray(blk.C, dtype=float).reshape(nout, nxb)
            Db = np.asarray(blk.D, dtype=float).reshape(nout, nin)
        except ValueError:
            raise ModelError(f"block {b}: matrices do not match {nxb} states, {nin} inputs and "
                             f"{nout} outputs") from None
        blk_i[b] = (nxb, nin, nout, add_floats(Ab), add_floats(Bb), add_floats(Cb), add_floats(Db),
                    add_ints(blk.inputs, f"block {b} input"), add_ints(blk.outputs, f"block {b} output"),
                    xs)
        x0b = np.zeros(nxb) if blk.x0 is None else np.asarray(blk.x0, dtype=float).reshape(nxb)
        xb0.append(x0b)
        xs += nxb

    n_ops = len(program.ops)
    op_code = np.zeros(n_ops, dtype=np.int64)
    op_period = np.ones(n_ops, dtype=np.int64)
    op_phase = np.zeros(n_ops, dtype=np.int64)
    op_ip = np.zeros((n_ops, _NIP), dtype=np.int64)
    op_fp = np.zeros((n_ops, _NFP))
    n_delay = 0
    n_blocks = len(program.blocks)
    for o, op in enumerate(program.ops):
        period = int(op.period)
        if period < 1:
            raise ModelError(f"op {o}: period must be a positive number of base steps",
                             value=op.period)
        op_period[o], op_phase[o] = period, int(op.phase)
        if isinstance(op, (LinearOutput, LinearUpdate)):
            if not 0 <= op.block < n_blocks:
                raise ModelError(f"op {o}: no block {op.block} ({n_blocks} blocks)")
            op_code[o] = _LIN_OUT if isinstance(op, LinearOutput) else _LIN_UPD
            op_ip[o, 0] = op.block
        elif isinstance(op, Sum):
            if len(op.inputs) != len(op.weights):
                raise ModelError(f"op {o}: Sum needs one weight per input",
                                 value=(op.inputs, op.weights))
            op_code[o] = _SUM
            op_ip[o] = (len(op.inputs), add_ints(op.inputs, f"op {o} input"),
                        _slot(op.output, n_slots, f"op {o} output"), add_floats(op.weights))
            op_fp[o, 0] = op.offset
        elif isinstance(op, Saturate):
            op_code[o] = _SAT
            op_ip[o] = (_slot(op.input, n_slots, f"op {o} input"),
                        _slot(op.output, n_slots, f"op {o} output"),
                        -1 if op.lower_slot < 0 else _slot(op.lower_slot, n_slots, f"op {o} lower_slot"),
                        -1 if op.upper_slot < 0 else _slot(op.upper_slot, n_slots, f"op {o} upper_slot"))
            op_fp[o, :2] = (op.lower, op.upper)
        elif isinstance(op, Quantize):
            if op.mode not in ("round", "floor"):
                raise ModelError(f"op {o}: Quantize mode must be 'round' or 'floor'", value=op.mode)
            if not (np.isfinite(op.step) and op.step > 0):
                raise ModelError(f"op {o}: Quantize step must be positive", value=op.step)
            op_code[o] = _QUANT
            op_ip[o, :3] = (_slot(op.input, n_slots, f"op {o} input"),
                            _slot(op.output, n_slots, f"op {o} output"), op.mode == "floor")
            op_fp[o, 0] = op.step
        elif isinstance(op, Delay):
            if op.samples < 0:
                raise ModelError(f"op {o}: Delay samples must be >= 0", value=op.samples)
            op_code[o] = _DELAY
            op_ip[o] = (_slot(op.input, n_slots, f"op {o} input"),
                        _slot(op.output, n_slots, f"op {o} output"), op.samples, n_delay)
            n_delay += int(op.samples)
        elif isinstance(op, CurrentLimit):
            if not op.i_peak > 0 or not op.u_max > 0:
                raise ModelError(f"op {o}: CurrentLimit needs i_peak > 0 and u_max > 0",
                                 value=(op.i_peak, op.u_max))
            op_code[o] = _CURLIM
            op_ip[o, :3] = (_slot(op.speed, n_slots, f"op {o} speed"),
                            _slot(op.lower, n_slots, f"op {o} lower"),
                            _slot(op.upper, n_slots, f"op {o} upper"))
            op_fp[o] = (op.i_peak, op.u_max, op.resistance, op.ke, op.wl)
        elif isinstance(op, ClampGate):
            op_code[o] = _CLAMP
            op_ip[o] = (_slot(op.input, n_slots, f"op {o} input"),
                        _slot(op.unsaturated, n_slots, f"op {o} unsaturated"),
                        _slot(op.saturated, n_slots, f"op {o} saturated"),
                        _slot(op.output, n_slots, f"op {o} output"))
        elif isinstance(op, Setpoint):
            if not 0 <= op.column < table.shape[0]:
                raise ModelError(f"op {o}: Setpoint column must be in [0, {table.shape[0]})",
                                 value=op.column)
            op_code[o] = _SETPOINT
            op_ip[o, :2] = (op.column, _slot(op.output, n_slots, f"op {o} output"))
        else:
            raise ModelError(f"op {o}: unknown op kind {type(op).__name__}")

    struct = dict(op_code=op_code, op_period=op_period, op_phase=op_phase, op_ip=op_ip,
                  idx=np.array(idx, dtype=np.int64), blk_i=blk_i, in_slots=in_slots,
                  out_slots=out_slots, fr_slots=fr_slots, rec_slots=rec_slots,
                  shapes=np.array([n_slots, nx, nu, ny, links.size, n_delay, f_len, xs,
                                   *table.shape], dtype=np.int64),
                  links=links.astype(np.int64))
    nums = dict(op_fp=op_fp,
                fdata=np.concatenate(fdata) if fdata else np.zeros(0),
                xb0=np.concatenate(xb0) if xb0 else np.zeros(0),
                table=np.ascontiguousarray(table), CD=np.hstack([C, D]), G=G,
                coulomb=np.ascontiguousarray(coulomb),
                static=np.ascontiguousarray(static), x0=x0)
    return _Lowered(struct, nums, nx, links, n_links)


def _kernel_matrices(programs: Sequence[HybridProgram], links: np.ndarray,
                     levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stacked ``[Phi Gamma]ᵀ`` (transposed), ``[Lx Lu Lf]`` and projections of every variant."""
    disc = discretize_many([p.continuous for p in programs], programs[0].step,
                           levels if links.size else 0, links=links)
    PG = np.ascontiguousarray(np.swapaxes(np.concatenate([disc.Phi, disc.Gamma], axis=-1), -1, -2))
    Lz = np.ascontiguousarray(np.concatenate([disc.Lx, disc.Lu, disc.Lf], axis=-1))
    return PG, Lz, np.ascontiguousarray(disc.projection)


def _sparse_outputs(CD: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``[C D]`` of every variant (shape (n_variants, ny, nx + nu)) as rows of a shared sparsity pattern.

    Returns ``(ptr, col, val)``: row ``r`` is ``Σ val[v, q] z[col[q]]`` for ``ptr[r] <= q < ptr[r+1]``;
    the pattern is the union of the variants' non-zeros (outputs are mostly selections of states).
    """
    mask = np.any(CD != 0.0, axis=0)
    ptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))]).astype(np.int64)
    col = np.nonzero(mask)[1].astype(np.int64)
    val = np.ascontiguousarray(CD[:, mask])
    return ptr, col, val


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
    Base step k follows :mod:`sicomat.simulate.program`: (1) ``y = C x_k + D u_{k-1}`` (the input
    still held from the previous step, zero at k = 0) and the acting friction forces (with that
    same input) are written to their slots; (2) the due ops run in list order; (3) ``u_k`` is
    latched, and a stuck link whose holding force now exceeds its static limit breaks away;
    (4) records; (5) exact advance to ``t_{k+1}``. In (5) each friction link is stuck (its
    constraint force holds it) or slides with ``f = -coulomb * d`` (``d`` its direction of
    motion); a sliding link whose velocity reverses, or a stuck link whose force exceeds
    ``static``, is an event, located by bisection over binary fractions of h. At an event, the
    links whose velocity reached zero are projected onto ``v = 0`` and stick if the holding force
    is within ``static``; otherwise they slide against that force. Links with ``coulomb = static
    = 0`` are ignored.

    Divergence is checked on the continuous state after every step and on the recorded slots
    (NaN); block states are not checked themselves (they act through the slots).
    """
    _check_run_args(n_steps, levels, max_events)
    n_steps = int(n_steps)
    low = _lower(program)
    PG, Lz, Proj = _kernel_matrices([program], low.links, int(levels))
    s, m = low.struct, low.nums
    out_ptr, out_col, out_val = _sparse_outputs(m["CD"][None])
    nf = low.links.size
    rec = np.zeros((n_steps, s["rec_slots"].size))
    states = np.zeros((n_steps, low.nx))
    fric = np.zeros((n_steps, nf))
    stuck = np.zeros((n_steps, nf), dtype=np.bool_)
    x_final = np.zeros(low.nx)
    limit_abs, factor = _divergence_args(divergence_limit)
    status, k_bad, n_events = _simulate(
        n_steps, 1, True, int(max_events), limit_abs, factor, DIVERGENCE_WARMUP,
        s["op_code"], s["op_period"], s["op_phase"], s["op_ip"], m["op_fp"], s["idx"], m["fdata"],
        s["blk_i"], m["xb0"], m["table"], int(s["shapes"][5]), s["in_slots"], s["out_slots"],
        s["fr_slots"], s["rec_slots"], int(program.n_slots), PG[0], Lz[0], Proj[0], out_ptr, out_col,
        out_val[0], m["G"], m["coulomb"], m["static"], m["x0"], rec, states, fric, stuck, x_final)
    if status != _OK:
        raise _diverged(status, k_bad, program.step, None)
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
              on_divergence: str = "raise") -> BatchResult:
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
    n_steps, every = int(n_steps), int(record_every)
    rec_sel = _record_slots(programs[0], record)
    lows = [_lower(p, rec_sel) for p in programs]
    first = lows[0]
    step = programs[0].step
    for v, (p, low) in enumerate(zip(programs, lows)):
        if p.step != step:
            raise ModelError(f"variant {v}: base step differs from variant 0", value=p.step)
        for key, ref in first.struct.items():
            if not np.array_equal(low.struct[key], ref) or low.struct[key].shape != ref.shape:
                raise ModelError(f"variant {v} does not have the structure of variant 0 ({key} "
                                 f"differs)")
    PG, Lz, Proj = _kernel_matrices(programs, first.links, int(levels))
    nums = {key: np.ascontiguousarray(np.stack([low.nums[key] for low in lows]))
            for key in first.nums}
    s = first.struct
    out_ptr, out_col, out_val = _sparse_outputs(nums["CD"])
    nv = len(programs)
    n_rec = -(-n_steps // every)
    rec = np.zeros((nv, n_rec, s["rec_slots"].size))
    x_final = np.zeros((nv, first.nx))
    status = np.zeros(nv, dtype=np.int64)
    k_bad = np.zeros(nv, dtype=np.int64)
    limit_abs, factor = _divergence_args(divergence_limit)
    _simulate_batch(
        n_steps, every, int(max_events), limit_abs, factor, DIVERGENCE_WARMUP,
        s["op_code"], s["op_period"], s["op_phase"], s["op_ip"], nums["op_fp"], s["idx"],
        nums["fdata"], s["blk_i"], nums["xb0"], nums["table"], int(s["shapes"][5]), s["in_slots"],
        s["out_slots"], s["fr_slots"], s["rec_slots"], int(programs[0].n_slots), PG, Lz, Proj,
        out_ptr, out_col, out_val, nums["G"], nums["coulomb"], nums["static"], nums["x0"], rec,
        x_final, status, k_bad)
    diverged_step = np.where(status != _OK, k_bad, -1)
    for v in np.flatnonzero(status != _OK):
        if on_divergence == "raise":
            raise _diverged(int(status[v]), int(k_bad[v]), step, int(v))
        rec[v, -(-int(k_bad[v]) // every):] = 0.0
        x_final[v] = 0.0
    names = tuple(programs[0].slot_names[i] for i in s["rec_slots"])
    return BatchResult(time=np.arange(n_rec) * every * step, records=rec, record_names=names,
                       final_states=x_final, diverged_step=diverged_step)
