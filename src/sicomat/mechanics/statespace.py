"""The state space of a second-order mechanics (the paper's eqs. 11–12): z = (q, q̇).

**The** one assembler from ``(M, D, K, F)`` to ``(A, B)`` lives here; the mechanics' plant, the servo
loop's continuous part and the simulator's friction inputs all use it. M is any symmetric positive
definite matrix (a lumped mechanics has a diagonal one; the robotics formalism brings full,
configuration-dependent ones): :class:`MassFactor` solves with its Cholesky factor ``M = L Lᵀ``, never
with an explicit inverse. A diagonal M is recognised (off-diagonal entries exactly 0) and solved by
multiplying with the reciprocal masses — the same numbers, rounded once, as the Cholesky solve would
give up to the last bit, and no O(n³) factorisation for the few-thousand-body chains.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Iterable

import numpy as np
import scipy.linalg

from ..errors import ModelError
from ..lti.plant import Plant

if TYPE_CHECKING:  # pragma: no cover
    from .lumped import Mechanics

__all__ = ["MassFactor", "second_order_state_space", "second_order_input", "mechanics_plant"]


class MassFactor:
    """The Cholesky factor of a symmetric positive definite mass matrix, ``M = L Lᵀ``.

    Parameters
    ----------
    M : array_like, (n, n)
        The mass matrix (SI units: kg, kg·m², or mixed for mixed dofs).
    path : str, optional
        Where M came from, for the error message (e.g. ``"mass"``).

    Raises
    ------
    ModelError
        M is not square, not finite, not symmetric (to ``1e-12·max|M|``) or not positive definite.

    Examples
    --------
    >>> f = MassFactor([[2.0, 1.0], [1.0, 2.0]])
    >>> np.round(f.solve(np.array([3.0, 3.0])), 12).tolist()
    [1.0, 1.0]
    >>> MassFactor([[1.0, 2.0], [2.0, 1.0]])
    Traceback (most recent call last):
    ...
    sicomat.errors.ModelError: mass: the mass matrix is not positive definite (its Cholesky factorisation fails at row 2); ...
    """

    def __init__(self, M, *, path: str | None = "mass") -> None:
        M = np.asarray(M, dtype=float)
        if M.ndim != 2 or M.shape[0] != M.shape[1]:
            raise ModelError(f"the mass matrix must be square, got shape {M.shape}", path=path)
        if not np.all(np.isfinite(M)):
            raise ModelError("the mass matrix has non-finite entries", path=path)
        n = M.shape[0]
        self.n = n
        off = M - np.diag(np.diag(M))
        self.diagonal = not np.any(off)
        scale = float(np.max(np.abs(M))) if n else 0.0
        if not self.diagonal and np.max(np.abs(M - M.T)) > 1e-12 * scale:
            i, j = np.unravel_index(np.argmax(np.abs(M - M.T)), M.shape)
            raise ModelError(f"the mass matrix is not symmetric: M[{i}, {j}] = {M[i, j]:.17g} but "
                             f"M[{j}, {i}] = {M[j, i]:.17g}; a kinetic energy ½ q̇ᵀ M q̇ needs M = Mᵀ", path=path)
        if self.diagonal:
            d = np.diag(M).copy()
            bad = np.flatnonzero(~(d > 0))
            if bad.size:
                raise ModelError(f"the mass matrix is not positive definite: its diagonal entry {int(bad[0]) + 1} "
                                 f"is {d[bad[0]]:g}; every body needs a positive mass or inertia", path=path)
            self._inverse = 1.0 / d
            self._half_inverse = 1.0 / np.sqrt(d)
            self._cho = None
        else:
            M = 0.5 * (M + M.T)
            try:
                self._cho = scipy.linalg.cho_factor(M, lower=True, check_finite=False)
            except np.linalg.LinAlgError as exc:
                row = _failed_row(str(exc))
                raise ModelError("the mass matrix is not positive definite (its Cholesky factorisation fails "
                                 f"at row {row}); a kinetic energy ½ q̇ᵀ M q̇ must be positive for every "
                                 "motion", path=path) from None

    def solve(self, X: np.ndarray) -> np.ndarray:
        """``M⁻¹ X`` (``X``: (n,) or (n, m))."""
        X = np.asarray(X, dtype=float)
        if self._cho is None:
            return self._inverse * X if X.ndim == 1 else self._inverse[:, None] * X
        return scipy.linalg.cho_solve(self._cho, X, check_finite=False)

    def half_solve(self, X: np.ndarray, *, transposed: bool = False) -> np.ndarray:
        """``L⁻¹ X``, or ``L⁻ᵀ X`` with ``transposed`` (``M = L Lᵀ``; ``M^{-1/2} X`` for a diagonal M)."""
        X = np.asarray(X, dtype=float)
        if self._cho is None:
            return self._half_inverse * X if X.ndim == 1 else self._half_inverse[:, None] * X
        return scipy.linalg.solve_triangular(self._cho[0], X, lower=True, trans="T" if transposed else "N",
                                             check_finite=False)


def _failed_row(message: str) -> str:
    digits = "".join(c if c.isdigit() else " " for c in message).split()
    return digits[0] if digits else "?"


def _factor(M) -> MassFactor:
    return M if isinstance(M, MassFactor) else MassFactor(M)


def second_order_input(M, F: np.ndarray) -> np.ndarray:
    """The input matrix ``[0; M⁻¹ F]`` of generalised forces ``F`` (n, m) in ``z = (q, q̇)``.

    ``M`` is a mass matrix or its :class:`MassFactor`.
    """
    factor = _factor(M)
    F = np.asarray(F, dtype=float).reshape(factor.n, -1)
    return np.vstack([np.zeros_like(F), factor.solve(F)])


def second_order_state_space(M, D, K, F: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of ``M q̈ + D q̇ + K q = F u`` in ``z = (q, q̇)``.

    ``A = [[0, I], [-M⁻¹K, -M⁻¹D]]``, ``B = [0; M⁻¹F]``; M (a matrix or its :class:`MassFactor`)
    symmetric positive definite, solved through its Cholesky factor.

    Examples
    --------
    >>> A, B = second_order_state_space([[2.0]], [[0.4]], [[8.0]], [[1.0]])
    >>> A.tolist(), B.ravel().tolist()
    ([[0.0, 1.0], [-4.0, -0.2]], [0.0, 0.5])
    """
    factor = _factor(M)
    n = factor.n
    D = np.asarray(D, dtype=float)
    K = np.asarray(K, dtype=float)
    F = np.zeros((n, 0)) if F is None else np.asarray(F, dtype=float).reshape(n, -1)
    solved = factor.solve(np.hstack([K, D, F]))          # one solve for the three
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-solved[:, :n], -solved[:, n: 2 * n]]])
    B = np.vstack([np.zeros_like(F), solved[:, 2 * n:]])
    return A, B


def mechanics_plant(mech: "Mechanics", *, forces_on: Iterable[str] = (), dof_outputs: bool = False) -> Plant:
    """The state space of eqs. (11)–(12): ``z = (q, q̇)``.

    The paper prints ``z = (Ẋ, X)`` but its A and B of eq. (12) are those of ``z = (X, Ẋ)``;
    we follow A and B (see ``docs/mechanics.md``).

    Parameters
    ----------
    mech : Mechanics
        The lumped model.
    forces_on : iterable of str, optional
        Bodies that also get an external load input, named ``"<body>.force"`` or ``"<body>.torque"``
        (for compliance and disturbance transfers).
    dof_outputs : bool, optional
        Also output every state (``"<body>.v"``, ``"<body>.x"``, ...).

    Returns
    -------
    Plant
        Inputs: the actuators, then the external loads. Outputs: the sensors (position sensors read
        ``q``, velocity sensors ``q̇``), then the states if ``dof_outputs``.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = mechanics_plant(build_mechanics(ChainSpec(type="chain", masses=[2.0])))
    >>> plant.states, plant.inputs, plant.outputs
    (('m1.x', 'm1.v'), ('motor',), ('first', 'last'))
    >>> plant.B.ravel().tolist()
    [0.0, 0.5]
    """
    n = mech.n
    columns = [a.vector for a in mech.actuators]
    inputs = [a.name for a in mech.actuators]
    for body in forces_on:
        if body not in mech.dof_names:
            raise ModelError(f"unknown body {body!r}; expected one of {', '.join(mech.dof_names)}")
        vector = np.zeros(n)
        vector[mech.index(body)] = 1.0
        columns.append(vector)
        inputs.append(mech.dofs[mech.index(body)].load)
    Fu = np.column_stack(columns) if columns else np.zeros((n, 0))
    A, B = second_order_state_space(mech.mass_factor, mech.damping, mech.stiffness, Fu)
    rows, outputs = [], []
    for s in mech.sensors:
        rows.append(np.concatenate([np.zeros(n), s.vector]) if s.kind == "velocity"
                    else np.concatenate([s.vector, np.zeros(n)]))
        outputs.append(s.name)
    states = [d.position for d in mech.dofs] + [d.velocity for d in mech.dofs]
    if dof_outputs:
        rows.extend(np.eye(2 * n))
        outputs.extend(states)
    C = np.array(rows).reshape(len(rows), 2 * n)
    return Plant(A, B, C, np.zeros((len(outputs), len(inputs))), tuple(states), tuple(inputs), tuple(outputs))
