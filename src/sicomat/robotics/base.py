"""The base inertial parameters of an :class:`~sicomat.robotics.MDHRobot` by the numerical method
(Gautier 1991): :func:`base_parameters` and its result :class:`BaseParameters`.

The regressor ``Phi`` (:func:`~sicomat.robotics.dynamics.regressor_batch`) is stacked over random
states into ``W``. Its zero columns are parameters with no effect on the torques (unidentifiable); of the
others, the columns are taken in the order of preference link 1 -> NF and, within a link, ``XX XY XZ YY YZ
ZZ MX MY MZ M IA FV FS`` (Khalil's choice of what to keep, e.g. ``XX2R = XX2 - YY2 - ...``), and a column
is kept when it is not a combination of the columns kept before it (Gram–Schmidt with
re-orthogonalisation). The count is checked against the rank of ``W`` read from a QR factorisation
*with column pivoting*: the pitfall of the notes (``shared/reference/robotics-formalism.md`` §2.7) is
to read it from the diagonal of an unpivoted QR, which under leading zero columns (a massless first
link) misses ranks. Each dropped column is ``W_dep = W_keep beta``, so
``Phi chi = Phi_keep (chi_keep + beta chi_dep)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import scipy.linalg

from ..errors import AnalysisError
from .dynamics import regressor_batch

if TYPE_CHECKING:  # table imports this module lazily (MDHRobot.base_parameters): no runtime import back
    from .table import MDHRobot

__all__ = ["BaseParameters", "base_parameters"]

# Default rank tolerance, relative, on columns scaled to unit norm (so independent of the units of
# XX, MX, M, FS...). Two kinds of numbers meet it:
# - a column that is structurally zero, or structurally a combination of earlier ones, leaves a
#   residual of rounding only: a few eps times sqrt(rows) ~ 1e-15..1e-14 (measured ~2e-15 on the RX-90,
#   the PUMA 560 and the elastic XY cross-slide; a zero column made of cos(pi/2) = 6e-17 terms is
#   ~2e-15 of the largest column);
# - a structurally independent column leaves a residual of the order of the geometry that separates
#   it, a ratio of lengths or its square: ~0.1 measured on those robots, and still ~1e-6 for a lever
#   of 1 mm on a 1 m machine taken squared.
# 1e-8 sits ~1e6 above the first and >= ~1e2 below the second. A length below ~1e-4 of the machine's
# size entering squared can fall under it: give exact zeros for lengths that are zero, and real values
# otherwise (the notes' pitfall (b): the count depends on which lengths are exactly zero).
DEFAULT_TOL = 1e-8
DEFAULT_SAMPLES = 60
_INERTIAL = 10    # XX..M, the first 10 of the 13 standard parameters of a link


@dataclass(frozen=True, eq=False)
class BaseParameters:
    """The base inertial parameters of a robot: a minimal set of combinations of the standard ones
    that the torques depend on.

    Attributes
    ----------
    names : tuple of str
        The standard parameter each base parameter is named after (``"ZZ1"``, ``"XX2"``...), in the
        order of preference.
    labels : tuple of str
        The same with Khalil's ``R`` when other parameters are regrouped into it (``"ZZ1R"``).
    indices : ndarray of int, shape (count,)
        Position of each ``names`` entry in :meth:`MDHRobot.standard_parameters` (``13 (j - 1) + c``),
        so ``regressor(q, qd, qdd)[:, indices]`` is the base regressor.
    dropped, dropped_indices : tuple of str, ndarray of int
        The standard parameters regrouped into the base ones (their columns are combinations of kept ones).
    unidentifiable : tuple of str
        The standard parameters with no effect on the torques (zero regressor columns).
    beta : ndarray, shape (count, len(dropped))
        Base parameter ``i`` is ``chi[indices[i]] + beta[i] @ chi[dropped_indices]``; entries below
        rounding (relative to the columns' scales) are exactly 0.
    values : ndarray, shape (count,)
        The base parameters of the robot's own standard parameters.
    parameters : {"all", "inertial"}
        Which standard parameters were considered: all 13 per link, or only ``XX..M`` (10 per link).
    n_standard : int
        The length of the robot's standard-parameter vector, ``13 NF`` (``+ n_e`` with ``stiffness``).
    stiffness : bool
        Whether the stiffness ``k`` of the elastic joints (``K2``...) was considered, after every link's
        parameters (:meth:`MDHRobot.standard_parameters` with ``stiffness=True``).
    """

    names: tuple[str, ...]
    labels: tuple[str, ...]
    indices: np.ndarray
    dropped: tuple[str, ...]
    dropped_indices: np.ndarray
    unidentifiable: tuple[str, ...]
    beta: np.ndarray
    values: np.ndarray
    parameters: str
    n_standard: int
    stiffness: bool = False

    @property
    def count(self) -> int:
        """The number of base parameters."""
        return len(self.names)

    @property
    def relations(self) -> tuple[str, ...]:
        """Each base parameter as text, e.g. ``"XX2R = XX2 - YY2 - 0.2025 M3 - ..."`` (``"XY5 = XY5"``
        when nothing is regrouped into it); coefficients to 6 significant digits."""
        out = []
        for label, name, row in zip(self.labels, self.names, self.beta):
            terms = [name]
            for coef, other in zip(row, self.dropped):
                if coef == 0.0:
                    continue
                sign = "-" if coef < 0 else "+"
                magnitude = abs(float(coef))
                shown = "" if math.isclose(magnitude, 1.0, rel_tol=1e-9) else f"{magnitude:.6g} "
                terms.append(f"{sign} {shown}{other}")
            out.append(f"{label} = {' '.join(terms)}")
        return tuple(out)

    def regroup(self, standard: Any) -> np.ndarray:
        """The base parameters (count,) of other standard parameters of the same robot, a vector laid
        out as :meth:`MDHRobot.standard_parameters` (``13 NF``, then the stiffnesses if ``stiffness``)."""
        chi = np.asarray(standard, dtype=float)
        if chi.shape != (self.n_standard,):
            layout = "13 per frame, then one stiffness per elastic joint" if self.stiffness else "13 per frame"
            raise ValueError(f"expected the {self.n_standard} standard parameters ({layout}), "
                             f"got shape {chi.shape}")
        return chi[self.indices] + self.beta @ chi[self.dropped_indices]

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-ready): ``count``, ``names``, ``labels``, ``relations``, ``values``,
        ``dropped``, ``unidentifiable``, ``parameters``."""
        return {"count": self.count, "names": list(self.names), "labels": list(self.labels),
                "relations": list(self.relations), "values": [float(v) for v in self.values],
                "dropped": list(self.dropped), "unidentifiable": list(self.unidentifiable),
                "parameters": self.parameters, "stiffness": self.stiffness}


def _random_states(robot: "MDHRobot", samples: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions uniform over a turn (revolute) or +-1 m (prismatic: no joint ranges in the table yet),
    speeds and accelerations uniform in +-1 (rad or m, per s, per s^2)."""
    rng = np.random.default_rng(seed)
    n = robot.n_joints
    prismatic = robot.sigma[robot.joint_frames] == 1
    q = rng.uniform(-math.pi, math.pi, (samples, n))
    q[:, prismatic] = rng.uniform(-1.0, 1.0, (samples, int(prismatic.sum())))
    return q, rng.uniform(-1.0, 1.0, (samples, n)), rng.uniform(-1.0, 1.0, (samples, n))


def _greedy(columns: np.ndarray, tol: float) -> list[int]:
    """Indices of the columns (unit norm, in preference order) kept by Gram–Schmidt: a column is
    kept when its residual against the ones kept before it exceeds ``tol``. Zero columns never
    are (they are removed before), so no rank is read from a diagonal."""
    basis = np.zeros((columns.shape[0], 0))
    kept: list[int] = []
    for index in range(columns.shape[1]):
        residual = columns[:, index].copy()
        for _ in range(2):          # twice is enough (Kahan–Parlett "twice is enough")
            residual -= basis @ (basis.T @ residual)
        norm = float(np.linalg.norm(residual))
        if norm > tol:
            basis = np.column_stack([basis, residual / norm])
            kept.append(index)
    return kept


def _pivoted_rank(columns: np.ndarray, tol: float) -> int:
    """Rank from a QR with column pivoting: ``|R_kk|`` is non-increasing, zero columns go last."""
    if columns.shape[1] == 0:
        return 0
    r = scipy.linalg.qr(columns, mode="r", pivoting=True)[0]
    diag = np.abs(np.diag(r))
    return int(np.sum(diag > tol * diag[0]))


def base_parameters(robot: "MDHRobot", *, parameters: Literal["all", "inertial"] = "all", stiffness: bool = False,
                    samples: int = DEFAULT_SAMPLES, seed: int = 0, tol: float = DEFAULT_TOL) -> BaseParameters:
    """The base parameters of a robot by the numerical method (QR of a random-sample regressor).

    Parameters
    ----------
    robot : MDHRobot
        Its geometry fixes the result (use the real lengths: which ones are exactly zero matters).
    parameters : {"all", "inertial"}
        ``"all"``: the 13 standard parameters per link (``IA``, ``FV``, ``FS`` included; the base model then
        gives the robot's :func:`~sicomat.robotics.dynamics.inverse_dynamics`); ``"inertial"``: only
        ``XX..M``, the torques less ``IA qdd + FV qd + FS sign(qd)``.
    stiffness : bool
        Also the stiffness ``k`` of each elastic joint (the regressor's column ``q_e e_e``), after every
        link's parameters in the order of preference: the base model then gives ``inverse_dynamics + k q``
        on the elastic rows (:func:`~sicomat.robotics.dynamics.regressor` with ``stiffness=True``).
    samples : int
        Random states stacked (``samples * n`` rows, at least as many as the parameters considered).
    seed : int
        Seed of the states: the same seed gives the same result.
    tol : float
        Relative tolerance of the rank, on columns scaled to unit norm (see the module's comment).

    Returns
    -------
    BaseParameters

    Raises
    ------
    ValueError
        On a bad argument, or a robot without joints.
    AnalysisError
        If the column selection does not reach the rank of the stacked regressor (a tolerance too close
        to the conditioning of these states: change ``tol`` or ``samples``).

    Examples
    --------
    A planar 2R arm with vertical axes (gravity has no effect): 4 inertial base parameters
    ``ZZ1R = ZZ1 + L^2 M2``, ``MX2``, ``MY2``, ``ZZ2``.

    >>> from sicomat.robotics import MDHRobot
    >>> arm = MDHRobot.from_table([{"ant": 0, "sigma": 0, "ZZ": 1.0},
    ...                            {"ant": 1, "sigma": 0, "d": 0.5, "M": 2.0, "MX": 0.5,
    ...                             "XX": 0.01, "YY": 0.2, "ZZ": 0.2}])
    >>> base = base_parameters(arm, parameters="inertial")
    >>> base.count, base.names
    (4, ('ZZ1', 'ZZ2', 'MX2', 'MY2'))
    >>> base.relations[0]
    'ZZ1R = ZZ1 + 0.25 M2'
    """
    if parameters not in ("all", "inertial"):
        raise ValueError(f"parameters must be 'all' or 'inertial', got {parameters!r}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ValueError(f"samples must be a positive integer, got {samples!r}")
    if not (isinstance(tol, (int, float)) and 0.0 < tol < 1.0):
        raise ValueError(f"tol must be a number in (0, 1), got {tol!r}")
    n = robot.n_joints
    if n == 0:
        raise ValueError("the robot has no joint (every frame is fixed): no torque, no base parameters")
    stride = robot.chi.shape[1]      # the 13 standard parameters of a link
    per_link = stride if parameters == "all" else _INERTIAL
    n_elastic = int(np.sum(robot.eta[robot.joint_frames] == 1)) if stiffness else 0
    considered = np.array([stride * row + c for row in range(robot.n_frames) for c in range(per_link)] +
                          [stride * robot.n_frames + i for i in range(n_elastic)])
    if samples * n < len(considered):
        raise ValueError(f"samples * n_joints = {samples * n} rows cannot show the rank of {len(considered)} "
                         f"parameters: use samples >= {-(-len(considered) // n)}")
    phi = regressor_batch(robot, *_random_states(robot, int(samples), seed), stiffness=bool(stiffness))
    w = phi.reshape(-1, phi.shape[-1])[:, considered]
    norms = np.linalg.norm(w, axis=0)
    nonzero = np.flatnonzero(norms > tol * norms.max()) if norms.max() > 0.0 else np.zeros(0, dtype=int)
    scaled = w[:, nonzero] / norms[nonzero]
    kept_local = _greedy(scaled, tol)
    rank = _pivoted_rank(scaled, tol)
    if len(kept_local) != rank:
        raise AnalysisError(f"the column selection kept {len(kept_local)} parameters but the stacked regressor has "
                            f"rank {rank}: the tolerance {tol:g} is too close to the conditioning of these states; "
                            "change tol or samples")
    dep_local = np.setdiff1d(np.arange(len(nonzero)), kept_local)
    keep_cols, dep_cols = scaled[:, kept_local], scaled[:, dep_local]
    beta_scaled = np.linalg.lstsq(keep_cols, dep_cols, rcond=None)[0] if len(dep_local) else \
        np.zeros((len(kept_local), 0))
    beta_scaled[np.abs(beta_scaled) <= tol] = 0.0     # rounding of an exact structural zero
    # back to the parameters' units: W_dep = W_keep beta  <=>  scaled_dep = scaled_keep (n_k^-1 beta n_d)
    kept_norms, dep_norms = norms[nonzero[kept_local]], norms[nonzero[dep_local]]
    beta = beta_scaled * dep_norms[None, :] / kept_norms[:, None]
    indices = considered[nonzero[kept_local]]
    dropped_indices = considered[nonzero[dep_local]]
    zero = np.setdiff1d(considered, considered[nonzero])
    names_all = robot.parameter_names(stiffness=bool(stiffness))
    names = tuple(names_all[i] for i in indices)
    labels = tuple(f"{name}R" if np.any(row != 0.0) else name for name, row in zip(names, beta))
    chi = robot.standard_parameters(stiffness=bool(stiffness))
    return BaseParameters(names=names, labels=labels, indices=indices,
                          dropped=tuple(names_all[i] for i in dropped_indices), dropped_indices=dropped_indices,
                          unidentifiable=tuple(names_all[i] for i in zero), beta=beta,
                          values=chi[indices] + beta @ chi[dropped_indices], parameters=parameters,
                          n_standard=len(chi), stiffness=bool(stiffness))
