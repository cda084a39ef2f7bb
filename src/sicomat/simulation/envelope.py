"""Bounds of the friction-event functions inside a base step (in-step event detection).

Within a segment of a step (one stick configuration, held ``w = [u; f]``) every event function of
the kernel is linear in the state: the holding force of a stuck link ``g = Lz[c, j] @ z`` or the
velocity of a sliding link ``g = G[j] @ x``. Its second derivative depends on the state derivative
``y = ẋ = [A_c B_c] z`` alone, which evolves autonomously, ``y(t) = e^{A_c t} y(0)``:
``g''(t) = r A_c e^{A_c t} y(0)`` (``r`` the state part of the row). With ``ξ = Y y(0)`` the
coordinates of ``y(0)`` in a block-diagonalising basis ``A_c = S diag(T_b) Y`` (``Y = S⁻¹``),

    sup_{0 <= t <= h} |g''(t)| <= Σ_b K_b · |ξ_b|,

where ``|ξ_b|`` is the Euclidean norm of the block's coordinates for a single real mode or a
complex pair in real modal form (``T_b = [[σ, ω], [-ω, σ]]``, whose exponential is ``e^{σt}``
times a rotation: ``K_b = ||q_b||₂ max(1, e^{μ h})`` with ``μ`` the block's logarithmic norm, exact),
and the absolute value of each coordinate for the general block that gathers the slow eigenvalues
(``|λ| h <= SLOW``: rigid-body Jordan blocks, the zeros of the constraints) and any cluster of
close fast eigenvalues (componentwise suprema by a piecewise Taylor series with its remainder).
Modal coordinates matter: in raw coordinates a stiff spring's two ends would each look like a
large force. The same holds for ``g'''`` and, for the fast blocks (invertible ``T_b``), for the
block's part of ``g`` itself (``r S_b T_b⁻¹ e^{T_b t} ξ_b``, its amplitude). The kernel computes
``|ξ|`` from ``ξ = Psi z`` (``Psi = Y [A_c B_c]``) at a segment's start, and on a sub-step of
level ``l`` a link's event function lies within ``KU[l] @ |ξ| + τ(1 - τ) KP[l] @ |ξ|`` of its chord (each block contributing twice
its amplitude or its interpolation remainder ``δ² sup|g_b''| / 2``, the smaller), and within
``s³/6 K3 @ |ξ|`` of its Taylor polynomial of degree 2 at the sub-step's start; a sub-step
whose bounds stay on the safe side of the threshold holds no event.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numba import njit

__all__ = ["SLOW", "MARGIN", "curvature_bounds"]

SLOW = 0.5
"""Eigenvalues with ``|λ| h <= SLOW`` go to the general (componentwise) block."""

MARGIN = 1e-6
"""Relative inflation of every bound: covers the rounding of the decomposition and of the suprema."""

_CLUSTER = 1e-3      # fast eigenvalues closer than this (relative) share a general block
_COND_MAX = 1e8      # a block basis worse conditioned than this: the blocks are merged
_TAYLOR_STEP = 0.5   # grid of the piecewise Taylor suprema: Δt ||T||_∞ <= this
_TAYLOR_TERMS = 14
_GRID_MAX = 20000


def _rotation_basis(v: np.ndarray) -> np.ndarray:
    """Real basis ``[Re v, Im v]`` of a complex eigenvector, its phase chosen to make the two
    columns orthogonal (a well-conditioned basis); the block is then ``[[σ, ω], [-ω, σ]]``."""
    a, b = v.real, v.imag
    phi = 0.5 * math.atan2(2 * (a @ b), (a @ a) - (b @ b))
    v = v * np.exp(-1j * phi)
    Q = np.column_stack([v.real, v.imag])
    return Q / np.linalg.norm(Q[:, 0])


def _fast_blocks(T: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int, str]]] | None:
    """Real modal basis ``Q`` of ``T`` (all eigenvalues fast): one column per real eigenvalue, two
    per complex pair; None when eigenvalues cluster or the basis is ill-conditioned."""
    n = T.shape[0]
    lam, V = np.linalg.eig(T)
    dist = np.abs(lam[:, None] - lam[None, :])
    np.fill_diagonal(dist, np.inf)
    conj = np.abs(lam[:, None] - np.conj(lam)[None, :]) <= 1e-12 * np.abs(lam)[:, None]
    dist[conj & (lam.imag != 0)[:, None]] = np.inf       # a pair's two members belong together
    if np.any(dist.min(axis=1) <= _CLUSTER * np.abs(lam)):
        return None
    cols: list[np.ndarray] = []
    blocks: list[tuple[int, int, str]] = []
    for i in np.flatnonzero(lam.imag >= 0):
        if lam[i].imag > 0:
            blocks.append((len(cols), 2, "euclid"))
            Q = _rotation_basis(V[:, i])
            cols += [Q[:, 0], Q[:, 1]]
        else:
            blocks.append((len(cols), 1, "euclid"))
            cols.append(V[:, i].real / np.linalg.norm(V[:, i].real))
    if len(cols) != n:
        return None
    Q = np.column_stack(cols)
    try:
        Qinv = np.linalg.inv(Q)
    except np.linalg.LinAlgError:
        return None
    if _cond1(Q, Qinv) > _COND_MAX:
        return None
    return Q, blocks


def _cond1(M: np.ndarray, Minv: np.ndarray) -> float:
    """The 1-norm condition number from a matrix and its inverse."""
    return float(np.abs(M).sum(axis=0).max() * np.abs(Minv).sum(axis=0).max())


def _decompose(A: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int, str]]]:
    """``S``, ``Y = S⁻¹`` and blocks ``(start, size, kind)`` with ``Y A S`` block diagonal; kind
    ``"euclid"``: one real mode or a pair in real modal form, ``"slow"``: the general block of the
    slow eigenvalues, ``"general"``: fast eigenvalues that did not separate.

    An ordered real Schur form puts the slow eigenvalues (``|λ| h <= SLOW``) first; a Sylvester
    equation decouples them from the fast ones, which are then diagonalised (real modal form).
    Whatever cannot be separated safely stays in one general block (componentwise bounds)."""
    n = A.shape[0]
    slow = lambda re, im: bool(math.hypot(re, im) * h <= SLOW)  # noqa: E731
    T, Z, k = scipy.linalg.schur(A, output="real", sort=slow)
    if k == n:
        return np.eye(n), np.eye(n), [(0, n, "slow")]
    X = np.zeros((k, n - k))
    if k:
        # T11 X - X T22 = -T12 on the quasi-triangular blocks of the Schur form
        X, scale, info = scipy.linalg.lapack.dtrsyl(T[:k, :k], T[k:, k:], -T[:k, k:], isgn=-1)
        if info < 0 or not scale > 0:
            return np.eye(n), np.eye(n), [(0, n, "slow")]
        X = X / scale
    fast = _fast_blocks(T[k:, k:])
    if fast is None:
        Q, fblocks = np.eye(n - k), [(0, n - k, "general")]
    else:
        Q, fblocks = fast
    # S = Z [[I, X], [0, I]] diag(I, Q);  Y = diag(I, Q⁻¹) [[I, -X], [0, I]] Zᵀ
    S = Z.copy()
    S[:, k:] = (Z[:, :k] @ X + Z[:, k:]) @ Q
    Y = Z.T.copy()
    Y[:k] -= X @ Z[:, k:].T
    Y[k:] = np.linalg.solve(Q, Z[:, k:].T)
    if not (np.isfinite(S).all() and np.isfinite(Y).all()) or _cond1(S, Y) > _COND_MAX:
        return np.eye(n), np.eye(n), [(0, n, "slow")]
    blocks = ([(0, k, "slow")] if k else []) + [(k + st, sz, kind) for st, sz, kind in fblocks]
    return S, Y, blocks


_SLOW_BLOCK, _GENERAL_BLOCK, _EUCLID_BLOCK = 0, 1, 2
_KINDS = {"slow": _SLOW_BLOCK, "general": _GENERAL_BLOCK, "euclid": _EUCLID_BLOCK}


@njit(cache=True)
def _balance(T):
    """``Tb = D⁻¹ T D`` with a diagonal ``D`` of powers of 2 that evens row and column norms
    (Parlett–Reinsch, as LAPACK's gebal without permutations); returns ``Tb, diag(D)``."""
    m = T.shape[0]
    Tb = T.copy()
    d = np.ones(m)
    done = False
    while not done:
        done = True
        for i in range(m):
            c = 0.0
            r = 0.0
            for j in range(m):
                if j != i:
                    c += abs(Tb[j, i])
                    r += abs(Tb[i, j])
            if c == 0.0 or r == 0.0:
                continue
            s = c + r
            f = 1.0
            g = r / 2.0
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c > g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * s:
                done = False
                d[i] *= f
                for j in range(m):
                    Tb[j, i] *= f
                    Tb[i, j] /= f
    return Tb, d


@njit(cache=True)
def _taylor_sup(Q, T, h):
    """Componentwise ``sup_{0<=t<=h} |(q e^{T t})_i|`` for each row ``q`` of ``Q``, rigorous: on
    a grid of ``t_k`` with ``Δt ||T||_∞ <= 0.5``, ``|(v_k e^{Ts})_i| <= Σ_n Δt^n/n! |(v_k T^n)_i|``
    plus the series' tail. A diagonal scaling (balancing, ``T = D Tb D⁻¹``, so
    ``q e^{Tt} = (q D) e^{Tb t} D⁻¹``) lowers ``||T||_∞`` and so the grid."""
    n_rows, m = Q.shape
    out = np.zeros((n_rows, m))
    if m == 0:
        return out
    Tb, d = _balance(T)
    norm = 0.0
    for i in range(m):
        s = 0.0
        for j in range(m):
            s += abs(Tb[i, j])
        norm = max(norm, s)
    n_grid = max(1, int(math.ceil(h * norm / _TAYLOR_STEP)))
    if n_grid > _GRID_MAX:
        out[:, :] = np.inf
        return out
    dt = h / n_grid
    # e^{Tb dt} by its Taylor series (dt ||Tb|| <= 0.5: 20 terms reach the rounding level)
    E = np.eye(m)
    term = np.eye(m)
    for k in range(1, 21):
        term = term @ Tb * (dt / k)
        E = E + term
    rho = dt * norm
    fact = np.empty(_TAYLOR_TERMS + 2)
    fact[0] = 1.0
    for k in range(1, _TAYLOR_TERMS + 2):
        fact[k] = fact[k - 1] * dt / k
    for r in range(n_rows):
        v = Q[r] * d
        for _ in range(n_grid):
            acc = np.abs(v)
            w = v.copy()
            for k in range(1, _TAYLOR_TERMS + 1):
                w = w @ Tb
                acc += np.abs(w) * fact[k]
            w = w @ Tb
            tail = np.abs(w).sum() * fact[_TAYLOR_TERMS + 1] / (1.0 - rho / (_TAYLOR_TERMS + 2))
            for i in range(m):
                out[r, i] = max(out[r, i], (acc[i] + tail) / d[i])
            v = v @ E
    return out


@njit(cache=True)
def _coefficients(R, Y, S, A, bstart, bsize, bkind, h, levels):
    """``KU, KP`` (shape ``(n_rows, levels + 1, nx)``) and ``K3`` (shape ``(n_rows, nx)``) of the
    event rows ``R`` (state parts), blocks ``bstart, bsize, bkind`` of :func:`_decompose`.

    On a sub-step of length ``δ_l = h / 2**l`` of a segment, ``g`` deviates from its chord by at
    most ``KU[l] @ |ξ| + τ(1 - τ) KP[l] @ |ξ|`` (``τ`` the fraction of the sub-step). A block
    contributes its curvature ``δ_l² sup|g_b''| / 2`` to ``KP`` (the interpolation remainder) or,
    when smaller, twice its amplitude ``sup|g_b|`` to ``KU`` (a fast block's part of ``g`` is
    ``r S_b T_b⁻¹ e^{T_b t} ξ_b``: it lies within twice its amplitude of any chord).
    ``sup |g'''| <= K3 @ |ξ|`` over the segment bounds the remainder of the Taylor polynomial
    of degree 2 at a sub-step's start. Compiled: a batch has one set per variant and configuration.
    """
    n_rows, nx = R.shape[0], S.shape[1]
    KU = np.zeros((n_rows, levels + 1, nx))
    KP = np.zeros((n_rows, levels + 1, nx))
    K3 = np.zeros((n_rows, nx))
    half_dt2 = np.empty(levels + 1)
    for lev in range(levels + 1):
        dl = h / 2.0 ** lev
        half_dt2[lev] = 0.5 * dl * dl
    RS = R @ S
    AS = A @ S
    for b in range(bstart.shape[0]):
        st, sz, kind = bstart[b], bsize[b], bkind[b]
        T = np.ascontiguousarray(Y[st:st + sz]) @ np.ascontiguousarray(AS[:, st:st + sz])
        Rb = np.ascontiguousarray(RS[:, st:st + sz])
        Q2 = Rb @ T                              # g_b'' = q e^{Tt} ξ_b
        Q3 = Q2 @ T
        has_amp = kind != _SLOW_BLOCK
        Q0 = Rb @ np.linalg.inv(T) if has_amp else Rb   # g_b = p e^{Tt} ξ_b + constant
        curv = np.zeros((n_rows, sz))
        amp = np.zeros((n_rows, sz))
        if kind == _EUCLID_BLOCK:
            if sz == 1:
                mu = T[0, 0]
            else:                                # largest eigenvalue of (T + Tᵀ) / 2
                a, c, e = T[0, 0], 0.5 * (T[0, 1] + T[1, 0]), T[1, 1]
                mu = 0.5 * (a + e) + math.hypot(0.5 * (a - e), c)
            grow = max(1.0, math.exp(min(mu * h, 700.0)))
            for r in range(n_rows):
                curv[r, 0] = np.sqrt(np.sum(Q2[r] ** 2)) * grow
                K3[r, st] = np.sqrt(np.sum(Q3[r] ** 2)) * grow
                amp[r, 0] = 2.0 * np.sqrt(np.sum(Q0[r] ** 2)) * grow
        else:
            curv = _taylor_sup(Q2, T, h)
            K3[:, st:st + sz] = _taylor_sup(Q3, T, h)
            if has_amp:
                amp = 2.0 * _taylor_sup(Q0, T, h)
        # per level the smaller of the two (the parabola's largest value is a quarter of C)
        for r in range(n_rows):
            a_sum = amp[r].sum()
            c_sum = curv[r].sum()
            for lev in range(levels + 1):
                if has_amp and a_sum < 0.25 * half_dt2[lev] * c_sum:
                    KU[r, lev, st:st + sz] = amp[r] * (1.0 + MARGIN)
                else:
                    KP[r, lev, st:st + sz] = curv[r] * (half_dt2[lev] * (1.0 + MARGIN))
    return KU, KP, K3 * (1.0 + MARGIN)


@njit(cache=True)
def _expm(T, t):
    """``e^{T t}`` by scaling, a Taylor series and squaring (small blocks; the rounding of the
    result is covered by :data:`MARGIN`)."""
    m = T.shape[0]
    norm = 0.0
    for i in range(m):
        norm = max(norm, np.abs(T[i]).sum() * t)
    s = 0
    while norm > 0.5:
        norm /= 2.0
        s += 1
    M = T * (t / 2.0 ** s)
    E = np.eye(m)
    term = np.eye(m)
    for k in range(1, 21):
        term = term @ M / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


@njit(cache=True)
def _assemble(Z, X, k, lam, V):
    """:func:`_decompose` after the Schur form ``Z`` (its first ``k`` columns the slow invariant
    subspace), the Sylvester solution ``X`` and the eigenpairs ``lam, V`` of the fast diagonal
    block, compiled (the setup runs once per configuration and batch variant): the fast block's
    real modal basis ``Q`` (:func:`_fast_blocks`), ``S``, ``Y`` and the blocks as arrays
    ``(start, size, kind)``, with the same fall-backs."""
    n = Z.shape[0]
    m = n - k
    lam_abs = np.abs(lam)
    fast_ok = True
    for i in range(m):                    # clusters (a pair's two members belong together)
        dmin = np.inf
        for j in range(m):
            if j == i:
                continue
            if lam[i].imag != 0 and abs(lam[i] - np.conj(lam[j])) <= 1e-12 * lam_abs[i]:
                continue
            dmin = min(dmin, abs(lam[i] - lam[j]))
        if dmin <= _CLUSTER * lam_abs[i]:
            fast_ok = False
    Q = np.zeros((m, m))
    fstart = np.zeros(m, dtype=np.int64)
    fsize = np.zeros(m, dtype=np.int64)
    nb = 0
    ncol = 0
    if fast_ok:
        for i in range(m):
            if lam[i].imag > 0:
                if ncol + 2 > m:
                    fast_ok = False
                    break
                a = np.ascontiguousarray(V[:, i].real)
                b = np.ascontiguousarray(V[:, i].imag)
                phi = 0.5 * math.atan2(2 * (a @ b), (a @ a) - (b @ b))
                v = V[:, i] * np.exp(-1j * phi)
                c0 = np.ascontiguousarray(v.real)
                scale = np.linalg.norm(c0)
                Q[:, ncol] = c0 / scale
                Q[:, ncol + 1] = v.imag / scale
                fstart[nb], fsize[nb] = ncol, 2
                nb += 1
                ncol += 2
            elif lam[i].imag == 0:
                if ncol + 1 > m:
                    fast_ok = False
                    break
                c0 = np.ascontiguousarray(V[:, i].real)
                Q[:, ncol] = c0 / np.linalg.norm(c0)
                fstart[nb], fsize[nb] = ncol, 1
                nb += 1
                ncol += 1
        if ncol != m:
            fast_ok = False
    if fast_ok:
        Qinv = np.linalg.inv(Q)
        cq = np.abs(Q).sum(axis=0).max() * np.abs(Qinv).sum(axis=0).max()
        if cq > _COND_MAX:
            fast_ok = False
    if not fast_ok:
        Q = np.eye(m)
        fstart[0], fsize[0] = 0, m
        nb = 1
    S = Z.copy()
    ZX = np.ascontiguousarray(Z[:, :k]) @ X if k else np.zeros((n, m))
    S[:, k:] = (ZX + Z[:, k:]) @ Q
    Y = np.ascontiguousarray(Z.T)
    if k:
        Y[:k] -= X @ np.ascontiguousarray(Z[:, k:].T)
    Y[k:] = np.linalg.solve(Q, np.ascontiguousarray(Z[:, k:].T))
    cs = np.abs(S).sum(axis=0).max() * np.abs(Y).sum(axis=0).max()
    nblk = nb + (1 if k else 0)
    bstart = np.zeros(nblk, dtype=np.int64)
    bsize = np.zeros(nblk, dtype=np.int64)
    bkind = np.zeros(nblk, dtype=np.int64)
    if not (np.isfinite(S).all() and np.isfinite(Y).all()) or cs > _COND_MAX:
        bsize1 = np.array([n], dtype=np.int64)
        return np.eye(n), np.eye(n), np.zeros(1, dtype=np.int64), bsize1, np.zeros(1, dtype=np.int64)
    o = 0
    if k:
        bstart[0], bsize[0], bkind[0] = 0, k, _SLOW_BLOCK
        o = 1
    for j in range(nb):
        bstart[o + j] = k + fstart[j]
        bsize[o + j] = fsize[j]
        bkind[o + j] = _EUCLID_BLOCK if fast_ok else _GENERAL_BLOCK
    return S, Y, bstart, bsize, bkind


def _decompose_arrays(A: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    """:func:`_decompose` with the blocks as arrays ``bstart, bsize, bkind``: the Schur form,
    the Sylvester equation and the eigensolve in LAPACK, the rest compiled (:func:`_assemble`);
    falls back to :func:`_decompose` wherever the compiled path cannot decide (a singular basis)."""
    n = A.shape[0]
    slow = lambda re, im: bool(math.hypot(re, im) * h <= SLOW)  # noqa: E731
    if n == 0 or not np.isfinite(A).all():
        return _reference_arrays(A, h)
    # LAPACK's dgees and dgeev as scipy.linalg.schur and numpy's eig call them, without their
    # wrappers' overhead (a few µs each, paid per configuration and batch variant)
    T, k, _, _, Z, _, info = _dgees(slow, A, sort_t=1, overwrite_a=0)
    if info != 0:
        return _reference_arrays(A, h)
    if k == n:
        return (np.eye(n), np.eye(n), np.zeros(1, dtype=np.int64), np.array([n], dtype=np.int64),
                np.zeros(1, dtype=np.int64))
    X = np.zeros((k, n - k))
    if k:
        X, scale, info = scipy.linalg.lapack.dtrsyl(T[:k, :k], T[k:, k:], -T[:k, k:], isgn=-1)
        if info < 0 or not scale > 0:
            return (np.eye(n), np.eye(n), np.zeros(1, dtype=np.int64),
                    np.array([n], dtype=np.int64), np.zeros(1, dtype=np.int64))
        X = X / scale
    wr, wi, _, vr, info = _dgeev(T[k:, k:], compute_vl=0, compute_vr=1)
    if info != 0:
        return _reference_arrays(A, h)
    try:
        return _assemble(np.ascontiguousarray(Z), np.ascontiguousarray(X), k,
                         *_eigenpairs(wr, wi, vr))
    except Exception:  # noqa: BLE001 - a singular basis: the reference path decides
        return _reference_arrays(A, h)


_dgees = scipy.linalg.lapack.dgees
_dgeev = scipy.linalg.lapack.dgeev


@njit(cache=True)
def _eigenpairs(wr, wi, vr):
    """Eigenvalues and right eigenvectors from dgeev's real output, as numpy's ``eig`` forms
    them (a complex pair's vectors are ``vr[:, j] ± i vr[:, j+1]``)."""
    m = wr.shape[0]
    lam = np.empty(m, dtype=np.complex128)
    V = np.empty((m, m), dtype=np.complex128)
    j = 0
    while j < m:
        if wi[j] != 0.0 and j + 1 < m:
            lam[j] = complex(wr[j], wi[j])
            lam[j + 1] = complex(wr[j + 1], wi[j + 1])
            for i in range(m):
                V[i, j] = complex(vr[i, j], vr[i, j + 1])
                V[i, j + 1] = complex(vr[i, j], -vr[i, j + 1])
            j += 2
        else:
            lam[j] = complex(wr[j], wi[j])
            for i in range(m):
                V[i, j] = complex(vr[i, j], 0.0)
            j += 1
    return lam, V


def _reference_arrays(A: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    """:func:`_decompose` (the reference path, with scipy's and numpy's checks) as arrays."""
    S, Y, blocks = _decompose(A, h)
    return (S, Y) + tuple(np.array(col, dtype=np.int64) for col in zip(
        *((st, sz, _KINDS[kind]) for st, sz, kind in blocks)))


@njit(cache=True)
def _configuration(PEc, Lc, Gv, c, S, Y, bstart, bsize, bkind, h, levels,
                   PsiT, KU, KP, K3, D, pair):
    """Every bound of :func:`curvature_bounds` for one configuration ``c`` (``PEc = [A_c B_c]``,
    ``Lc`` its holding-force rows, ``Gv`` the sliding-velocity rows) into the output slices;
    compiled: it runs once per configuration and batch variant."""
    nx = PEc.shape[0]
    nf = Lc.shape[0]
    A = np.ascontiguousarray(PEc[:, :nx])
    Psi = Y @ PEc
    PsiT[:, :] = Psi.T
    for b in range(bstart.shape[0]):
        if bkind[b] == _EUCLID_BLOCK and bsize[b] == 2:
            pair[bstart[b]] = 1
    R = np.empty((nf, nx))
    for j in range(nf):
        if (c >> j) & 1:
            R[j] = Lc[j, :nx]
        else:
            R[j] = Gv[j]
    ku, kp, k3 = _coefficients(R, Y, S, A, bstart, bsize, bkind, h, levels)
    KU[:] = ku
    KP[:] = kp
    K3[:] = k3
    D[:, 0] = R @ PEc
    D[:, 1] = (R @ A) @ PEc


def curvature_bounds(PE: np.ndarray, L: np.ndarray, G: np.ndarray, step: float,
                     levels: int) -> tuple[np.ndarray, ...]:
    """The kernel's in-step event bounds of every stick configuration of stacked parts.

    Parameters
    ----------
    PE : ndarray, shape (n_parts, 2**nf, nx, nz)
        ``[A_c B_c]`` of each configuration (see :func:`sicomat.simulation.continuous._constrained_all`).
    L : ndarray, shape (n_parts, 2**nf, nf, nz)
        Holding-force rows.
    G : ndarray, shape (n_parts, nf, nx)
        Sliding-velocity rows.
    step : float
        Base step h (s): the bounds hold over any segment of length <= h.
    levels : int
        Sub-steps ``h / 2**l``, ``l = 0..levels``.

    Returns
    -------
    PsiT : ndarray, shape (n_parts, 2**nf, nz, nx)
        ``Psiᵀ`` (the kernel computes ``ξ = Psi z`` column-wise).
    KU, KP : ndarray, shape (n_parts, 2**nf, nf, levels + 1, nx)
        On a sub-step of level ``l`` of a segment in configuration ``c``, link ``j``'s event
        function (holding force when stuck in c, else velocity) lies within
        ``KU[c, j, l] @ |ξ| + τ (1 - τ) KP[c, j, l] @ |ξ|`` of its chord.
    K3 : ndarray, shape (n_parts, 2**nf, nf, nx)
        ``sup |g_j'''| <= K3[c, j] @ |ξ|`` over the segment.
    D : ndarray, shape (n_parts, 2**nf, nf, 2, nz)
        ``g_j' = D[c, j, 0] @ z`` and ``g_j'' = D[c, j, 1] @ z`` at any instant of a segment.
    pair : ndarray of int8, shape (n_parts, 2**nf, nx)
        1 where coordinates ``i, i+1`` form a Euclidean pair (``|ξ|_i`` is their norm, the
        coefficients at ``i + 1`` are 0), else 0.
    """
    n_parts, nc, nx, nz = PE.shape
    nf = L.shape[2]
    PsiT = np.zeros((n_parts, nc, nz, nx))
    KU = np.zeros((n_parts, nc, nf, levels + 1, nx))
    KP = np.zeros((n_parts, nc, nf, levels + 1, nx))
    K3 = np.zeros((n_parts, nc, nf, nx))
    D = np.zeros((n_parts, nc, nf, 2, nz))
    pair = np.zeros((n_parts, nc, nx), dtype=np.int8)
    PE = np.ascontiguousarray(PE, dtype=float)
    L = np.ascontiguousarray(L, dtype=float)
    G = np.ascontiguousarray(G, dtype=float)
    for v in range(n_parts):
        for c in range(nc):
            S, Y, bstart, bsize, bkind = _decompose_arrays(PE[v, c, :, :nx], step)
            _configuration(PE[v, c], L[v, c], G[v], c, np.ascontiguousarray(S), np.ascontiguousarray(Y),
                           bstart, bsize, bkind, float(step), int(levels), PsiT[v, c], KU[v, c], KP[v, c],
                           K3[v, c], D[v, c], pair[v, c])
    return tuple(np.ascontiguousarray(a) for a in (PsiT, KU, KP, K3, D, pair))
