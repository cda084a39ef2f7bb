"""The one rigid/flexible split: an additive decomposition ``G = D + rigid + flexible`` of a state
space, on a diagonally balanced, ordered real Schur form.

The plant is scaled (diagonal balancing), brought to real Schur form once, and split into decoupled
blocks by reordering the Schur form (LAPACK ``trsen``) and solving a Sylvester equation (``trsyl``):
no eigenvector of the full model is ever formed, so lightly damped or stiff models (stiffness ratios of
1e12) stay accurate. It separates the rigid-body part (poles at 0) for the frequency-response engine
(:mod:`sicomat.lti.response`), for modal and balanced truncation and for the reduction's error metrics.

**Cluster tolerance** (:data:`RIGID_TOL`): a pole is *at 0* when ``|λ| ≤ rigid_tol · max|λ|``
(``max|λ|`` of the balanced matrix, i.e. the fastest mode) and, for a real negative pole, when it is
also within its own round-off of 0 (``1e3·eps·‖T‖ / s(λ)``, ``s`` its reciprocal condition number):
a double pole at 0 is computed to ``sqrt(eps)·max|λ| ≈ 1.5e-8 max|λ|``, the default ``1e-6`` leaves a
margin of ~70 above that and lies far below any flexible mode of a feed axis. A block of poles at 0
only is made exactly nilpotent (:func:`nilpotent`, a change of the order of that round-off).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

from ..errors import AnalysisError, ModelError
from .plant import Plant

__all__ = ["RIGID_TOL", "StateBlock", "SpectralSplit", "spectral_split", "split_state_space",
           "schur_eigenvalues", "schur_triplet", "split_block", "select_positions", "nilpotent"]

RIGID_TOL = 1e-6
"""Default relative tolerance: poles with ``|λ| ≤ RIGID_TOL · max|λ|`` are rigid-body poles at 0.

A double pole at 0 (a free rigid mode) is computed to about ``sqrt(eps) · max|λ| ≈ 1.5e-8 max|λ|``;
the default leaves a margin of ~70 above that and is far below any flexible mode of a feed axis.
"""

_STABILITY_TOL = 1e-10  # poles with Re λ ≥ −_STABILITY_TOL·max|λ| are marginal (kept exactly by BT)


@dataclass(frozen=True, eq=False)
class StateBlock:
    """A block ``(A, B, C)`` of a block-diagonal realization; ``A`` is quasi-upper-triangular."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    @property
    def n(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (read from its quasi-triangular form)."""
        return schur_eigenvalues(self.A)


@dataclass(frozen=True, eq=False)
class SpectralSplit:
    """Additive decomposition ``G(s) = D + C₀(sI−A₀)⁻¹B₀ + C₁(sI−A₁)⁻¹B₁``.

    Attributes
    ----------
    rigid : StateBlock
        The poles at 0 (rigid-body modes), or also the marginal/unstable poles when asked; its
        ``A`` is made exactly nilpotent when it only holds poles at 0.
    flexible : StateBlock
        The remaining (stable) part, in real Schur form.
    D : ndarray
        Feedthrough ``(ny, nu)``.
    """

    rigid: StateBlock
    flexible: StateBlock
    D: np.ndarray

    def dc_gain(self) -> np.ndarray:
        """Static gain of the flexible part, ``D − C₁ A₁⁻¹ B₁`` (finite even with rigid modes)."""
        f = self.flexible
        if f.n == 0:
            return np.array(self.D, dtype=float)
        return self.D - f.C @ scipy.linalg.solve(f.A, f.B)


# --------------------------------------------------------------------------- Schur machinery
def schur_eigenvalues(T: np.ndarray) -> np.ndarray:
    """Eigenvalues of a quasi-upper-triangular matrix, one per diagonal position (vectorised)."""
    lam = np.diag(T).astype(complex)
    n = T.shape[0]
    if n < 2:
        return lam
    starts = np.flatnonzero(np.diag(T, -1) != 0.0)
    if starts.size:
        a, d = T[starts, starts], T[starts + 1, starts + 1]
        b, c = T[starts, starts + 1], T[starts + 1, starts]
        mid = 0.5 * (a + d)
        root = np.sqrt(complex(1.0) * (0.25 * (a - d) ** 2 + b * c))
        lam[starts] = mid + root
        lam[starts + 1] = mid - root
        swap = lam[starts].imag < 0  # positive imaginary part first
        lam[starts[swap]], lam[starts[swap] + 1] = lam[starts[swap] + 1], lam[starts[swap]]
    return lam


def schur_triplet(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T, B̃, C̃)``: the realization ``(A, B, C)`` scaled by diagonal balancing, in real Schur form."""
    A, B, C = (np.array(X, dtype=float) for X in (A, B, C))
    if A.shape[0] == 0:
        return A, B, C
    if not np.all(np.isfinite(A)):
        raise ModelError("the plant's state matrix has non-finite entries")
    _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    A = (A * scale[None, :]) / scale[:, None]  # diag(scale)⁻¹ A diag(scale)
    T, Z = scipy.linalg.schur(A, output="real", check_finite=False)
    return T, Z.T @ (B / scale[:, None]), (C * scale[None, :]) @ Z


def _reorder(T: np.ndarray, B: np.ndarray, C: np.ndarray, select: np.ndarray):
    """Move the selected eigenvalues to the top-left of ``T`` (orthogonal; LAPACK ``trsen``)."""
    n = T.shape[0]
    if select.all() or not select.any():
        return T, B, C, int(select.sum())
    ts, qs, _, _, m, _, _, info = lapack.dtrsen(select.astype(np.int32), T, np.eye(n), job="N",
                                                lwork=max(1, n), liwork=1)
    if info != 0:
        raise AnalysisError("cannot separate the modes: the Schur form could not be reordered "
                            f"(LAPACK trsen info={info}; eigenvalues too close to each other)")
    return ts, qs.T @ B, C @ qs, int(m)


def _decouple(T: np.ndarray, B: np.ndarray, C: np.ndarray, m: int) -> tuple[StateBlock, StateBlock]:
    """Block-diagonalise ``[[T11, T12], [0, T22]]`` with ``T11 Y − Y T22 = −T12`` (LAPACK ``trsyl``)."""
    T11, T12, T22 = T[:m, :m], T[:m, m:], T[m:, m:]
    B1, B2, C1, C2 = B[:m], B[m:], C[:, :m], C[:, m:]
    if m == 0 or m == T.shape[0]:
        return StateBlock(T11, B1, C1), StateBlock(T22, B2, C2)
    Y, scale, info = lapack.dtrsyl(T11, T22, -T12, isgn=-1)
    if info != 0 or not np.all(np.isfinite(Y)):
        raise AnalysisError("cannot separate the modes: the two groups of poles are too close "
                            f"(LAPACK trsyl info={info})")
    Y = Y / scale
    return StateBlock(T11, B1 - Y @ B2, C1), StateBlock(T22, B2, C1 @ Y + C2)


def split_block(block: StateBlock, select: np.ndarray) -> tuple[StateBlock, StateBlock]:
    """Two decoupled blocks: the selected eigenvalues (``select`` per diagonal position), the rest."""
    T, B, C, m = _reorder(block.A, block.B, block.C, select)
    return _decouple(T, B, C, m)


def select_positions(T: np.ndarray, predicate) -> np.ndarray:
    """Boolean selection per diagonal position, consistent over the 2×2 blocks of complex pairs."""
    lam = schur_eigenvalues(T)
    return _pairs_together(T, np.array([bool(predicate(v)) for v in lam], dtype=bool))


def _reciprocal_condition(T: np.ndarray, position: int) -> float:
    """Reciprocal condition number of the real eigenvalue at ``position`` of a Schur form (``trsen``)."""
    n = T.shape[0]
    if n == 1:
        return 1.0
    select = np.zeros(n, dtype=np.int32)
    select[position] = 1
    out = lapack.dtrsen(select, T, np.eye(n), job="E", wantq=0, lwork=max(1, 2 * (n - 1)), liwork=1)
    s, info = out[5], out[-1]
    return float(s) if info == 0 and s > 0 else np.finfo(float).eps


def nilpotent(T: np.ndarray) -> np.ndarray:
    """The nearest strictly quasi-triangular matrix with all eigenvalues exactly 0 (tiny change)."""
    out = np.triu(T, 1)
    for i in np.flatnonzero(np.diag(T, -1) != 0.0) if T.shape[0] > 1 else ():
        if abs(T[i + 1, i]) > abs(T[i, i + 1]):  # keep the larger off-diagonal entry of the 2×2 block
            out[i, i + 1] = 0.0
            out[i + 1, i] = T[i + 1, i]
    return out


def spectral_split(plant: Plant, *, rigid_tol: float = RIGID_TOL, marginal: bool = False) -> SpectralSplit:
    """Split a plant into its rigid-body part (poles at 0) and the rest.

    A rigid-body mode has two states: its poles are a double pole at 0 or, when it is damped to
    the frame (viscous guides), a pole at 0 and a slow real pole ``−c/m``. The rigid part therefore
    holds the poles at 0 and, for each of them, at most one real pole slower than a tenth of the
    slowest oscillating mode (the slowest real poles when nothing oscillates). So "a rigid mode and one flexible mode make 4 states", and the static
    gain of the flexible part is the structure's compliance.

    Parameters
    ----------
    plant : Plant
        Any continuous plant.
    rigid_tol : float, optional
        Poles with ``|λ| ≤ rigid_tol · max|λ|`` are taken as exactly 0 (see :data:`RIGID_TOL`).
    marginal : bool, optional
        Also put the poles with ``Re λ ≥ −1e-10 · max|λ|`` (undamped modes, unstable poles) in the
        first block, so that the second one is strictly stable (for Gramians).

    Returns
    -------
    SpectralSplit
        ``rigid`` holds the rigid-body poles (and the marginal ones if asked), its poles at 0 made
        exactly 0; ``flexible`` the rest, in real Schur form.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[1, 1], stiffnesses=[100],
    ...                                   dampings=[0.1])).state_space()
    >>> split = spectral_split(plant)
    >>> split.rigid.n, split.flexible.n, bool(np.all(split.rigid.poles() == 0))
    (2, 2, True)
    """
    return split_state_space(plant.A, plant.B, plant.C, plant.D, rigid_tol=rigid_tol, marginal=marginal)


def split_state_space(A, B, C, D, *, rigid_tol: float = RIGID_TOL, marginal: bool = False) -> SpectralSplit:
    """:func:`spectral_split` of the realization ``(A, B, C, D)`` (arrays, no signal names)."""
    T, B, C = schur_triplet(A, B, C)
    D = np.array(D, dtype=float)
    if T.shape[0] == 0:
        empty = StateBlock(T, B, C)
        return SpectralSplit(empty, empty, D)
    lam = schur_eigenvalues(T)
    rho = max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    is_zero = np.abs(lam) <= rigid_tol * rho
    for i in np.flatnonzero(is_zero & (lam.imag == 0) & (lam.real < 0)):
        # a slow real pole is a pole at 0 only if it is within its own round-off of 0: the velocity
        # pole −c/m of a rigid motion with viscous guides is well conditioned and stays, while a
        # rigid pole pushed off 0 by the round-off of K's row sums has a tiny reciprocal condition
        if abs(lam[i]) > 1e3 * np.finfo(float).eps * np.linalg.norm(T) / _reciprocal_condition(T, int(i)):
            is_zero[i] = False
    n_zero = int(is_zero.sum())
    first = is_zero.copy()
    if n_zero:  # one slow real companion per pole at 0 at most, slower than a tenth of any oscillation
        real = lam.imag == 0
        osc = np.abs(lam[~real & ~is_zero])
        slow = np.flatnonzero(real & ~is_zero & (lam.real < 0))
        slow = slow[np.argsort(np.abs(lam[slow]))][:n_zero]
        if osc.size:
            slow = slow[np.abs(lam[slow]) <= 0.1 * osc.min()]
        first[slow] = True
    if marginal:
        first |= lam.real >= -_STABILITY_TOL * rho
    block, second = split_block(StateBlock(T, B, C), _pairs_together(T, first))
    if n_zero == block.n:
        block = StateBlock(nilpotent(block.A), block.B, block.C)
    elif n_zero:  # the poles at 0 first inside the first block (the smallest ones), made exactly 0
        mags = np.abs(schur_eigenvalues(block.A))
        smallest = np.zeros(block.n, dtype=bool)
        smallest[np.argsort(mags, kind="stable")[:n_zero]] = True
        zeros, others = split_block(block, _pairs_together(block.A, smallest))
        A = scipy.linalg.block_diag(nilpotent(zeros.A), others.A)
        block = StateBlock(A, np.vstack([zeros.B, others.B]), np.hstack([zeros.C, others.C]))
    return SpectralSplit(block, second, D)


def _pairs_together(T: np.ndarray, select: np.ndarray) -> np.ndarray:
    """The selection extended so that both positions of each 2×2 block agree."""
    select = np.array(select, dtype=bool)
    if T.shape[0] > 1:
        starts = np.flatnonzero(np.diag(T, -1) != 0.0)
        pair = select[starts] | select[starts + 1]
        select[starts] = pair
        select[starts + 1] = pair
    return select
