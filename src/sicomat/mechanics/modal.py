"""Modal analysis (paper III.A): undamped and damped natural frequencies, damping ratios, mode shapes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import linear_sum_assignment

if TYPE_CHECKING:  # pragma: no cover
    import pandas

    from .lumped import Mechanics
    from ..progress import ProgressCallback

__all__ = ["Mode", "ModalResult", "modal_analysis"]

_TWO_PI = 2.0 * np.pi
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Mode:
    """One mode of the mechanics.

    Attributes
    ----------
    frequency_hz : float
        Natural frequency ``|λ|/2π`` of the mode's pole pair (0 for a rigid-body mode).
    damping_ratio : float
        ``−Re λ / |λ|`` (0 for a rigid-body mode).
    damped_frequency_hz : float
        ``Im λ / 2π`` (0 for rigid or overdamped modes).
    undamped_hz : float
        Frequency of the undamped problem ``K φ = ω² M φ``.
    shape : dict
        Undamped mode shape per dof name, largest component +1.
    rigid : bool
        True for a rigid-body motion (a free motion of the mechanism, ``K φ = 0``).
    participation : float
        Share of the actuator-to-sensor static compliance carried by this mode (flexible modes sum
        to 1; 0 for rigid modes or when the mechanics has no actuator or sensor).
    """

    frequency_hz: float
    damping_ratio: float
    damped_frequency_hz: float
    undamped_hz: float
    shape: dict[str, float]
    rigid: bool
    participation: float = 0.0

    @property
    def dominant_dof(self) -> str:
        """The dof with the largest amplitude in this mode."""
        return max(self.shape, key=lambda k: abs(self.shape[k]))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return {"frequency_hz": self.frequency_hz, "damping_ratio": self.damping_ratio,
                "damped_frequency_hz": self.damped_frequency_hz, "undamped_hz": self.undamped_hz,
                "rigid": self.rigid, "dominant_dof": self.dominant_dof,
                "participation": self.participation, "shape": dict(self.shape)}


@dataclass(frozen=True, eq=False)
class ModalResult:
    """Result of :func:`modal_analysis`: modes in ascending frequency, rigid modes first."""

    dofs: tuple[str, ...]
    modes: tuple[Mode, ...]
    poles: np.ndarray

    @property
    def undamped_hz(self) -> np.ndarray:
        """Undamped natural frequencies (Hz), ascending, rigid modes exactly 0."""
        return np.sort([m.undamped_hz for m in self.modes])

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies of the damped modes (Hz), in mode order."""
        return np.array([m.frequency_hz for m in self.modes])

    @property
    def damping_ratios(self) -> np.ndarray:
        """Damping ratios, in mode order."""
        return np.array([m.damping_ratio for m in self.modes])

    @property
    def shapes(self) -> np.ndarray:
        """Mode shapes as columns of an ``(n_dofs, n_modes)`` array, dofs in :attr:`dofs` order."""
        return np.array([[m.shape[d] for m in self.modes] for d in self.dofs])

    @property
    def n_rigid(self) -> int:
        """Number of rigid-body modes."""
        return sum(m.rigid for m in self.modes)

    @property
    def f_meca_hz(self) -> float | None:
        """Suggested first flexible frequency for the loop bandwidths (Hz).

        The lowest flexible mode that carries at least 1 % of the actuator-to-sensor static
        compliance (so a mode the motor cannot excite or the sensors cannot see is skipped); the
        lowest flexible mode when the mechanics has no actuator or sensor; ``None`` when rigid.
        """
        flexible = [m for m in self.modes if not m.rigid]
        if not flexible:
            return None
        if any(m.participation > 0 for m in flexible):
            return next(m.frequency_hz for m in flexible if m.participation >= 0.01)
        return flexible[0].frequency_hz

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (the ``sicomat modal --json`` contract)."""
        return {"dofs": list(self.dofs), "undamped_hz": [float(f) for f in self.undamped_hz],
                "f_meca_hz": self.f_meca_hz, "modes": [m.to_dict() for m in self.modes]}

    def to_pandas(self) -> "pandas.DataFrame":
        """One row per mode: frequencies, damping, dominant dof and the shape per dof."""
        import pandas as pd

        rows = []
        for m in self.modes:
            row = {"frequency_hz": m.frequency_hz, "damping_ratio": m.damping_ratio,
                   "damped_frequency_hz": m.damped_frequency_hz, "undamped_hz": m.undamped_hz,
                   "rigid": m.rigid, "participation": m.participation, "dominant_dof": m.dominant_dof}
            row.update({f"shape.{d}": m.shape[d] for d in self.dofs})
            rows.append(row)
        frame = pd.DataFrame(rows)
        frame.index = pd.RangeIndex(1, len(rows) + 1, name="mode")
        return frame

    def plot(self, max_modes: int = 8):
        """Bar charts of the mode shapes per dof, one panel per mode, frequencies in the titles.

        Returns the matplotlib ``Figure``.
        """
        from ..plots.modes import plot_modes

        return plot_modes(self, max_modes=max_modes)


def modal_analysis(mech: "Mechanics", *, progress: "ProgressCallback | None" = None) -> ModalResult:
    """Natural frequencies, damping ratios and mode shapes of a lumped mechanics.

    ``progress`` (:mod:`sicomat.progress`) is told the four phases (undamped modes, poles, matching,
    participation); on a few thousand bodies the poles take most of the time.

    Undamped: the generalized symmetric eigenproblem ``K φ = ω² M φ`` solved on the M-orthogonal
    complement of the rigid-body motions, which are found from the couplings' geometry and
    reported as exactly 0 Hz. Damped: the poles of the state matrix, each complex pair assigned to
    the undamped mode whose shape it matches best (MAC), overdamped modes from pairs of real poles.

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> res = modal_analysis(build_mechanics(ChainSpec(type="chain", masses=[1, 1], stiffnesses=[2])))
    >>> [round(float(f) * 2 * 3.141592653589793, 6) for f in res.undamped_hz]
    [0.0, 2.0]
    """
    from .conditioning import check_resolvable

    check_resolvable(mech)
    from ..progress import notify

    n = mech.n
    M, D = mech.mass, mech.damping
    task = f"modal analysis of {n} bodies"
    notify(progress, task, 0, 4)
    omega, shapes, r = _undamped(mech)
    notify(progress, task, 1, 4)
    poles, vectors = np.linalg.eig(mech.state_space().A)
    notify(progress, task, 2, 4)
    freq, zeta, damped = _match_poles(shapes, omega, r, poles, vectors[:n], M, D)
    notify(progress, task, 3, 4)
    participation = _participation(mech, shapes, omega, r)
    notify(progress, task, 4, 4)

    modes = []
    for i in range(n):
        phi = shapes[:, i]
        phi = phi / phi[np.argmax(np.abs(phi))]
        phi[np.abs(phi) < 1e-12] = 0.0
        modes.append(Mode(frequency_hz=float(freq[i] / _TWO_PI), damping_ratio=float(zeta[i]),
                          damped_frequency_hz=float(damped[i] / _TWO_PI),
                          undamped_hz=float(omega[i] / _TWO_PI),
                          shape={d: float(v) for d, v in zip(mech.dof_names, phi)},
                          rigid=i < r, participation=float(participation[i])))
    _check_passive(modes)
    order = sorted(range(n), key=lambda i: (0 if modes[i].rigid else 1, modes[i].frequency_hz))
    return ModalResult(dofs=mech.dof_names, modes=tuple(modes[i] for i in order), poles=poles)


_NEGATIVE_DAMPING = float(np.sqrt(np.finfo(float).eps))
"""A passive mechanics (M > 0, K ≥ 0, D ≥ 0) has damping ratios ≥ 0: one below −√ε (1.5e-8) is not
rounding noise of a resolved pole (an undamped 1e17-spread chain gives −6e-14) but a lost one."""


def _check_passive(modes: list[Mode]) -> None:
    """Refuse to report modes that cannot be right: non-finite figures, or a negative damping ratio
    of a passive mechanics (see :mod:`sicomat.mechanics.conditioning` for the check made on the model)."""
    from ..errors import AnalysisError

    for m in modes:
        figures = (m.frequency_hz, m.damping_ratio, m.damped_frequency_hz, m.undamped_hz, m.participation)
        if not all(np.isfinite(figures)) or m.damping_ratio < -_NEGATIVE_DAMPING:
            raise AnalysisError(f"the modal analysis of the mode dominated by {m.dominant_dof!r} is not resolved in "
                                "double precision (a passive mechanics cannot have a negative damping ratio or "
                                "non-finite figures); the stiffnesses or masses differ too much")


def _undamped(mech: "Mechanics") -> tuple[np.ndarray, np.ndarray, int]:
    """Undamped frequencies (ascending, rigid first and exactly 0), shapes and the rigid count.

    ``K = Gᵀ diag(k) G`` with the couplings' stretch vectors G and ``M = L Lᵀ`` (Cholesky; for a
    diagonal M, ``L = M^{1/2}``), so ``K φ = ω² M φ`` becomes ``RᵀR ψ = ω² ψ`` with
    ``R = diag(√k) G L⁻ᵀ`` and ``φ = L⁻ᵀ ψ``: the natural frequencies are the singular values of R
    and the shapes ``L⁻ᵀ`` times its right singular vectors. The SVD gets ω to an absolute accuracy
    ``ε·ω_max`` (the eigenproblem of K gets ω² to ``ε·ω²_max``), so soft modes beside stiffnesses of
    1e12 stay accurate; a full M adds its condition number to that bound (``L`` is as well
    conditioned as ``√κ(M)``).
    """
    n = mech.n
    factor = mech.mass_factor
    springs = [link for link in mech.couplings if link.stiffness > 0]
    r = mech.rigid_modes().shape[1]
    if not springs:
        return np.zeros(n), np.eye(n), n
    R = factor.half_solve(np.vstack([np.sqrt(link.stiffness) * link.g for link in springs]).T).T
    _, sigma, vt = np.linalg.svd(R, full_matrices=True)
    values = np.zeros(n)
    values[: sigma.size] = sigma
    order = np.argsort(values)
    omega = values[order]
    omega[:r] = 0.0
    shapes = factor.half_solve(vt.T[:, order], transposed=True)
    return omega, shapes, r


def _mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``a`` and ``b``."""
    num = np.abs(a.conj().T @ b) ** 2
    den = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    return num / np.where(den > 0, den, 1.0)


def _match_poles(shapes, omega, r, poles, pos_vectors, M, D):
    n = len(omega)
    freq = np.zeros(n)
    zeta = np.zeros(n)
    damped = np.zeros(n)
    flex = np.arange(r, n)
    if flex.size == 0:
        return freq, zeta, damped
    scale = max(np.max(np.abs(poles)), 1.0)
    # A rigid motion is a double pole at 0; rounding (a backward error eps*|A| on a defective
    # double zero) splits it into about +-sqrt(eps*|A|), e.g. +-1.1e-7 j beside |A| ~ 200: such a
    # pair is not a flexible mode's pole. At most 2r poles, each below 10 sqrt(eps*scale), are set aside.
    near_zero = [j for j in np.argsort(np.abs(poles))[: 2 * r] if abs(poles[j]) <= 10.0 * np.sqrt(_EPS * scale)]
    usable = np.ones(poles.size, dtype=bool)
    usable[near_zero] = False
    oscillating = np.flatnonzero((poles.imag > 1e-12 * scale) & usable)
    matched = set()
    if oscillating.size:
        mac = _mac(shapes[:, flex], pos_vectors[:, oscillating])
        ratio = np.abs(np.log(np.abs(poles[oscillating])[None, :] / np.maximum(omega[flex], 1e-300)[:, None]))
        rows, cols = linear_sum_assignment((1.0 - mac) + ratio)
        for i, j in zip(rows, cols):
            lam = poles[oscillating[j]]
            k = flex[i]
            freq[k], zeta[k], damped[k] = abs(lam), -lam.real / abs(lam), lam.imag
            matched.add(k)
    real_idx = [j for j in np.flatnonzero((np.abs(poles.imag) <= 1e-12 * scale) & usable)
                if abs(poles[j]) > 1e-9 * scale]
    for k in flex:
        if k in matched:
            continue
        phi = shapes[:, [k]]
        if len(real_idx) >= 2:  # overdamped: the two real poles whose vectors match the shape best
            mac = _mac(phi, pos_vectors[:, real_idx])[0]
            best = np.argsort(mac)[-2:]
            lam1, lam2 = (poles[real_idx[b]].real for b in best)
            for b in sorted(best, reverse=True):
                real_idx.pop(b)
            freq[k] = np.sqrt(lam1 * lam2)
            zeta[k] = -(lam1 + lam2) / (2.0 * freq[k])
        else:  # no pole left (degenerate): modal projection of the damping
            m = (phi.T @ M @ phi).item()
            freq[k] = omega[k]
            zeta[k] = (phi.T @ D @ phi).item() / (2.0 * omega[k] * m) if omega[k] > 0 else 0.0
    return freq, zeta, damped


def _participation(mech, shapes, omega, r) -> np.ndarray:
    """Each flexible mode's share of the static actuator-to-sensor compliance (flexible part)."""
    n = mech.n
    out = np.zeros(n)
    if not mech.actuators or not mech.sensors or r == n:
        return out
    B = np.column_stack([a.vector for a in mech.actuators])
    C = np.vstack([s.vector for s in mech.sensors])
    for k in range(r, n):
        phi = shapes[:, k]
        modal_mass = float(phi @ mech.mass @ phi)
        out[k] = np.abs(np.outer(C @ phi, phi @ B)).sum() / (modal_mass * omega[k] ** 2)
    total = out.sum()
    return out / total if total > 0 else out
