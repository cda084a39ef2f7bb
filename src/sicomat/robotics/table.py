"""The MDH description of a multi-body machine: :class:`MDHRobot`, built and validated from a table of
frames (Khalil–Kleinfinger modified Denavit–Hartenberg, SYMORO's field names)."""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import ModelError

if typing.TYPE_CHECKING:
    from .base import BaseParameters
    from .symbolic import SymbolicModels

__all__ = ["MDHRobot", "FRAME_FIELDS", "PARAMETER_FIELDS"]

GEOMETRY_FIELDS = ("gamma", "b", "alpha", "d", "theta", "r")
PARAMETER_FIELDS = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M", "IA", "FV", "FS")
"""The 13 standard parameters of a frame's link, in the order of :meth:`MDHRobot.standard_parameters`."""
FRAME_FIELDS = ("ant", "sigma", "mu", *GEOMETRY_FIELDS, "eta", "k", *PARAMETER_FIELDS)
"""Every key a row of the table may hold (``ant`` and ``sigma`` are required, the rest default to 0)."""

REVOLUTE, PRISMATIC, FIXED = 0, 1, 2
# Relative tolerance of the inertia check: the tensor about the centre of mass is computed as a
# difference J_O - (|MS|^2 I - MS MS^T)/M whose rounding is a few ulps of its terms; 1e-12 of the
# largest term accepts a point mass (exact zero tensor) written with rounded decimals and rejects
# any tensor that is wrong by a physically meaningful amount.
_INERTIA_RTOL = 1e-12


def _where(row: int, name: str) -> str:
    return f"frames[{row}].{name}"


def _error(row: int, name: str, message: str, value: object = None) -> ModelError:
    return ModelError(f"frame {row + 1}: {message}", path=_where(row, name), value=value,
                      has_value=value is not None)


def _integer(row: int, name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral):
        if isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value)) \
                and float(value).is_integer():
            return int(float(value))
        raise _error(row, name, f"{name} must be an integer", value)
    return int(value)


def _number(row: int, name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise _error(row, name, f"{name} must be a number", value)
    number = float(value)
    if not math.isfinite(number):
        raise _error(row, name, f"{name} must be finite", value)
    return number


def _check_inertia(row: int, chi: np.ndarray) -> None:
    """The link's inertia tensor about its centre of mass must be positive semi-definite.

    The triangle inequality of the principal moments (I1 + I2 >= I3, true of any real body) is not
    required: planar models commonly give only ``ZZ``, which is harmless for their dynamics."""
    xx, xy, xz, yy, yz, zz, mx, my, mz, mass = chi[:10]
    j_origin = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    ms = np.array([mx, my, mz])
    if mass == 0.0:
        for name, value in zip(("MX", "MY", "MZ"), ms):
            if value != 0.0:
                raise _error(row, name, f"a massless link (M = 0) has no first moment, but {name} != 0",
                             float(value))
        j_com = j_origin
        scale = float(np.max(np.abs(j_origin)))
    else:
        shift = (ms @ ms * np.eye(3) - np.outer(ms, ms)) / mass
        j_com = j_origin - shift
        scale = max(float(np.max(np.abs(j_origin))), float(np.max(np.abs(shift))))
    moments = np.linalg.eigvalsh(j_com)
    tol = _INERTIA_RTOL * scale
    if moments[0] < -tol:
        raise _error(row, "XX..ZZ", "the inertia tensor XX..ZZ about the centre of mass (J_O - M(c^2 I - c c^T), "
                     f"c = MS/M) is not positive semi-definite: principal moments {moments.tolist()}")


@dataclass(frozen=True, eq=False)
class MDHRobot:
    """A tree of rigid links described frame by frame in modified Denavit–Hartenberg parameters.

    Frames are numbered 1..NF (row ``j - 1`` of the table is frame ``j``), frame 0 is the fixed base.
    The joint variables ``q`` are those of the frames with ``sigma`` 0 (revolute, ``q`` adds to
    ``theta``) or 1 (prismatic, ``q`` adds to ``r``), in frame order; fixed frames (``sigma = 2``)
    have none. SI units throughout (rad, m, kg, kg m^2). Build one with :meth:`from_table`.

    Attributes
    ----------
    ant, sigma, mu, eta : ndarray of int, shape (NF,)
        Antecedent frame number (0 = base), joint type, motorised flag, elastic flag.
    gamma, b, alpha, d, theta, r, k : ndarray of float, shape (NF,)
        Geometric constants and the joint stiffness (``k``, used by elastic joints).
    chi : ndarray, shape (NF, 13)
        The standard parameters ``XX XY XZ YY YZ ZZ MX MY MZ M IA FV FS`` of each frame's link, the
        inertia about the frame origin in the frame (Khalil's convention, ``XY = -∫xy dm``).
    gravity : ndarray, shape (3,)
        Gravity acceleration in the base frame (m/s^2).
    """

    ant: np.ndarray
    sigma: np.ndarray
    mu: np.ndarray
    eta: np.ndarray
    gamma: np.ndarray
    b: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    theta: np.ndarray
    r: np.ndarray
    k: np.ndarray
    chi: np.ndarray
    gravity: np.ndarray
    joint_of_frame: np.ndarray = field(init=False, repr=False)
    """Index in ``q`` of each frame's joint variable, -1 for a fixed frame."""
    joint_frames: np.ndarray = field(init=False, repr=False)
    """Row (frame number - 1) of each joint variable."""

    def __post_init__(self) -> None:
        movable = self.sigma != FIXED
        index = np.full(len(self.sigma), -1, dtype=int)
        index[movable] = np.arange(int(movable.sum()))
        object.__setattr__(self, "joint_of_frame", index)
        object.__setattr__(self, "joint_frames", np.flatnonzero(movable))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_table(cls, frames: Sequence[Mapping[str, Any]],
                   gravity: Sequence[float] = (0.0, 0.0, -9.81)) -> "MDHRobot":
        """Build and validate a robot from one mapping per frame.

        Parameters
        ----------
        frames : sequence of mappings
            Row ``j - 1`` describes frame ``j`` with the keys of :data:`FRAME_FIELDS`: ``ant``
            (antecedent, ``0 <= ant < j``) and ``sigma`` (0 revolute, 1 prismatic, 2 fixed) are
            required; ``mu`` (1 motorised), ``gamma b alpha d theta r`` (rad, m), ``eta`` (1 elastic),
            ``k`` (stiffness) and the link's ``XX XY XZ YY YZ ZZ`` (kg m^2, about the frame origin),
            ``MX MY MZ`` (kg m), ``M`` (kg), ``IA`` (rotor inertia), ``FV`` (viscous), ``FS`` (dry
            friction) default to 0.
        gravity : sequence of 3 floats
            Gravity in the base frame, m/s^2.

        Raises
        ------
        ModelError
            On the first bad entry, naming the frame and the field (``path = "frames[ROW].FIELD"``):
            an unknown key, a missing ``ant``/``sigma``, an antecedent not before its frame, ``sigma``
            not in 0/1/2, ``mu``/``eta`` not 0/1, an elastic or fixed frame marked motorised, a fixed
            frame marked elastic or given ``IA``, ``FV``, ``FS`` or ``k``, a non-finite number, a negative
            ``M``, ``k``, ``IA``, ``FV`` or ``FS``, or an inertia no real body has (not positive semi-definite about the centre of
            mass). Closed loops (cut frames) are not supported yet: every fixed frame is rigidly
            attached to its antecedent.

        Examples
        --------
        >>> arm = MDHRobot.from_table([{"ant": 0, "sigma": 0, "ZZ": 1.0},  # ZZ alone: allowed
        ...                            {"ant": 1, "sigma": 0, "d": 0.5, "M": 2.0, "MX": 0.5,
        ...                             "XX": 0.01, "YY": 0.2, "ZZ": 0.2}])  # YY, ZZ >= MX^2/M
        >>> arm.n_joints
        2
        """
        if isinstance(frames, Mapping) or not isinstance(frames, Sequence):
            raise ModelError("the robot's frames must be a list of tables, one per frame", path="frames")
        if len(frames) == 0:
            raise ModelError("the robot has no frames", path="frames")
        g = _gravity(gravity)
        columns: dict[str, list[float]] = {name: [] for name in FRAME_FIELDS}
        for row, frame in enumerate(frames):
            values = _row(row, frame)
            for name in FRAME_FIELDS:
                columns[name].append(values[name])
        chi = np.array([[columns[name][row] for name in PARAMETER_FIELDS] for row in range(len(frames))],
                       dtype=float)
        ints = {name: np.array(columns[name], dtype=int) for name in ("ant", "sigma", "mu", "eta")}
        floats = {name: np.array(columns[name], dtype=float) for name in (*GEOMETRY_FIELDS, "k")}
        return cls(chi=chi, gravity=g, **ints, **floats)

    # ------------------------------------------------------------------ sizes and names
    @property
    def n_frames(self) -> int:
        """NF, the number of frames (base excluded)."""
        return len(self.sigma)

    @property
    def n_joints(self) -> int:
        """The number of joint variables (frames that are not fixed)."""
        return len(self.joint_frames)

    def standard_parameters(self) -> np.ndarray:
        """The 13 standard parameters of every frame, frame by frame (``13 * NF``)."""
        return self.chi.reshape(-1).copy()

    def parameter_names(self) -> list[str]:
        """Names of :meth:`standard_parameters`: ``XX1 XY1 ... FS1 XX2 ...``."""
        return [f"{name}{j + 1}" for j in range(self.n_frames) for name in PARAMETER_FIELDS]

    # ------------------------------------------------------------------ models (free functions)
    def transforms(self, q: Any) -> np.ndarray:
        """``0T_j`` for j = 0..NF, shape (NF+1, 4, 4); see :func:`sicomat.robotics.geometry.transforms`."""
        from .geometry import transforms
        return transforms(self, q)

    def transform(self, q: Any, j: int, i: int = 0) -> np.ndarray:
        """``iT_j``, frame j in frame i (4x4); see :func:`sicomat.robotics.geometry.transform`."""
        from .geometry import transform
        return transform(self, q, j, i)

    def jacobian(self, q: Any, j: int) -> np.ndarray:
        """Jacobian of frame j, 6 x n, base frame, linear then angular; see
        :func:`sicomat.robotics.geometry.jacobian`."""
        from .geometry import jacobian
        return jacobian(self, q, j)

    def inverse_dynamics(self, q: Any, qd: Any, qdd: Any) -> np.ndarray:
        """Joint torques/forces by Newton–Euler; see :func:`sicomat.robotics.dynamics.inverse_dynamics`."""
        from .dynamics import inverse_dynamics
        return inverse_dynamics(self, q, qd, qdd)

    def inverse_dynamics_batch(self, q: Any, qd: Any, qdd: Any) -> np.ndarray:
        """:meth:`inverse_dynamics` over many states, arrays (n_states, n)."""
        from .dynamics import inverse_dynamics_batch
        return inverse_dynamics_batch(self, q, qd, qdd)

    def inertia_matrix(self, q: Any) -> np.ndarray:
        """The joint-space inertia matrix by composite links (n x n, rotor inertias included)."""
        from .dynamics import inertia_matrix
        return inertia_matrix(self, q)

    def direct_dynamics(self, q: Any, qd: Any, tau: Any) -> np.ndarray:
        """Joint accelerations under the torques ``tau``."""
        from .dynamics import direct_dynamics
        return direct_dynamics(self, q, qd, tau)

    def regressor(self, q: Any, qd: Any, qdd: Any) -> np.ndarray:
        """``Phi`` (n x 13 NF) with ``inverse_dynamics = Phi @ standard_parameters()``."""
        from .dynamics import regressor
        return regressor(self, q, qd, qdd)

    def base_parameters(self, **options: Any) -> "BaseParameters":
        """The base inertial parameters (numerical method); see :func:`sicomat.robotics.base.base_parameters`
        for the options (``parameters``, ``samples``, ``seed``, ``tol``)."""
        from .base import base_parameters
        return base_parameters(self, **options)

    def symbolic(self) -> "SymbolicModels":
        """The models in SymPy; see :func:`sicomat.robotics.symbolic.symbolic_models`."""
        from .symbolic import symbolic_models
        return symbolic_models(self)


def _gravity(gravity: object) -> np.ndarray:
    try:
        g = np.asarray(gravity, dtype=float)
    except (TypeError, ValueError):
        raise ModelError("gravity must be 3 numbers (m/s^2, base frame)", path="gravity", value=gravity) from None
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ModelError("gravity must be 3 finite numbers (m/s^2, base frame)", path="gravity", value=gravity)
    return g


def _row(row: int, frame: object) -> dict[str, float]:
    """One row checked: every key known, every value of its kind, the flags consistent."""
    j = row + 1
    if not isinstance(frame, Mapping):
        raise ModelError(f"frame {j}: each frame is a table of fields", path=f"frames[{row}]", value=frame)
    for key in frame:
        if key not in FRAME_FIELDS:
            raise _error(row, str(key), f"unknown field {key!r}; expected one of {', '.join(FRAME_FIELDS)}")
    for key in ("ant", "sigma"):
        if key not in frame:
            raise _error(row, key, f"the field {key!r} is required")
    values: dict[str, float] = {}
    ant = _integer(row, "ant", frame["ant"])
    if not 0 <= ant < j:
        raise _error(row, "ant", f"the antecedent must be a frame before frame {j} (0 = base .. {j - 1})", ant)
    sigma = _integer(row, "sigma", frame["sigma"])
    if sigma not in (REVOLUTE, PRISMATIC, FIXED):
        raise _error(row, "sigma", "sigma must be 0 (revolute), 1 (prismatic) or 2 (fixed)", sigma)
    values.update(ant=ant, sigma=sigma)
    for key in ("mu", "eta"):
        flag = _integer(row, key, frame.get(key, 0))
        if flag not in (0, 1):
            raise _error(row, key, f"{key} must be 0 or 1", flag)
        values[key] = flag
    if values["eta"] == 1 and values["mu"] == 1:
        raise _error(row, "mu", "an elastic joint (eta = 1) cannot be motorised (mu = 1): "
                     "put the motor on its own frame before the elastic one", 1)
    if sigma == FIXED and values["mu"] == 1:
        raise _error(row, "mu", "a fixed frame (sigma = 2) has no joint to motorise", 1)
    if sigma == FIXED and values["eta"] == 1:
        raise _error(row, "eta", "a fixed frame (sigma = 2) has no joint to be elastic", 1)
    for key in (*GEOMETRY_FIELDS, "k", *PARAMETER_FIELDS):
        values[key] = _number(row, key, frame.get(key, 0.0))
    for key in ("M", "k", "IA", "FV", "FS"):
        if values[key] < 0.0:
            raise _error(row, key, f"{key} must not be negative", values[key])
    if sigma == FIXED:
        for key in ("IA", "FV", "FS", "k"):
            if values[key] != 0.0:
                raise _error(row, key, f"a fixed frame (sigma = 2) has no joint: {key} must be 0", values[key])
    _check_inertia(row, np.array([values[name] for name in PARAMETER_FIELDS]))
    return values
