"""Exact (zero-order-hold) discretisation of a program's continuous part for every stick configuration."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from sicomat.errors import ModelError
from sicomat.simulate.program import ContinuousPart

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

    @property
    def n_configurations(self) -> int:
        """Number of stick configurations, ``2**nf``."""
        return int(self.Phi.shape[-4])


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


def _constrained(A: np.ndarray, B: np.ndarray, F: np.ndarray, G: np.ndarray,
                 mask: int) -> ConstrainedDynamics:
    nx, nf = F.shape
    nu = B.shape[1]
    stuck = np.array([(mask >> j) & 1 == 1 for j in range(nf)], dtype=bool)
    F_slip = F.copy()
    F_slip[:, stuck] = 0.0
    E = np.hstack([A, B, F_slip])                      # ẋ = E [x; u; f] without constraints
    if stuck.any():
        F_S, G_S = F[:, stuck], G[stuck, :]
        W_pinv = np.linalg.pinv(G_S @ F_S)
        P = np.eye(nx) - F_S @ W_pinv @ G_S
        L_S = -W_pinv @ G_S @ E
    else:
        P = np.eye(nx)
        L_S = np.zeros((0, E.shape[1]))
    L = np.zeros((nf, E.shape[1]))
    L[stuck, :] = L_S
    PE = P @ E
    return ConstrainedDynamics(mask=mask, A=PE[:, :nx], B=PE[:, nx:],
                               Lx=L[:, :nx], Lu=L[:, nx:nx + nu], Lf=L[:, nx + nu:], projection=P)


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
    A, B, F, G = _matrices(part)
    if not 0 <= mask < 2 ** F.shape[1]:
        raise ModelError(f"stick configuration must be in [0, {2 ** F.shape[1]})", value=mask)
    return _constrained(A, B, F, G, mask)


def _zoh(Ac: np.ndarray, Bc: np.ndarray, step: float, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """ZOH of stacked ``(..., nx, nx)``, ``(..., nx, nw)`` at ``step / 2**l``; adds a level axis."""
    nx, nw = Ac.shape[-1], Bc.shape[-1]
    n = nx + nw
    lead = Ac.shape[:-2]
    M = np.zeros(lead + (n, n))
    M[..., :nx, :nx] = Ac
    M[..., :nx, nx:] = Bc
    dts = step / 2.0 ** np.arange(levels + 1)
    Ml = M[..., None, :, :] * dts.reshape((1,) * len(lead) + (-1, 1, 1))
    if n == 0:
        E = Ml
    else:
        E = scipy.linalg.expm(Ml.reshape(-1, n, n)).reshape(Ml.shape)
    return (np.ascontiguousarray(E[..., :nx, :nx]), np.ascontiguousarray(E[..., :nx, nx:]))


def _check_step(step: float, levels: int) -> None:
    if not (np.isfinite(step) and step > 0):
        raise ModelError("step must be a positive finite time (s)", value=step)
    if not 0 <= levels <= 30:
        raise ModelError("levels must be in 0..30", value=levels)


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
    return _discretize_arrays([part], step, levels, links, stacked=False)


def discretize_many(parts: Sequence[ContinuousPart], step: float, levels: int = DEFAULT_LEVELS, *,
                    links: Sequence[int] | None = None) -> Discretization:
    """:func:`discretize` for variants of the same shapes, in one batched matrix exponential.

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
    return _discretize_arrays(list(parts), step, levels, links, stacked=True)


def _discretize_arrays(parts: list[ContinuousPart], step: float, levels: int,
                       links: Sequence[int] | None, stacked: bool) -> Discretization:
    _check_step(step, levels)
    if not parts:
        raise ModelError("no continuous part to discretise")
    sel = None if links is None else np.asarray(links, dtype=int)
    mats = [_matrices(p, sel) for p in parts]
    shapes = {(m[0].shape, m[1].shape, m[2].shape) for m in mats}
    if len(shapes) != 1:
        raise ModelError(f"variants must share their continuous shapes, got {sorted(shapes)}")
    nv = len(parts)
    A0, B0, F0, _ = mats[0]
    nx, nu, nf = A0.shape[0], B0.shape[1], F0.shape[1]
    nc = 2 ** nf
    Ac = np.empty((nv, nc, nx, nx))
    Bc = np.empty((nv, nc, nx, nu + nf))
    Lx = np.empty((nv, nc, nf, nx))
    Lu = np.empty((nv, nc, nf, nu))
    Lf = np.empty((nv, nc, nf, nf))
    Pr = np.empty((nv, nc, nx, nx))
    for v, (A, B, F, G) in enumerate(mats):
        if nf == 0:
            Ac[v, 0], Bc[v, 0], Pr[v, 0] = A, B, np.eye(nx)
            continue
        for c in range(nc):
            d = _constrained(A, B, F, G, c)
            Ac[v, c], Bc[v, c], Lx[v, c], Lu[v, c], Lf[v, c], Pr[v, c] = (
                d.A, d.B, d.Lx, d.Lu, d.Lf, d.projection)
    Phi, Gamma = _zoh(Ac, Bc, float(step), int(levels))
    arrays = (Phi, Gamma, Lx, Lu, Lf, Pr)
    if not stacked:
        arrays = tuple(a[0] for a in arrays)
    return Discretization(float(step), int(levels), *(np.ascontiguousarray(a) for a in arrays))
