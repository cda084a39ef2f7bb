"""Modal truncation with static-gain matching (paper III.C.1), on an ordered real Schur form.

The plant is scaled (diagonal balancing), brought to real Schur form once, and split into decoupled
blocks by reordering the Schur form (LAPACK ``trsen``) and solving a Sylvester equation (``trsyl``):
no eigenvector of the full model is ever formed, so lightly damped or stiff models (stiffness ratios of
1e12) stay accurate. The same split separates the rigid-body part (poles at 0) for balanced truncation
and for the error metrics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

from ..errors import AnalysisError, ModelError
from ..lti.plant import Plant

if TYPE_CHECKING:  # pragma: no cover
    from .error import ReductionResult

__all__ = ["StateBlock", "SpectralSplit", "spectral_split", "modal_truncation", "RIGID_TOL"]

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


def _schur(plant: Plant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Diagonally balanced real Schur form ``(T, B̃, C̃)`` of the plant."""
    return schur_triplet(plant.A, plant.B, plant.C)


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
    T, B, C = _schur(plant)
    D = np.array(plant.D, dtype=float)
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


# --------------------------------------------------------------------------- modal truncation
def _real_modal_form(block: StateBlock) -> tuple[StateBlock, np.ndarray]:
    """Block-diagonal real modal form of a small block, modes sorted by ``|λ|``.

    Returns the block and the pole of each mode (one entry per real pole or complex pair, Im ≥ 0).
    """
    n = block.n
    if n == 0:
        return block, np.zeros(0, complex)
    lam, V = np.linalg.eig(block.A)
    W = np.linalg.inv(V)
    order = np.lexsort((-lam.imag, np.abs(lam)))
    A = np.zeros((n, n))
    rows_v: list[np.ndarray] = []
    rows_w: list[np.ndarray] = []
    poles: list[complex] = []
    used = np.zeros(n, dtype=bool)
    tol = 1e-9 * max(np.max(np.abs(lam)), 1.0)
    for i in order:
        if used[i] or lam[i].imag < -tol:
            continue
        used[i] = True
        k = len(rows_v)
        if abs(lam[i].imag) <= tol:
            A[k, k] = lam[i].real
            rows_v.append(V[:, i].real)
            rows_w.append(W[i].real)
            poles.append(complex(lam[i].real))
        else:
            conj = int(np.argmin(np.where(used, np.inf, np.abs(lam - lam[i].conjugate()))))
            used[conj] = True
            s, w = lam[i].real, lam[i].imag
            A[k:k + 2, k:k + 2] = [[s, w], [-w, s]]
            rows_v += [V[:, i].real, V[:, i].imag]
            rows_w += [2.0 * W[i].real, -2.0 * W[i].imag]
            poles.append(lam[i])
    Vr = np.column_stack(rows_v)
    Wr = np.vstack(rows_w)
    return StateBlock(A, Wr @ block.B, block.C @ Vr), np.array(poles)


def modal_truncation(plant: Plant, order: int, *, band_hz: tuple[float, float] | None = None,
                     rigid_tol: float = RIGID_TOL, inputs: Sequence[str] | None = None,
                     outputs: Sequence[str] | None = None) -> "ReductionResult":
    """Remove the fastest modes and keep the static gain (paper III.C.1).

    The modes are the eigenvalues of A, sorted by natural frequency ``|λ|``; the slowest are kept
    (their poles are exactly those of the full model), the fastest are removed and their static
    contribution ``−C_f A_f⁻¹ B_f`` is added to the feedthrough, so the static gain is preserved.
    Rigid-body modes (poles at 0, whose static gain is infinite) are always kept and kept exactly;
    the static gain matched is then that of the flexible part.

    Parameters
    ----------
    plant : Plant
        The full model.
    order : int
        Number of states of the reduced model, rigid part included (a free rigid mode and one
        flexible mode make 4). A complex pair is never split: if ``order`` falls inside one, the
        reduced model has one state less, and ``warnings`` says so.
    band_hz : (float, float), optional
        Band of interest (Hz) for the reported band errors.
    rigid_tol : float, optional
        Relative tolerance for poles at 0 (see :data:`RIGID_TOL`).
    inputs, outputs : sequence of str, optional
        The transfer to reduce (see :func:`~sicomat.reduction.error.select_transfer`); all the
        plant's signals by default. The kept modes do not depend on it, the error figures do.

    Returns
    -------
    ReductionResult
        Reduced plant in real modal coordinates (states ``rigid.i``, ``mode<k>.a``/``.b``), with the
        error report.

    Raises
    ------
    ModelError
        ``order`` below the rigid part or above the model's number of states.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[1, 1, 1], stiffnesses=[1e4, 1e4],
    ...                                   dampings=[1, 1])).state_space()
    >>> res = modal_truncation(plant, 4)
    >>> res.order_after, res.dc_gain_error < 1e-12
    (4, True)
    """
    from .error import ReductionResult, check_band, select_transfer

    band_hz = check_band(band_hz)
    plant = select_transfer(plant, inputs, outputs)
    n = plant.n_states
    split = spectral_split(plant, rigid_tol=rigid_tol)
    rigid, flexible = split.rigid, split.flexible
    check_order(order, n, rigid.n, what="rigid-body part")
    warnings: list[str] = []

    lam = flexible.poles()
    budget = order - rigid.n
    # one entry per mode: (|λ|, positions); positions of a pair are adjacent in the Schur form
    modes: list[tuple[float, list[int]]] = []
    starts = set(np.flatnonzero(np.diag(flexible.A, -1) != 0.0).tolist()) if flexible.n > 1 else set()
    i = 0
    while i < flexible.n:
        if i in starts:
            modes.append((abs(lam[i]), [i, i + 1]))
            i += 2
        else:
            modes.append((abs(lam[i]), [i]))
            i += 1
    modes.sort(key=lambda m: m[0])
    select = np.zeros(flexible.n, dtype=bool)
    used = 0
    for magnitude, positions in modes:
        if used + len(positions) > budget:
            if used < budget:
                below = rigid.n + used
                warnings.append(f"order {order} would split the complex pole pair at "
                                f"{magnitude / (2 * np.pi):.6g} Hz; the reduced model has {below} states "
                                f"(a whole number of modes: order {below} or {below + len(positions)})")
            break
        select[positions] = True
        used += len(positions)
    kept, removed = split_block(flexible, select)

    D = split.D.copy()
    if removed.n:
        D = D - removed.C @ scipy.linalg.solve(removed.A, removed.B)  # static gain of the removed modes
    modal, poles = _real_modal_form(kept)
    names = [f"rigid.{k + 1}" for k in range(rigid.n)]
    for k, p in enumerate(poles, start=1):
        names += [f"mode{k}"] if p.imag == 0 else [f"mode{k}.a", f"mode{k}.b"]
    A = scipy.linalg.block_diag(rigid.A, modal.A)
    reduced = Plant(A, np.vstack([rigid.B, modal.B]), np.hstack([rigid.C, modal.C]), D, tuple(names),
                    plant.inputs, plant.outputs)
    return ReductionResult(method="modal", variant="truncation-dc-matched", full=plant, reduced=reduced,
                           band_hz=band_hz, warnings=tuple(warnings), rigid_tol=rigid_tol)


def check_order(order: int, n: int, n_exact: int, *, what: str) -> None:
    """Validate a requested number of states against the model and its exactly-kept part."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise ModelError("expected a whole number of states", path="order", value=order)
    if order > n:
        raise ModelError(f"the order is larger than the model: expected at most {n} states",
                         path="order", value=int(order))
    if order < max(n_exact, 1):
        raise ModelError(f"the order is too small: the {what} alone has {n_exact} states, which are "
                         f"always kept; expected at least {max(n_exact, 1)}", path="order", value=int(order))
