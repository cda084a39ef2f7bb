"""Gramian-based reduction (paper III.C.2): balanced truncation and its variants, with scipy only.

The state matrix is first scaled by diagonal balancing (stiffness ratios of 1e12 make the raw
matrix badly scaled). When it has no pole at 0 or on the imaginary axis and its eigenvectors are
well conditioned (the usual damped, grounded mechanics), the Gramians are written in closed form
in modal coordinates — Cauchy matrices ``−b̃_a b̃_bᴴ / (λ_a + λ̄_b)`` — and taken to the real
block-diagonal modal form: one eigen-decomposition and O(n²) work. Otherwise the rigid-body and
marginal poles are split off (ordered real Schur form and a Sylvester equation,
:func:`~sicomat.reduction.modal.spectral_split`) and kept exactly, and the stable part, in real
Schur form, gets its Gramians from triangular Lyapunov solves (LAPACK ``trsyl``). Square-root
factors come from a pivoted Cholesky (``pstrf``); the Hankel singular values from the SVD of their
product.

- :func:`balanced_truncation`: square-root balanced truncation, or its singular-perturbation
  variant (``match_dc=True``) which keeps the static gain; a-priori bound ``2 Σ`` of the discarded
  Hankel singular values.
- :func:`frequency_limited_truncation`: the paper's "partial Gramian operators" — Gawronski–Juang
  frequency-limited Gramians over a band ``[ω₁, ω₂]``, ``P_Ω = S P + P Sᵀ`` with
  ``S = (1/π) Im[ln(jω₂I − A) − ln(jω₁I − A)]``; falls back to the stabilised Gramians of
  Gugercin–Antoulas if the reduced model would be unstable.
- :func:`schur_truncation`: the Schur (balancing-free square-root) method of Safonov–Chiang/Varga:
  same transfer function as balanced truncation, better-conditioned coordinates.
- :func:`hankel_norm_approximation`: Glover's optimal Hankel-norm approximation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

from ..errors import AnalysisError, ModelError
from ..lti.plant import Plant
from ..lti.spectral import (RIGID_TOL, SpectralSplit, StateBlock, schur_eigenvalues, schur_triplet, select_positions, spectral_split, split_block)
from .modal import check_order

if TYPE_CHECKING:  # pragma: no cover
    from .error import ReductionResult

__all__ = ["hankel_singular_values", "balanced_truncation", "frequency_limited_truncation",
           "schur_truncation", "hankel_norm_approximation", "band_gramian_operator"]

_EXACT_PART = "rigid-body and marginally stable part (poles at 0 or on the imaginary axis)"


# --------------------------------------------------------------------------- Gramians
def _lyapunov(T: np.ndarray, rhs: np.ndarray, transpose: bool = False) -> np.ndarray:
    """``T X + X Tᵀ = rhs`` (or ``Tᵀ X + X T = rhs``) for quasi-triangular stable ``T``."""
    if transpose:
        X, scale, info = lapack.dtrsyl(T, T, rhs, trana="T", tranb="N", isgn=1)
    else:
        X, scale, info = lapack.dtrsyl(T, T, rhs, trana="N", tranb="T", isgn=1)
    if info < 0 or not np.all(np.isfinite(X)):
        raise AnalysisError(f"the Lyapunov equation of the Gramians could not be solved (trsyl info={info})")
    X = X / scale
    return 0.5 * (X + X.T)


def _factor(X: np.ndarray) -> np.ndarray:
    """``L`` with ``L Lᵀ ≈ X`` for a symmetric positive semi-definite ``X``.

    Pivoted Cholesky (LAPACK ``pstrf``), which stops at the numerical rank; an eigen-decomposition
    with the round-off negatives cut if that fails.
    """
    n = X.shape[0]
    if n == 0:
        return np.zeros((0, 0))
    c, piv, rank, info = lapack.dpstrf(X, lower=1)
    if info >= 0 and np.all(np.isfinite(c)):
        L = np.zeros((n, rank))
        L[piv - 1] = np.tril(c)[:, :rank]  # X = Π C Cᵀ Πᵀ
        return L
    w, U = np.linalg.eigh(X)
    keep = w > max(float(w[-1]), 0.0) * n * np.finfo(float).eps
    return U[:, keep] * np.sqrt(w[keep])


def _gramians(block: StateBlock) -> tuple[np.ndarray, np.ndarray]:
    P = _lyapunov(block.A, -block.B @ block.B.T)
    Q = _lyapunov(block.A, -block.C.T @ block.C, transpose=True)
    return P, Q


def _balance(Lp: np.ndarray, Lq: np.ndarray):
    """``U, σ, Vᵀ`` of ``Lqᵀ Lp``: σ are the Hankel singular values."""
    if Lp.shape[1] == 0 or Lq.shape[1] == 0:
        return np.zeros((Lq.shape[1], 0)), np.zeros(0), np.zeros((0, Lp.shape[1]))
    return scipy.linalg.svd(Lq.T @ Lp, full_matrices=False, lapack_driver="gesdd")


def _square_root(P: np.ndarray, Q: np.ndarray):
    """``Lp, Lq, U, σ, Vᵀ``: the Gramians' factors and their balancing SVD (square-root method)."""
    Lp, Lq = _factor(P), _factor(Q)
    return (Lp, Lq, *_balance(Lp, Lq))


def _minimal(hsv: np.ndarray) -> int:
    """Number of Hankel singular values above round-off."""
    if hsv.size == 0 or hsv[0] <= 0:
        return 0
    return int(np.sum(hsv > hsv[0] * 1e3 * np.finfo(float).eps * max(hsv.size, 1)))


def _reliable(hsv: np.ndarray) -> int:
    """Hankel singular values computed to a few digits at least: ``σ > √eps · σ₁``.

    The Gramians are formed before being factored, so ``σᵢ`` carries a relative error of about
    ``eps (σ₁/σᵢ)²``; the balanced realizations used by the singular-perturbation and Hankel-norm
    methods only take these states (the others are round-off and would pollute ``A₂₂⁻¹`` or ``Γ⁻¹``).
    """
    if hsv.size == 0 or hsv[0] <= 0:
        return 0
    return int(np.sum(hsv > hsv[0] * np.sqrt(np.finfo(float).eps)))


def hankel_singular_values(plant: Plant, *, rigid_tol: float = RIGID_TOL, inputs: Sequence[str] | None = None,
                           outputs: Sequence[str] | None = None) -> np.ndarray:
    """Hankel singular values of the stable part of a plant (or of its transfer from ``inputs`` to
    ``outputs``, see :func:`~sicomat.reduction.error.select_transfer`), descending.

    The poles at 0 and on the imaginary axis (rigid-body and undamped modes) are split off first:
    their Hankel singular values would be infinite.

    Examples
    --------
    >>> from sicomat.lti.plant import Plant
    >>> G = Plant([[-1.0]], [[1.0]], [[1.0]], [[0.0]], ("x",), ("u",), ("y",))  # 1/(s+1)
    >>> hankel_singular_values(G).round(12).tolist()
    [0.5]
    """
    from .error import select_transfer

    _, gram = _stable_part(select_transfer(plant, inputs, outputs), rigid_tol)
    return _square_root(*gram.gramians())[3]


def band_gramian_operator(T: np.ndarray, band_omega: tuple[float, float]) -> np.ndarray:
    """``S = (1/π) Im[ln(jω₂I − T) − ln(jω₁I − T)]`` for a stable ``T`` (Gawronski–Juang).

    ``S`` maps the infinite-frequency Gramians to the band-limited ones: ``P_Ω = S P + P Sᵀ``,
    ``Q_Ω = Sᵀ Q + Q S``. Computed from the eigen-decomposition of ``T`` (the logarithm of a
    diagonal), or with ``scipy.linalg.logm`` when the eigenvectors are ill-conditioned.
    """
    w1, w2 = band_omega
    n = T.shape[0]
    if n == 0:
        return np.zeros((0, 0))
    try:
        lam, V = np.linalg.eig(T)
        W = np.linalg.inv(V)
        kappa = np.linalg.norm(V) * np.linalg.norm(W) / n
    except np.linalg.LinAlgError:
        kappa = np.inf
    if np.isfinite(kappa) and kappa < 1e8:
        d = np.log(1j * w2 - lam)
        if w1 > 0:
            d = d - np.log(1j * w1 - lam)
        return ((V * d[None, :]) @ W).imag / np.pi
    eye = np.eye(n)
    S = scipy.linalg.logm(1j * w2 * eye - T).imag
    if w1 > 0:
        S = S - scipy.linalg.logm(1j * w1 * eye - T).imag
    return S / np.pi


def _psd_part(X: np.ndarray) -> np.ndarray:
    w, U = np.linalg.eigh(0.5 * (X + X.T))
    return (U * np.abs(w)) @ U.T


class _SchurGramians:
    """Gramians of a stable block in real Schur form, from triangular Lyapunov solves (``trsyl``)."""

    def __init__(self, block: StateBlock) -> None:
        self.block = block

    def gramians(self, band_omega: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        P, Q = _gramians(self.block)
        if band_omega is None:
            return P, Q
        S = band_gramian_operator(self.block.A, band_omega)
        return _sym(S @ P + P @ S.T), _sym(S.T @ Q + Q @ S)

    def stabilised_band_gramians(self, band_omega: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        S = band_gramian_operator(self.block.A, band_omega)
        return _stabilised(self.block, S)


class _ModalGramians:
    """Gramians of a diagonalisable stable system in closed form, in real modal coordinates.

    With ``A = V Λ V⁻¹`` the Gramians in modal coordinates are Cauchy matrices,
    ``P̃_ab = −b̃_a b̃_bᴴ / (λ_a + λ̄_b)``, and the band operator of Gawronski–Juang is diagonal,
    ``s_a = (1/2πj)[ln(jω₂ − λ_a) − ln(−jω₂ − λ_a) − (same at ω₁)]``: O(n²) once the eigenvectors
    are known. The block returned is the real block-diagonal modal form (2×2 blocks
    ``[[σ, ω], [−ω, σ]]``, a valid real Schur form), in whose coordinates the Gramians are given.
    """

    def __init__(self, lam: np.ndarray, V: np.ndarray, W: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
        n = lam.size
        self.lam = lam
        self.bt = W @ B  # complex modal coordinates z = W x
        self.ct = C @ V
        a1, a2 = np.arange(n), np.arange(n)
        r1, r2 = np.ones(n, complex), np.zeros(n, complex)
        A = np.zeros((n, n))
        pair = np.zeros(n, dtype=bool)
        j = 0
        while j < n:
            if lam[j].imag > 0 and j + 1 < n:  # dgeev returns λ, λ̄ adjacent, positive part first
                s, w = lam[j].real, lam[j].imag
                A[j:j + 2, j:j + 2] = [[s, w], [-w, s]]
                a2[j], r2[j] = j + 1, 1.0          # ξ_j = z_j + z̄_j = 2 Re z_j
                a1[j + 1], a2[j + 1] = j, j + 1    # ξ_{j+1} = i (z_j − z̄_j) = −2 Im z_j
                r1[j + 1], r2[j + 1] = 1j, -1j
                pair[j:j + 2] = True
                j += 2
            else:
                A[j, j] = lam[j].real
                j += 1
        self.a1, self.a2, self.r1, self.r2, self.pair = a1, a2, r1, r2, pair
        Vr = np.where(pair[None, :], 0.0, V.real)  # real basis: x = V_r ξ, ξ = W_r x
        Wr = np.where(pair[:, None], 0.0, W.real)
        for j in np.flatnonzero(pair & (r2 == 1.0)).tolist():
            Vr[:, j], Vr[:, j + 1] = V[:, j].real, V[:, j].imag
            Wr[j], Wr[j + 1] = 2.0 * W[j].real, -2.0 * W[j].imag
        self.block = StateBlock(A, Wr @ B, C @ Vr)

    def _real(self, Y: np.ndarray) -> np.ndarray:
        """``R Y Rᴴ`` for the sparse map ``ξ = R z`` (two entries per row)."""
        a1, a2, r1, r2 = self.a1, self.a2, self.r1, self.r2
        out = (np.outer(r1, r1.conj()) * Y[np.ix_(a1, a1)] + np.outer(r1, r2.conj()) * Y[np.ix_(a1, a2)]
               + np.outer(r2, r1.conj()) * Y[np.ix_(a2, a1)] + np.outer(r2, r2.conj()) * Y[np.ix_(a2, a2)])
        return _sym(out.real)

    def _band(self, band_omega: tuple[float, float]) -> np.ndarray:
        lam = self.lam
        w1, w2 = band_omega

        def f(w: float) -> np.ndarray:
            return (np.log(1j * w - lam) - np.log(-1j * w - lam)) / (2j * np.pi)

        return f(w2) - (f(w1) if w1 > 0 else 0.0)

    def gramians(self, band_omega: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        lam, bt, ct = self.lam, self.bt, self.ct
        Pz = -(bt @ bt.conj().T) / (lam[:, None] + lam.conj()[None, :])
        Qz = -(ct.conj().T @ ct) / (lam.conj()[:, None] + lam[None, :])
        if band_omega is not None:
            s = self._band(band_omega)
            Pz = Pz * (s[:, None] + s.conj()[None, :])
            Qz = Qz * (s.conj()[:, None] + s[None, :])
        scale = np.where(self.pair, 0.5, 1.0)  # ξ = R z, R⁻¹ = Rᴴ/2 on the pairs: Q_ξ = R (S Q_z S) Rᴴ
        return self._real(Pz), self._real(Qz * np.outer(scale, scale))

    def stabilised_band_gramians(self, band_omega: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        s = self._band(band_omega)
        n = s.size
        S = np.zeros((n, n))
        j = 0
        while j < n:  # S = f(A) is block-diagonal like A: [[Re s, Im s], [−Im s, Re s]]
            if self.pair[j]:
                S[j:j + 2, j:j + 2] = [[s[j].real, s[j].imag], [-s[j].imag, s[j].real]]
                j += 2
            else:
                S[j, j] = s[j].real
                j += 1
        return _stabilised(self.block, S)


def _sym(X: np.ndarray) -> np.ndarray:
    return 0.5 * (X + X.T)


def _stabilised(block: StateBlock, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gugercin–Antoulas: Lyapunov equations with the positive parts of the band right-hand sides."""
    BB, CC = block.B @ block.B.T, block.C.T @ block.C
    P = _lyapunov(block.A, -_psd_part(S @ BB + BB @ S.T))
    Q = _lyapunov(block.A, -_psd_part(S.T @ CC + CC @ S), transpose=True)
    return P, Q


def _modal_gramians(A: np.ndarray, B: np.ndarray, C: np.ndarray, rigid_tol: float | None):
    """Closed-form modal Gramians of ``(A, B, C)``, or ``None`` when A has poles at 0 or on the
    imaginary axis (``rigid_tol`` given) or ill-conditioned eigenvectors."""
    n = A.shape[0]
    lam, V = np.linalg.eig(A)
    rho = float(np.max(np.abs(lam)))
    if rho == 0 or (rigid_tol is not None and (np.any(np.abs(lam) <= rigid_tol * rho)
                                               or np.any(lam.real >= -1e-10 * rho))):
        return None
    try:
        W = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return None
    if np.linalg.norm(V) * np.linalg.norm(W) / n > 1e6:
        return None
    return _ModalGramians(lam, V, W, B, C)


def _stable_part(plant: Plant, rigid_tol: float):
    """``(split, gramians)``: the rigid/marginal part split off, and a Gramian source for the rest.

    A nonsingular, diagonalisable, strictly stable state matrix (the usual damped, grounded
    mechanics) goes straight to the closed-form modal Gramians (one eigen-decomposition). A
    (nearly) singular one — a rigid-body mode — is split with the ordered Schur form first; its
    stable block then gets the modal Gramians too, or triangular Lyapunov solves when its
    eigenvectors are ill-conditioned.
    """
    A = np.array(plant.A, dtype=float)
    n = A.shape[0]
    D = np.array(plant.D, dtype=float)
    if n and np.all(np.isfinite(A)):
        _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
        Ab = (A * scale[None, :]) / scale[:, None]
        lu, _, info = lapack.dgetrf(Ab)
        rcond = lapack.dgecon(lu, np.linalg.norm(Ab, 1), norm="1")[0] if info == 0 else 0.0
        if rcond > 1e-10:  # no pole at 0 in sight: try the direct modal route
            gram = _modal_gramians(Ab, plant.B / scale[:, None], plant.C * scale[None, :], rigid_tol)
            if gram is not None:
                empty = StateBlock(np.zeros((0, 0)), np.zeros((0, plant.B.shape[1])),
                                   np.zeros((plant.C.shape[0], 0)))
                return SpectralSplit(empty, gram.block, D), gram
    split = spectral_split(plant, rigid_tol=rigid_tol, marginal=True)
    stable = split.flexible
    if stable.n:
        gram = _modal_gramians(stable.A, stable.B, stable.C, None)
        if gram is not None:
            return SpectralSplit(split.rigid, gram.block, split.D), gram
    return split, _SchurGramians(stable)


# --------------------------------------------------------------------------- projections
def _truncate(block: StateBlock, Lp, Lq, U, hsv, Vt, r: int) -> StateBlock:
    """Square-root balanced truncation to ``r`` states."""
    scale = 1.0 / np.sqrt(hsv[:r])
    Tr = (Lp @ Vt[:r].T) * scale
    Wr = (Lq @ U[:, :r]) * scale
    return StateBlock(Wr.T @ block.A @ Tr, Wr.T @ block.B, block.C @ Tr)


def _balanced_realization(block: StateBlock, Lp, Lq, U, hsv, Vt) -> StateBlock:
    return _truncate(block, Lp, Lq, U, hsv, Vt, _reliable(hsv))


def _residualize(bal: StateBlock, D: np.ndarray, r: int) -> tuple[StateBlock, np.ndarray]:
    """Singular perturbation: the states ``r:`` set to their steady state (keeps the static gain)."""
    A, B, C = bal.A, bal.B, bal.C
    if r >= A.shape[0]:
        return bal, D
    A11, A12, A21, A22 = A[:r, :r], A[:r, r:], A[r:, :r], A[r:, r:]
    lu = scipy.linalg.lu_factor(A22)
    X_A, X_B = scipy.linalg.lu_solve(lu, A21), scipy.linalg.lu_solve(lu, B[r:])
    return (StateBlock(A11 - A12 @ X_A, B[:r] - A12 @ X_B, C[:, :r] - C[:, r:] @ X_A),
            D - C[:, r:] @ X_B)


def _assemble(plant: Plant, split: SpectralSplit, reduced: StateBlock, D: np.ndarray, prefix: str) -> Plant:
    first = split.rigid
    zeros = int(np.sum(first.poles() == 0)) if first.n else 0
    names = [f"rigid.{k + 1}" for k in range(zeros)] + [f"marginal.{k + 1}" for k in range(first.n - zeros)]
    names += [f"{prefix}.{k + 1}" for k in range(reduced.n)]
    return Plant(scipy.linalg.block_diag(first.A, reduced.A), np.vstack([first.B, reduced.B]),
                 np.hstack([first.C, reduced.C]), D, tuple(names), plant.inputs, plant.outputs)


def _prepare(plant: Plant, order: int, rigid_tol: float, inputs, outputs):
    """``(plant, split, gramians)``: the chosen transfer, its exact part split off, the order checked."""
    from .error import select_transfer

    plant = select_transfer(plant, inputs, outputs)
    split, gram = _stable_part(plant, rigid_tol)
    check_order(order, plant.n_states, split.rigid.n, what=_EXACT_PART)
    return plant, split, gram


def _cap(r: int, available: int, warnings: list[str], split: SpectralSplit) -> int:
    if r > available:
        warnings.append(f"the stable part has only {available} Hankel singular values above round-off; "
                        f"the reduced model has {split.rigid.n + available} states")
        return available
    return r


def _whole_pairs(r: int, order: int, split: SpectralSplit, warnings: list[str]) -> int:
    """``r`` unchanged; a warning when ``r`` is odd and every stable pole is complex (the lightly
    damped modes of a mechanics): the approximant then has a real pole that is no mode of the full
    model (on the 5M4S at order 5, 0.18 Hz). The approximation stays valid (error bound, Glover's
    optimality), so the order is kept, not rounded as modal truncation does."""
    stable = split.flexible
    if r % 2 and stable.n and not np.any(schur_eigenvalues(stable.A).imag == 0):
        total = split.rigid.n + r
        warnings.append(f"order {order}: every pole of the stable part is complex, so an odd number of "
                        f"states ({total}) gives the reduced model a real pole that is no mode of the full "
                        f"model; orders {total - 1} or {total + 1} keep whole modes")
    return r


# --------------------------------------------------------------------------- public reductors
def balanced_truncation(plant: Plant, order: int, *, match_dc: bool = False,
                        band_hz: tuple[float, float] | None = None,
                        rigid_tol: float = RIGID_TOL,
                        inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None) -> "ReductionResult":
    """Square-root balanced truncation (or singular-perturbation approximation) of the stable part.

    Parameters
    ----------
    plant : Plant
        The full model.
    order : int
        Number of states of the reduced model, the exactly-kept rigid/marginal part included.
    match_dc : bool, optional
        Singular-perturbation approximation instead of truncation: the static gain of the stable
        part is kept exactly (same error bound).
    band_hz : (float, float), optional
        Band of interest (Hz) for the reported band errors only (see
        :func:`frequency_limited_truncation` to reduce for a band).
    rigid_tol : float, optional
        Relative tolerance for poles at 0 (see :data:`~sicomat.reduction.modal.RIGID_TOL`).
    inputs, outputs : sequence of str, optional
        The transfer to reduce (:func:`~sicomat.reduction.error.select_transfer`); all the plant's
        signals by default. The Gramians weigh the channels in their SI units: choose the transfer
        that matters (the actuator to the position sensor), not a mix of m and m/s outputs.

    Returns
    -------
    ReductionResult
        With ``hankel_singular_values`` and ``error_bound = 2 Σ_{i>r} σ_i``. An odd number of
        stable states when every stable pole is complex gives a real pole that is no mode of the
        full model: kept (the bound holds), and ``warnings`` says so.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[1, 1, 1], stiffnesses=[1e4, 1e4],
    ...                                   dampings=[5, 5], ground_stiffness=1e4)).state_space()
    >>> res = balanced_truncation(plant, 2)
    >>> res.order_after, res.hinf_error <= res.error_bound
    (2, True)
    """
    from .error import ReductionResult, check_band

    band_hz = check_band(band_hz)
    plant, split, gram = _prepare(plant, order, rigid_tol, inputs, outputs)
    notes: list[str] = []
    warnings: list[str] = []
    stable = split.flexible
    Lp, Lq, U, hsv, Vt = _square_root(*gram.gramians())
    r = _whole_pairs(_cap(order - split.rigid.n, _reliable(hsv) if match_dc else _minimal(hsv), warnings, split),
                     order, split, warnings)
    if match_dc:
        bal = _balanced_realization(stable, Lp, Lq, U, hsv, Vt)
        red, D = _residualize(bal, split.D, r)
        if stable.n and red.n:  # absorb the round-off tail so the static gain is kept to the last digit
            D = split.dc_gain() + red.C @ scipy.linalg.solve(red.A, red.B)
        elif stable.n:
            D = split.dc_gain()
        variant = "singular-perturbation"
    else:
        red, D = _truncate(stable, Lp, Lq, U, hsv, Vt, r), split.D
        variant = "square-root"
    reduced = _assemble(plant, split, red, D, "balanced")
    return ReductionResult(method="balanced", variant=variant, full=plant, reduced=reduced,
                           hankel_singular_values=hsv, error_bound=float(2.0 * np.sum(hsv[r:])),
                           band_hz=band_hz, notes=tuple(notes), warnings=tuple(warnings), rigid_tol=rigid_tol)


def schur_truncation(plant: Plant, order: int, *, band_hz: tuple[float, float] | None = None,
                     rigid_tol: float = RIGID_TOL,
                     inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None) -> "ReductionResult":
    """The Schur method (balancing-free square root, Safonov–Chiang 1989, Varga 1991).

    Projects on orthonormal bases of the dominant controllable and observable subspaces instead of
    balancing: the reduced transfer function is that of :func:`balanced_truncation`, its
    coordinates are better conditioned. Same error bound ``2 Σ_{i>r} σ_i``, same ``order``,
    ``inputs`` and ``outputs`` rules.
    """
    from .error import ReductionResult, check_band

    band_hz = check_band(band_hz)
    plant, split, gram = _prepare(plant, order, rigid_tol, inputs, outputs)
    notes: list[str] = []
    warnings: list[str] = []
    stable = split.flexible
    Lp, Lq, U, hsv, Vt = _square_root(*gram.gramians())
    r = _whole_pairs(_cap(order - split.rigid.n, _minimal(hsv), warnings, split), order, split, warnings)
    Q1 = np.linalg.qr(Lp @ Vt[:r].T)[0]
    Q2 = np.linalg.qr(Lq @ U[:, :r])[0]
    E = Q2.T @ Q1
    red = StateBlock(np.linalg.solve(E, Q2.T @ stable.A @ Q1), np.linalg.solve(E, Q2.T @ stable.B),
                     stable.C @ Q1)
    reduced = _assemble(plant, split, red, split.D, "schur")
    return ReductionResult(method="balanced", variant="schur", full=plant, reduced=reduced,
                           hankel_singular_values=hsv, error_bound=float(2.0 * np.sum(hsv[r:])),
                           band_hz=band_hz, notes=tuple(notes), warnings=tuple(warnings), rigid_tol=rigid_tol)


def frequency_limited_truncation(plant: Plant, order: int, band_hz: tuple[float, float] | None, *,
                                 rigid_tol: float = RIGID_TOL,
                                 inputs: Sequence[str] | None = None,
                                 outputs: Sequence[str] | None = None) -> "ReductionResult":
    """Balanced truncation with frequency-limited ("partial") Gramians over a band (Gawronski–Juang).

    The Gramians only integrate the band ``[ω₁, ω₂]`` (and its mirror image), so the reduced model
    is accurate there and may be poor outside. There is no a-priori error bound. If the reduced
    model comes out unstable (possible with these Gramians), the stabilised Gramians of
    Gugercin–Antoulas (2004), which solve Lyapunov equations with the positive part of the band
    right-hand sides, are used instead (see ``notes``).

    Parameters
    ----------
    plant : Plant
        The full model.
    order : int
        Number of states of the reduced model, rigid/marginal part included.
    band_hz : (float, float)
        The band of interest ``(low_hz, high_hz)``, ``0 ≤ low < high``.
    rigid_tol : float, optional
        Relative tolerance for poles at 0.
    inputs, outputs : sequence of str, optional
        The transfer to reduce, as for :func:`balanced_truncation`.

    Returns
    -------
    ReductionResult
        ``hankel_singular_values`` are the frequency-limited ones; ``error_bound`` is ``None``.
    """
    from .error import ReductionResult, check_band

    band_hz = check_band(band_hz)
    if band_hz is None:
        raise ModelError("frequency-limited truncation needs a band (low_hz, high_hz)", path="band_hz")
    plant, split, gram = _prepare(plant, order, rigid_tol, inputs, outputs)
    notes: list[str] = []
    warnings: list[str] = []
    stable = split.flexible
    band_omega = (2 * np.pi * band_hz[0], 2 * np.pi * band_hz[1])
    variant = "frequency-limited"
    Lp, Lq, U, hsv, Vt = _square_root(*gram.gramians(band_omega))
    r = _whole_pairs(_cap(order - split.rigid.n, _minimal(hsv), warnings, split), order, split, warnings)
    red = _truncate(stable, Lp, Lq, U, hsv, Vt, r)
    if red.n and np.any(np.linalg.eigvals(red.A).real >= 0):
        Lp, Lq, U, hsv, Vt = _square_root(*gram.stabilised_band_gramians(band_omega))
        r = min(r, _minimal(hsv))
        red = _truncate(stable, Lp, Lq, U, hsv, Vt, r)
        notes.append("the frequency-limited Gramians gave an unstable reduced model; the stabilised "
                     "(Gugercin-Antoulas) frequency-limited Gramians were used instead")
        variant = "frequency-limited-stabilised"
    reduced = _assemble(plant, split, red, split.D, "balanced")
    return ReductionResult(method="balanced", variant=variant, full=plant, reduced=reduced,
                           hankel_singular_values=hsv, error_bound=None, band_hz=band_hz,
                           notes=tuple(notes), warnings=tuple(warnings), rigid_tol=rigid_tol)


def hankel_norm_approximation(plant: Plant, order: int, *, band_hz: tuple[float, float] | None = None,
                              rigid_tol: float = RIGID_TOL,
                              inputs: Sequence[str] | None = None,
                              outputs: Sequence[str] | None = None) -> "ReductionResult":
    """Glover's optimal Hankel-norm approximation of the stable part (scipy only).

    From a balanced realization of the stable part, Glover's all-pass dilation (K. Glover, Int. J.
    Control 39(6), 1984) gives a system ``Ĝ`` with ``‖G − Ĝ‖∞ = σ_{r+1}``; its stable part is the
    reduced model. Non-square plants are squared up with zero columns or rows first. ``order``,
    ``inputs`` and ``outputs`` as for :func:`balanced_truncation`.

    Returns
    -------
    ReductionResult
        ``error_bound = σ_{r+1} + 2 Σ_{i>r+l} σ_i`` (``l`` the multiplicity of ``σ_{r+1}``), a
        valid bound for this choice of feedthrough; the error is at least ``σ_{r+1}`` for any
        model of that order.
    """
    from .error import ReductionResult, check_band

    band_hz = check_band(band_hz)
    plant, split, gram = _prepare(plant, order, rigid_tol, inputs, outputs)
    notes: list[str] = []
    warnings: list[str] = []
    stable = split.flexible
    Lp, Lq, U, hsv, Vt = _square_root(*gram.gramians())
    n_min = _reliable(hsv)
    k = _whole_pairs(_cap(order - split.rigid.n, n_min, warnings, split), order, split, warnings)
    bal = _balanced_realization(stable, Lp, Lq, U, hsv, Vt)
    D = np.array(split.D, dtype=float)
    if k >= n_min:
        reduced = _assemble(plant, split, bal, D, "hankel")
        return ReductionResult(method="balanced", variant="hankel-norm", full=plant, reduced=reduced,
                               hankel_singular_values=hsv, error_bound=float(np.sum(hsv[n_min:])),
                               band_hz=band_hz, notes=tuple(notes), warnings=tuple(warnings), rigid_tol=rigid_tol)
    sigma = hsv[:n_min]
    s = float(sigma[k])
    group = np.flatnonzero(np.abs(sigma - s) <= 1e-9 * sigma[0])
    if group[0] < k:
        warnings.append(f"σ_{k + 1} is repeated; the reduced model keeps {group[0]} stable states")
        k = int(group[0])
    rest = np.setdiff1d(np.arange(n_min), group)
    ny, nu = D.shape
    A, B, C = bal.A, bal.B, bal.C
    p = max(ny, nu)  # square up with zero columns / rows
    B = np.hstack([B, np.zeros((B.shape[0], p - nu))])
    C = np.vstack([C, np.zeros((p - ny, C.shape[1]))])
    Dsq = np.zeros((p, p))
    Dsq[:ny, :nu] = D
    A11 = A[np.ix_(rest, rest)]
    B1, B2 = B[rest], B[group]
    C1, C2 = C[:, rest], C[:, group]
    S1 = sigma[rest]
    W, _, Zt = np.linalg.svd(-C2 @ B2)  # U unitary with C2ᵀ U = −B2 (orthogonal Procrustes)
    Uu = W @ Zt
    gamma = S1 ** 2 - s ** 2
    Ah = (s ** 2 * A11.T + A11 * np.outer(S1, S1) - s * C1.T @ Uu @ B1.T) / gamma[:, None]
    Bh = (S1[:, None] * B1 + s * C1.T @ Uu) / gamma[:, None]
    Ch = C1 * S1[None, :] + s * Uu @ B1.T
    Dh = Dsq - s * Uu
    T, Bt, Ct = schur_triplet(Ah, Bh, Ch)
    stable_part, _ = split_block(StateBlock(T, Bt, Ct), select_positions(T, lambda v: v.real < 0))
    red = StateBlock(stable_part.A, stable_part.B[:, :nu], stable_part.C[:ny])
    if red.n != k:
        warnings.append(f"the stable part of the Hankel-norm approximant has {red.n} states instead of {k}")
    bound = s + 2.0 * float(np.sum(hsv[group[-1] + 1:]))
    reduced = _assemble(plant, split, red, Dh[:ny, :nu], "hankel")
    return ReductionResult(method="balanced", variant="hankel-norm", full=plant, reduced=reduced,
                           hankel_singular_values=hsv, error_bound=bound, band_hz=band_hz,
                           notes=tuple(notes), warnings=tuple(warnings), rigid_tol=rigid_tol)
