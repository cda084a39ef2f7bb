"""Exact (zero-order-hold) discretisation of a program's continuous part for every stick configuration."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numba import njit

from sicomat.errors import ModelError
from .envelope import curvature_bounds
from ..servo.program import ContinuousPart

__all__ = ["MAX_FRICTION_LINKS", "DEFAULT_LEVELS", "ConstrainedDynamics", "Discretization",
           "active_links", "constrained_dynamics", "discretize", "discretize_many"]

MAX_FRICTION_LINKS = 6
"""Most friction links a continuous part may have: the kernel enumerates all ``2**nf`` configurations."""

DEFAULT_LEVELS = 10
"""Default depth of the binary step fractions: events are located to ``h / 2**10``."""


@dataclass(frozen=True, eq=False)
class ConstrainedDynamics:
    """The continuous dynamics with the links of one stick configuration held at zero sliding velocity.

    With ``S`` the stuck links, ``W = G_S F_S`` and ``P = I - F_S W⁺ G_S``:
    ``ẋ = P (A x + B u + F_slip f)``, ``F_slip`` being ``F`` with the stuck columns zeroed; the
    constraint (friction) force of the stuck links is ``λ_S = -W⁺ G_S (A x + B u + F_slip f)``.

    Attributes
    ----------
    mask : int
        The configuration: bit ``j`` set when link ``j`` is stuck.
    A : ndarray, shape (nx, nx)
        ``P A``.
    B : ndarray, shape (nx, nu + nf)
        ``[P B, P F_slip]``: the held inputs, then the sliding links' friction forces.
    Lx, Lu, Lf : ndarray, shapes (nf, nx), (nf, nu), (nf, nf)
        ``λ = Lx x + Lu u + Lf f``; rows of the sliding links and columns of the stuck links are zero.
    projection : ndarray, shape (nx, nx)
        ``P``: applied to the state when the links of ``S`` become stuck (for a mechanical system
        with ``F_j = [0; M⁻¹ g_j]``, ``G_j = [0, g_jᵀ]`` it conserves momentum).
    """

    mask: int
    A: np.ndarray
    B: np.ndarray
    Lx: np.ndarray
    Lu: np.ndarray
    Lf: np.ndarray
    projection: np.ndarray


@dataclass(frozen=True, eq=False)
class Discretization:
    """ZOH matrices of every stick configuration at the step fractions ``h / 2**l``, ``l = 0..levels``.

    Configuration ``c`` has link ``j`` stuck when bit ``j`` of ``c`` is set. Over a sub-step of
    length ``h / 2**l`` in configuration ``c`` with held ``w = [u; f]`` (inputs, then the friction
    forces of the sliding links), ``x+ = Phi[c, l] @ x + Gamma[c, l] @ w``. A leading variant axis is
    present when built by :func:`discretize_many`.

    Attributes
    ----------
    step : float
        Base step h (s).
    levels : int
        Finest fraction is ``h / 2**levels``.
    Phi : ndarray, shape ([n_variants,] 2**nf, levels + 1, nx, nx)
    Gamma : ndarray, shape ([n_variants,] 2**nf, levels + 1, nx, nu + nf)
    Lx : ndarray, shape ([n_variants,] 2**nf, nf, nx)
    Lu : ndarray, shape ([n_variants,] 2**nf, nf, nu)
    Lf : ndarray, shape ([n_variants,] 2**nf, nf, nf)
    projection : ndarray, shape ([n_variants,] 2**nf, nx, nx)
    """

    step: float
    levels: int
    Phi: np.ndarray
    Gamma: np.ndarray
    Lx: np.ndarray
    Lu: np.ndarray
    Lf: np.ndarray
    projection: np.ndarray


def active_links(part: ContinuousPart) -> np.ndarray:
    """Indices of the friction links that act (``coulomb > 0`` or ``static > 0``).

    Parameters
    ----------
    part : ContinuousPart

    Returns
    -------
    ndarray of int
    """
    coulomb = np.asarray(part.coulomb, dtype=float).reshape(-1)
    static = np.asarray(part.static, dtype=float).reshape(-1)
    if coulomb.shape != static.shape:
        raise ModelError(f"coulomb and static must have the same length, got {coulomb.size} and "
                         f"{static.size}")
    return np.flatnonzero((coulomb > 0) | (static > 0))


def _matrices(part: ContinuousPart, links: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """``A, B, F, G`` as float arrays with consistent shapes (``F, G`` restricted to ``links``)."""
    A = np.atleast_2d(np.asarray(part.A, dtype=float))
    nx = A.shape[0]
    if A.shape != (nx, nx):
        raise ModelError(f"A must be square, got shape {A.shape}")
    B = np.asarray(part.B, dtype=float).reshape(nx, -1) if np.size(part.B) else np.zeros((nx, 0))
    F = np.asarray(part.F, dtype=float).reshape(nx, -1) if np.size(part.F) else np.zeros((nx, 0))
    G = np.asarray(part.G, dtype=float).reshape(-1, nx) if np.size(part.G) else np.zeros((0, nx))
    if F.shape[1] != G.shape[0]:
        raise ModelError(f"F has {F.shape[1]} friction columns but G has {G.shape[0]} rows")
    if links is not None:
        F, G = F[:, links], G[links, :]
    if F.shape[1] > MAX_FRICTION_LINKS:
        raise ModelError(f"friction links must be at most {MAX_FRICTION_LINKS}: the kernel "
                         f"enumerates all 2**nf stick configurations", value=F.shape[1])
    return A, B, F, G


def _constrained_all(A: np.ndarray, B: np.ndarray, F: np.ndarray,
                     G: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constrained dynamics of stacked variants (leading axis of ``A, B, F, G``) for every
    stick configuration ``c`` (bit ``j`` set: link ``j`` stuck), see :class:`ConstrainedDynamics`.

    Returns ``PE = P [A B F_slip]``, ``L = [Lx Lu Lf]`` and ``P``, with leading axes
    ``(variant, configuration)``. The pseudo-inverses ``W⁺`` (``W = G_S F_S``, one stacked call per
    configuration) come from numpy, the rest from :func:`_constrained_products`.
    """
    nv, nx, nf = F.shape
    W_pinv = np.zeros((nv, 2 ** nf, nf, nf))
    for c in range(1, 2 ** nf):
        S = [j for j in range(nf) if (c >> j) & 1]
        W_pinv[:, c, :len(S), :len(S)] = np.linalg.pinv(G[:, S, :] @ F[:, :, S])
    return _constrained_products(A, B, F, G, W_pinv)


@njit(cache=True)
def _constrained_products(A, B, F, G, W_pinv):
    """:func:`_constrained_all` given ``W⁺`` of every variant and configuration (top-left block).

    Compiled loops: numpy costs ~100 µs per configuration in small array operations, more than
    the matrix exponentials that follow.
    """
    nv, nx = A.shape[0], A.shape[1]
    nu, nf = B.shape[2], F.shape[2]
    nz = nx + nu + nf
    nc = 1 << nf
    PE = np.empty((nv, nc, nx, nz))
    L = np.zeros((nv, nc, nf, nz))
    P = np.empty((nv, nc, nx, nx))
    E = np.empty((nx, nz))                         # ẋ = E [x; u; f] without constraints
    rows = np.empty(nf, dtype=np.int64)
    for v in range(nv):
        for c in range(nc):
            k = 0
            for j in range(nf):
                if (c >> j) & 1:
                    rows[k] = j
                    k += 1
            for i in range(nx):                         # E = [A B F_slip]
                for m in range(nx):
                    E[i, m] = A[v, i, m]
                for m in range(nu):
                    E[i, nx + m] = B[v, i, m]
                for j in range(nf):
                    E[i, nx + nu + j] = 0.0 if (c >> j) & 1 else F[v, i, j]
            # P = I - F_S W⁺ G_S;  L_S = -W⁺ G_S E
            for i in range(nx):
                for m in range(nx):
                    s = 0.0
                    for a in range(k):
                        fw = 0.0
                        for b in range(k):
                            fw += F[v, i, rows[b]] * W_pinv[v, c, b, a]
                        s += fw * G[v, rows[a], m]
                    P[v, c, i, m] = (1.0 if i == m else 0.0) - s
            for a in range(k):
                for m in range(nz):
                    s = 0.0
                    for i in range(nx):
                        wg = 0.0
                        for b in range(k):
                            wg += W_pinv[v, c, a, b] * G[v, rows[b], i]
                        s += wg * E[i, m]
                    L[v, c, rows[a], m] = -s
            for i in range(nx):
                for m in range(nz):
                    s = 0.0
                    for q in range(nx):
                        s += P[v, c, i, q] * E[q, m]
                    PE[v, c, i, m] = s
    return PE, L, P


def _stack(mats: list[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    if len(mats) == 1:
        return tuple(np.ascontiguousarray(a)[None] for a in mats[0])
    shapes = {(m[0].shape, m[1].shape, m[2].shape) for m in mats}
    if len(shapes) != 1:
        raise ModelError(f"variants must share their continuous shapes, got {sorted(shapes)}")
    return tuple(np.ascontiguousarray(np.stack(a)) for a in zip(*mats))


def constrained_dynamics(part: ContinuousPart, mask: int) -> ConstrainedDynamics:
    """The dynamics of ``part`` with the links of ``mask`` stuck (bit ``j`` set: link ``j`` stuck).

    Parameters
    ----------
    part : ContinuousPart
    mask : int
        Stick configuration, ``0 <= mask < 2**nf``.

    Returns
    -------
    ConstrainedDynamics

    Raises
    ------
    ModelError
        Inconsistent shapes, or more than :data:`MAX_FRICTION_LINKS` links.
    """
    A, B, F, G = _stack([_matrices(part)])
    if not 0 <= mask < 2 ** F.shape[2]:
        raise ModelError(f"stick configuration must be in [0, {2 ** F.shape[2]})", value=mask)
    nx, nu = B.shape[1:]
    PE, L, P = (a[0, mask] for a in _constrained_all(A, B, F, G))
    return ConstrainedDynamics(mask=mask, A=PE[:, :nx], B=PE[:, nx:], Lx=L[:, :nx],
                               Lu=L[:, nx:nx + nu], Lf=L[:, nx + nu:], projection=P)


def _direct_levels(levels: int) -> list[int]:
    """The levels whose ZOH is a matrix exponential: every third from the finest (the others are
    one or two squarings away, see :func:`_zoh`)."""
    return sorted(range(levels, -1, -3))


def _zoh(PE: np.ndarray, step: float, levels: int) -> np.ndarray:
    """ZOH of stacked ``ẋ = PE [x; w]`` (shape ``(..., nx, nx + nw)``) at ``step / 2**l``.

    Returns ``E`` of shape ``(..., levels + 1, n, n)``, ``n = nx + nw``:
    ``E[..., l, :, :] = expm([[PE], [0]] step / 2**l) = [[Phi, Gamma], [0, I]]``. Every third
    level from the finest down is a matrix exponential (10, 7, 4, 1 for ten levels); the two
    levels above each are its square and the square of that (``E(2t) = E(t)²``), level 0 the square
    of level 1. No level is more than two squarings from an exponential, which keeps the accuracy of
    an exponential at every level (``expm`` itself scales and squares: for the 5M4S servo it
    computes the whole step as a quarter step squared twice), whereas a chain of squarings from the
    finest level loses about ten times that on a stiff part; it costs less than half of an
    exponential per level.
    """
    nx, n = PE.shape[-2:]
    lead = PE.shape[:-2]
    direct = _direct_levels(levels)
    E = np.empty(lead + (levels + 1, n, n))
    if n == 0:
        return E
    dts = step / 2.0 ** np.array(direct)
    M = np.zeros(lead + (len(direct), n, n))
    M[..., :nx, :] = PE[..., None, :, :] * dts[:, None, None]
    E[..., direct, :, :] = scipy.linalg.expm(M.reshape(-1, n, n)).reshape(M.shape)
    for lev in range(levels - 1, -1, -1):
        if lev not in direct:
            E[..., lev, :, :] = E[..., lev + 1, :, :] @ E[..., lev + 1, :, :]
    return E


def _check_step(step: float, levels: int) -> None:
    if not (np.isfinite(step) and step > 0):
        raise ModelError("step must be a positive finite time (s)", value=step)
    if not 0 <= levels <= 30:
        raise ModelError("levels must be in 0..30", value=levels)


def _distinct(parts: Sequence[ContinuousPart],
              links: Sequence[int] | np.ndarray | None) -> tuple[list[tuple[np.ndarray, ...]], np.ndarray]:
    """The distinct ``A, B, F, G`` of ``parts`` (after ``links``) and the index of each part's."""
    sel = None if links is None else np.asarray(links, dtype=int)
    if len(parts) == 1:
        return [_matrices(parts[0], sel)], np.zeros(1, dtype=np.int64)
    mats: list[tuple[np.ndarray, ...]] = []
    seen: dict[tuple, int] = {}
    index = np.empty(len(parts), dtype=np.int64)
    for i, part in enumerate(parts):
        m = _matrices(part, sel)
        key = tuple((a.shape, a.tobytes()) for a in m)
        if key not in seen:
            seen[key] = len(mats)
            mats.append(m)
        index[i] = seen[key]
    return mats, index


def _discretized(parts: Sequence[ContinuousPart], step: float, levels: int,
                 links: Sequence[int] | np.ndarray | None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
    """``E`` (see :func:`_zoh`), ``L = [Lx Lu Lf]`` and projections of the distinct parts (leading
    axes ``(part, configuration)``), the index of each part's, and ``nx``.

    Variants that differ only in their discrete part (gains, limits, setpoints) share one continuous
    part: it is discretised once.
    """
    _check_step(step, levels)
    if not parts:
        raise ModelError("no continuous part to discretise")
    mats, index = _distinct(parts, links)
    A, B, F, G = _stack(mats)
    PE, L, P = _constrained_all(A, B, F, G)
    return _zoh(PE, float(step), int(levels)), L, P, index, A.shape[1], PE, G


def _kernel_layout(parts: Sequence[ContinuousPart], step: float, levels: int,
                   links: Sequence[int] | np.ndarray | None) -> tuple[np.ndarray, ...]:
    """The discretisation in the kernel's layout: ``[Phi Gamma]ᵀ`` (shape ``(n_distinct, 2**nf,
    levels + 1, nx + nw, nx)``), ``[Lx Lu Lf]``, the projections, for each part the index of its
    discretisation (equal parts share one), and the in-step event bounds ``PsiT, KU, KP, K3, D, pair`` of
    :func:`sicomat.simulation.envelope.curvature_bounds`."""
    E, L, P, index, nx, PE, G = _discretized(parts, step, levels, links)
    bounds = (curvature_bounds(PE, L, G, float(step), int(levels)) if L.shape[-2]
              else _no_bounds(PE, L))
    return (np.ascontiguousarray(np.swapaxes(E[..., :nx, :], -1, -2)), L, P, index) + bounds


def _no_bounds(PE: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, ...]:
    """Empty in-step bounds of parts without friction links (the kernel never reads them)."""
    n_parts, nc, nx, nz = PE.shape
    return (np.zeros((n_parts, nc, nz, nx)), np.zeros((n_parts, nc, 0, 1, nx)),
            np.zeros((n_parts, nc, 0, 1, nx)), np.zeros((n_parts, nc, 0, nx)),
            np.zeros((n_parts, nc, 0, 2, nz)), np.zeros((n_parts, nc, nx), dtype=np.int8))


def _discretization(E: np.ndarray, L: np.ndarray, P: np.ndarray, nx: int, step: float,
                    levels: int) -> Discretization:
    nu = E.shape[-1] - nx - L.shape[-2]
    arrays = (E[..., :nx, :nx], E[..., :nx, nx:], L[..., :nx], L[..., nx:nx + nu],
              L[..., nx + nu:], P)
    return Discretization(float(step), int(levels), *(np.ascontiguousarray(a) for a in arrays))


def discretize(part: ContinuousPart, step: float, levels: int = DEFAULT_LEVELS, *,
               links: Sequence[int] | None = None) -> Discretization:
    """Exact ZOH discretisation of ``part`` for every stick configuration and step fraction.

    Parameters
    ----------
    part : ContinuousPart
    step : float
        Base step h (s).
    levels : int, default 10
        Sub-steps ``h / 2**l`` for ``l = 0..levels`` are discretised.
    links : sequence of int, optional
        The friction links to keep (default: all of them).

    Returns
    -------
    Discretization

    Raises
    ------
    ModelError
        Inconsistent shapes, a bad step, or more than :data:`MAX_FRICTION_LINKS` friction links.
    """
    E, L, P, _, nx, _, _ = _discretized([part], step, levels, links)
    return _discretization(E[0], L[0], P[0], nx, step, levels)


def discretize_many(parts: Sequence[ContinuousPart], step: float, levels: int = DEFAULT_LEVELS, *,
                    links: Sequence[int] | None = None) -> Discretization:
    """:func:`discretize` for variants of the same shapes, in one batched matrix exponential.

    Equal parts are discretised once.

    Parameters
    ----------
    parts : sequence of ContinuousPart
        All with the same ``nx``, ``nu`` and ``nf``.
    step : float
    levels : int, default 10
    links : sequence of int, optional

    Returns
    -------
    Discretization
        With a leading variant axis on every array.
    """
    E, L, P, index, nx, _, _ = _discretized(list(parts), step, levels, links)
    return _discretization(E[index], L[index], P[index], nx, step, levels)
