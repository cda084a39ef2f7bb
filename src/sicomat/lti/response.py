"""Frequency responses: fast, vectorised evaluation of LTI systems (continuous or ZOH-sampled) and the
result object every loop transfer is returned in."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["FrequencyResponse", "ModalForm", "modal_form", "continuous_response", "sampled_response",
           "response_at", "zoh_matrices", "static_gain"]


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """A SISO frequency response ``H(jω)`` on a grid.

    Attributes
    ----------
    omega : ndarray, shape (n,)
        Angular frequencies (rad/s), ascending, > 0.
    response : ndarray of complex, shape (n,)
        The complex response at ``omega``.
    name : str
        What this is, e.g. ``"velocity-open"``.
    sample_period : float or None
        For a sampled loop: its period (s); ``omega`` then stays below the Nyquist frequency π/T.
    open_loop : bool
        True for a loop gain ``L`` (margins apply to it; the feedback is negative: ``1 + L``).
    info : dict
        Units and context (``"input"``, ``"output"``, ...).
    """

    omega: np.ndarray
    response: np.ndarray
    name: str = ""
    sample_period: float | None = None
    open_loop: bool = False
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def frequency_hz(self) -> np.ndarray:
        """Frequencies (Hz)."""
        return self.omega / (2 * np.pi)

    @property
    def magnitude(self) -> np.ndarray:
        """|H|."""
        return np.abs(self.response)

    @property
    def magnitude_db(self) -> np.ndarray:
        """20 log10 |H| (dB)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """Unwrapped phase (degrees), starting in (−360°, 0°] for a loop gain with integrators."""
        phase = np.unwrap(np.angle(self.response))
        if self.open_loop and phase.size:
            phase -= 2 * np.pi * np.ceil(phase[0] / (2 * np.pi))
        return np.degrees(phase)

    def to_pandas(self) -> "pandas.DataFrame":
        """Columns: frequency_hz, magnitude, magnitude_db, phase_deg, real, imag (index: omega)."""
        import pandas as pd

        return pd.DataFrame({"frequency_hz": self.frequency_hz, "magnitude": self.magnitude,
                             "magnitude_db": self.magnitude_db, "phase_deg": self.phase_deg,
                             "real": self.response.real, "imag": self.response.imag},
                            index=pd.Index(self.omega, name="omega"))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (lists)."""
        return {"name": self.name, "sample_period": self.sample_period, "open_loop": self.open_loop,
                "omega": self.omega.tolist(), "frequency_hz": self.frequency_hz.tolist(),
                "magnitude_db": [float(x) if np.isfinite(x) else None for x in self.magnitude_db],
                "phase_deg": self.phase_deg.tolist()}

    def plot(self, kind: str = "bode"):
        """A Bode (``kind="bode"``) or Nichols (``kind="nichols"``) figure."""
        from ..plots.frequency import bode_figure, nichols_figure

        return bode_figure([self]) if kind == "bode" else nichols_figure([self])


@dataclass(frozen=True, eq=False)
class ModalForm:
    """``A = S diag(A1, A2) S⁻¹``: a small dense block ``A1`` (eigenvalues near 0: rigid modes,
    possibly defective) and a diagonal block ``λ`` (``A2 = V diag(λ) V⁻¹``), with the input and output
    maps transformed accordingly, so that ``C (sI − A)⁻¹ B = C1 (sI − A1)⁻¹ B1 + Σ r_i / (s − λ_i)``."""

    A1: np.ndarray
    B1: np.ndarray
    C1: np.ndarray
    lam: np.ndarray
    B2: np.ndarray   # V⁻¹ B, rows per eigenvalue
    C2: np.ndarray   # C V, columns per eigenvalue
    D: np.ndarray


def modal_form(A, B, C, D=None, *, cluster: float = 1e-7) -> ModalForm:
    """Decompose a state space for fast frequency responses.

    The eigendecomposition is used directly unless eigenvalues with ``|λ| ≤ cluster · max(1, ‖A‖)``
    (rigid-body modes, integrators) come with ill-conditioned eigenvectors (``cond(V) ≥ 1e10``):
    those are split off by an ordered real Schur form and a Sylvester equation, the rest is
    diagonalised.
    """
    A = np.asarray(A, dtype=float)
    B = np.atleast_2d(np.asarray(B, dtype=float))
    C = np.atleast_2d(np.asarray(C, dtype=float))
    D = np.zeros((C.shape[0], B.shape[1])) if D is None else np.atleast_2d(np.asarray(D, dtype=float))
    n = A.shape[0]
    if n == 0:
        return ModalForm(np.zeros((0, 0)), np.zeros((0, B.shape[1])), np.zeros((C.shape[0], 0)),
                         np.zeros(0, complex), np.zeros((0, B.shape[1]), complex),
                         np.zeros((C.shape[0], 0), complex), D)
    scale = max(1.0, float(np.linalg.norm(A, 1)))
    lam, V = scipy.linalg.eig(A)
    small = np.abs(lam) <= cluster * scale
    # A rigid pair (a Jordan block at 0) has nearly parallel eigenvectors; up to cond(V) = 1e10 the
    # diagonal form stays accurate relative to the peak (~1e-9 on the 400-state free chain, where
    # the Schur split, its Sylvester equation poorly separated, gives ~6e-8 at twice the cost). Its
    # residues of opposite signs do cancel where the response rolls off: per-point relative error
    # grows there (1e-5 at 2 kHz on a two-mass drive), so small loops are evaluated by LU solves
    # instead (sicomat.frequency.loops).
    if not small.any() or np.linalg.cond(V) < 1e10:
        B2 = np.linalg.solve(V, B.astype(complex))
        return ModalForm(np.zeros((0, 0)), np.zeros((0, B.shape[1])), np.zeros((C.shape[0], 0)),
                         lam, B2, C @ V, D)
    T, Z, k = scipy.linalg.schur(A, output="real", sort=lambda re, im: np.hypot(re, im) <= cluster * scale)
    T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
    X = scipy.linalg.solve_sylvester(T11, -T22, -T12) if k and k < n else np.zeros((k, n - k))
    # A Z = Z T; with W = Z [[I, X], [0, I]]: W⁻¹ A W = diag(T11, T22)
    Bz, Cz = Z.T @ B, C @ Z
    B1 = Bz[:k] - X @ Bz[k:]
    B2r = Bz[k:]
    C1 = Cz[:, :k]
    C2r = Cz[:, :k] @ X + Cz[:, k:]
    lam, V = scipy.linalg.eig(T22)
    B2 = np.linalg.solve(V, B2r.astype(complex)) if n - k else np.zeros((0, B.shape[1]), complex)
    C2 = C2r @ V
    return ModalForm(T11, B1, C1, lam, B2, C2, D)


def continuous_response(form: ModalForm, omega: np.ndarray) -> np.ndarray:
    """``C (jωI − A)⁻¹ B + D`` for all ω: array (n_out, n_in, n_omega)."""
    return response_at(form, 1j * np.asarray(omega, dtype=float))


def response_at(form: ModalForm, points: np.ndarray) -> np.ndarray:
    """``C (pI − A)⁻¹ B + D`` at complex points p (``s = jω``, or ``z = e^{jωT}`` for a discrete A)."""
    s = np.asarray(points, dtype=complex)
    return _evaluate(form, s, lambda lam: 1.0 / (s[None, :] - lam[:, None]), lambda A1: _resolvent(A1, s))


def sampled_response(form: ModalForm, omega: np.ndarray, period: float) -> np.ndarray:
    """The ZOH-sampled system ``C (zI − Φ)⁻¹ Γ + D`` at ``z = e^{jωT}`` (input held over each period,
    output sampled): array (n_out, n_in, n_omega). Exact: Φ = e^{AT}, Γ = ∫₀ᵀ e^{At} dt B."""
    z = np.exp(1j * np.asarray(omega, dtype=float) * period)
    k = form.A1.shape[0]
    if k:
        aug = np.zeros((k + form.B1.shape[1], k + form.B1.shape[1]))
        aug[:k, :k] = form.A1 * period
        aug[:k, k:] = form.B1 * period
        E = scipy.linalg.expm(aug)
        phi1, gam1 = E[:k, :k], E[:k, k:]
    else:
        phi1, gam1 = np.zeros((0, 0)), form.B1
    mu = np.exp(form.lam * period)
    x = form.lam * period
    safe = np.where(np.abs(x) > 1e-300, x, 1.0)
    gain = np.where(np.abs(x) > 1e-300, np.expm1(safe) / safe, 1.0) * period  # ∫₀ᵀ e^{λt} dt
    part1 = np.einsum("ik,kjw->ijw", form.C1, _apply(_resolvent(phi1, z), gam1)) if k else 0.0
    part2 = np.einsum("ik,kw,kj->ijw", form.C2, 1.0 / (z[None, :] - mu[:, None]), gain[:, None] * form.B2)
    return (part1 + part2 + form.D[:, :, None]).astype(complex)


def _evaluate(form: ModalForm, s, diag, resolvent):
    k = form.A1.shape[0]
    part2 = np.einsum("ik,kw,kj->ijw", form.C2, diag(form.lam), form.B2)
    part1 = np.einsum("ik,kjw->ijw", form.C1, _apply(resolvent(form.A1), form.B1)) if k else 0.0
    return (part1 + part2 + form.D[:, :, None]).astype(complex)


def _resolvent(A1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``(s I − A1)⁻¹`` for each s: array (n_s, k, k)."""
    k = A1.shape[0]
    M = s[:, None, None] * np.eye(k)[None] - A1[None]
    return np.linalg.inv(M)


def _apply(resolvents: np.ndarray, B1: np.ndarray) -> np.ndarray:
    """(n_s, k, k) @ (k, m) → (k, m, n_s)."""
    return np.einsum("wab,bj->ajw", resolvents, B1)


def zoh_matrices(A: np.ndarray, B: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH discretisation: ``Φ = e^{AT}``, ``Γ = ∫₀ᵀ e^{At} dt B``."""
    n, m = A.shape[0], B.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A * period
    aug[:n, n:] = B * period
    E = scipy.linalg.expm(aug)
    return E[:n, :n], E[:n, n:]


STATIC_POLE_TOL = 1e-9
""":func:`static_gain` takes the eigenvalues within ``STATIC_POLE_TOL · max(1, ‖A‖₁)`` (``A``
diagonally balanced) of the point ``s = 0`` or ``z = 1`` as poles *at* it. A pole at exactly the
point (an integrator, a rigid-body drift) is computed to ``eps·‖A‖/sep`` (≈ 1e-16 on the 5M4S
loops, whose next eigenvalue is 1e-2 away); the tolerance leaves seven orders of magnitude on both
sides: a pole ``1e-9·‖A‖`` away from 0 is a time constant of hours for a feed axis."""


def static_gain(A, B, C, D=None, *, discrete: bool) -> np.ndarray:
    """The exact value at ω = 0 of ``C (pI − A)⁻¹ B + D``: at ``p = 1`` (``z = 1``) for a discrete
    ``A``, at ``p = 0`` (``s = 0``) for a continuous one.

    Eigenvalues at the point (within :data:`STATIC_POLE_TOL`) are split off by an ordered real
    Schur form and a Sylvester equation: with ``N = A₁ − pI`` (made exactly nilpotent), their part
    of the transfer is ``Σⱼ C₁Nʲ B₁ / (p' − p)^{j+1}``, a polynomial in ``1/(p' − p)`` without a
    constant term. When every coefficient vanishes (the pole is not seen from that input to that
    output, e.g. the drift of the rigid-body position in a velocity loop: the positions ramp, the
    measured velocity does not) the singularity is removable and the value is that of the other
    part, ``D + C₂ (pI − A₂)⁻¹ B₂``, the exact limit; otherwise the entry is ``inf`` (a pole at 0).

    Parameters
    ----------
    A, B, C : array_like
        State space, shapes ``(n, n)``, ``(n, m)``, ``(q, n)``.
    D : array_like, optional
        Feedthrough ``(q, m)``; zero by default.
    discrete : bool
        True for a sampled system (evaluated at ``z = 1``), False for a continuous one (``s = 0``).

    Returns
    -------
    ndarray, shape (q, m)
        Real static gains; ``inf`` for an entry with a pole at the point.

    Examples
    --------
    A velocity loop ``1/(m s)`` under a PI ``Kp (1 + 1/(Ti s))``, states (position, velocity,
    integral): the position drifts (a pole at 0 the measured velocity does not see) and the closed
    loop's static gain is exactly 1:

    >>> import numpy as np
    >>> m, kp, ti = 2.0, 50.0, 0.1
    >>> A = np.array([[0, 1, 0], [0, -kp / m, 1 / m], [0, -kp / ti, 0]])
    >>> B = np.array([[0], [kp / m], [kp / ti]])
    >>> round(float(static_gain(A, B, [[0, 1, 0]], discrete=False)[0, 0]), 12)
    1.0
    >>> float(static_gain(A, B, [[1, 0, 0]], discrete=False)[0, 0])   # the position: a pole at 0
    inf
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    C = np.asarray(C, dtype=float).reshape(-1, A.shape[0])
    D = np.zeros((C.shape[0], B.shape[1])) if D is None else np.asarray(D, dtype=float).reshape(C.shape[0], B.shape[1])
    n = A.shape[0]
    if n == 0:
        return D.copy()
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B)) and np.all(np.isfinite(C))):
        raise ValueError("static_gain: the state space has non-finite entries")
    p = 1.0 if discrete else 0.0
    _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    A = (A * scale[None, :]) / scale[:, None]
    B = B / scale[:, None]
    C = C * scale[None, :]
    tol = STATIC_POLE_TOL * max(1.0, float(np.linalg.norm(A, 1)))
    T, Z, k = scipy.linalg.schur(A, output="real", sort=lambda re, im: np.hypot(re - p, im) <= tol)
    Bz, Cz = Z.T @ B, C @ Z
    if k == 0:
        return D - Cz @ np.linalg.solve(T - p * np.eye(n), Bz)
    T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
    X = scipy.linalg.solve_sylvester(T11, -T22, -T12) if k < n else np.zeros((k, 0))
    B1, C1 = Bz[:k] - X @ Bz[k:], Cz[:, :k]
    B2, C2 = Bz[k:], Cz[:, :k] @ X + Cz[:, k:]
    out = D - C2 @ np.linalg.solve(T22 - p * np.eye(n - k), B2) if k < n else D.copy()
    # Laurent coefficients of the part at the point; "vanishing" is relative to round-off of C·B
    N = np.triu(T11 - p * np.eye(k), 1)
    floor = np.sqrt(np.finfo(float).eps) * np.linalg.norm(C, 2) * np.linalg.norm(B, 2)
    power = np.eye(k)
    seen = np.zeros(out.shape, dtype=bool)
    for j in range(k):
        seen |= np.abs(C1 @ power @ B1) > floor * max(1.0, float(np.linalg.norm(N, 2))) ** j
        power = power @ N
    return np.where(seen, np.inf, out)
