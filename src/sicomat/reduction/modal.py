"""Modal truncation with static-gain matching (paper III.C.1), on an ordered real Schur form.

The rigid/flexible split and the Schur machinery (reordering by LAPACK ``trsen``, decoupling by
``trsyl``) are the one of :mod:`sicomat.lti.spectral`, re-exported here (``spectral_split``,
``SpectralSplit``, ``StateBlock``, ``RIGID_TOL``) for the reduction methods.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np
import scipy.linalg

from ..errors import ModelError
from ..lti.plant import Plant
from ..lti.spectral import (RIGID_TOL, SpectralSplit, StateBlock, spectral_split, split_block)

if TYPE_CHECKING:  # pragma: no cover
    from .error import ReductionResult

__all__ = ["StateBlock", "SpectralSplit", "spectral_split", "modal_truncation", "RIGID_TOL"]

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
