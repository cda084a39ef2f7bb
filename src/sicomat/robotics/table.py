"""The MDH description of a multi-body machine: :class:`MDHRobot`, built and validated from a table of
frames (Khalil–Kleinfinger modified Denavit–Hartenberg, SYMORO's field names)."""

from __future__ import annotations

import typing
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ..description.robot_table import (FIXED, FRAME_FIELDS, GEOMETRY_FIELDS, PARAMETER_FIELDS,
                                       check_frame, check_gravity, check_links, check_loops)
from ..errors import ModelError

if typing.TYPE_CHECKING:
    from .base import BaseParameters
    from .symbolic import SymbolicModels

__all__ = ["MDHRobot", "FRAME_FIELDS", "PARAMETER_FIELDS"]


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
    links : int or None
        NL when the robot has closed loops (:attr:`n_links`, :attr:`n_loops`), None for a tree.
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
    links: int | None = None
    """NL, the number of links (SYMORO's ``NL``); None for a tree (NL = NF). Frames NL+1..NL+B are the cut
    joints of the B closed loops, frames NL+B+1..NF their closing frames (see :meth:`from_table`)."""
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
                   gravity: Sequence[float] = (0.0, 0.0, -9.81), links: int | None = None) -> "MDHRobot":
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
        links : int, optional
            NL, the number of links, for a robot with closed loops (SYMORO's description, notes §1.3):
            frames 1..NL are a tree of links; the B = (NF - NL)/2 loops are each cut at one joint. Cut
            frame k (NL < k <= NL + B) is that joint, on link ``ant(k)``, a passive joint (``mu = eta = 0``)
            with no link of its own; its closing frame k + B (``sigma = 2``) sits on the other link,
            ``ant(k + B)``, and the loop is closed when ``0T_k(q) = 0T_{k+B}(q)``. None (default): a tree.

        Raises
        ------
        ModelError
            On the first bad entry, naming the frame and the field (``path = "frames[ROW].FIELD"``):
            an unknown key, a missing ``ant``/``sigma``, an antecedent not before its frame, ``sigma``
            not in 0/1/2, ``mu``/``eta`` not 0/1, an elastic or fixed frame marked motorised, a fixed
            frame marked elastic or given ``IA``, ``FV``, ``FS`` or ``k``, a non-finite number, a negative
            ``M``, ``k``, ``IA``, ``FV`` or ``FS``, or an inertia no real body has (not positive semi-definite about the centre of
            mass); with ``links``: an odd number of frames after NL, a loop whose cut frame is not a
            passive joint, a closing frame that is not fixed, a cut or closing frame with a link
            (inertial parameters) or hanging from a frame after NL, a closing frame on the cut frame's link.

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
        g = check_gravity(gravity)
        columns: dict[str, list[float]] = {name: [] for name in FRAME_FIELDS}
        for row, frame in enumerate(frames):
            values = check_frame(row, frame)
            for name in FRAME_FIELDS:
                columns[name].append(values[name])
        chi = np.array([[columns[name][row] for name in PARAMETER_FIELDS] for row in range(len(frames))],
                       dtype=float)
        ints = {name: np.array(columns[name], dtype=int) for name in ("ant", "sigma", "mu", "eta")}
        floats = {name: np.array(columns[name], dtype=float) for name in (*GEOMETRY_FIELDS, "k")}
        nl = check_links(links, len(frames))
        if nl is not None:
            check_loops(columns, nl)
        return cls(chi=chi, gravity=g, links=nl, **ints, **floats)

    # ------------------------------------------------------------------ sizes and names
    @property
    def n_frames(self) -> int:
        """NF, the number of frames (base excluded)."""
        return len(self.sigma)

    @property
    def n_links(self) -> int:
        """NL, the number of links (NF for a tree)."""
        return self.n_frames if self.links is None else self.links

    @property
    def n_loops(self) -> int:
        """B, the number of closed loops: ``(NF - NL) / 2``."""
        return (self.n_frames - self.n_links) // 2

    @property
    def n_joints(self) -> int:
        """The number of joint variables (frames that are not fixed)."""
        return len(self.joint_frames)

    def standard_parameters(self, stiffness: bool = False) -> np.ndarray:
        """The 13 standard parameters of every frame, frame by frame (``13 * NF``); with ``stiffness=True``
        followed by the stiffness ``k`` of each elastic joint (``eta = 1``) in joint order."""
        chi = self.chi.reshape(-1).copy()
        return np.concatenate([chi, self.k[self._elastic_rows()]]) if stiffness else chi

    def parameter_names(self, stiffness: bool = False) -> list[str]:
        """Names of :meth:`standard_parameters`: ``XX1 XY1 ... FS1 XX2 ...`` (then ``K2 K3 ...``, the
        stiffness of the elastic frames, with ``stiffness=True``)."""
        names = [f"{name}{j + 1}" for j in range(self.n_frames) for name in PARAMETER_FIELDS]
        return names + [f"K{row + 1}" for row in self._elastic_rows()] if stiffness else names

    def _elastic_rows(self) -> np.ndarray:
        return self.joint_frames[self.eta[self.joint_frames] == 1]

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

    def regressor(self, q: Any, qd: Any, qdd: Any, stiffness: bool = False) -> np.ndarray:
        """``Phi`` (n x 13 NF) with ``inverse_dynamics = Phi @ standard_parameters()`` (and the stiffness
        columns with ``stiffness=True``); see :func:`sicomat.robotics.dynamics.regressor`."""
        from .dynamics import regressor
        return regressor(self, q, qd, qdd, stiffness=stiffness)

    def base_parameters(self, **options: Any) -> "BaseParameters":
        """The base inertial parameters (numerical method); see :func:`sicomat.robotics.base.base_parameters`
        for the options (``parameters``, ``stiffness``, ``samples``, ``seed``, ``tol``)."""
        from .base import base_parameters
        return base_parameters(self, **options)

    def symbolic(self) -> "SymbolicModels":
        """The models in SymPy; see :func:`sicomat.robotics.symbolic.symbolic_models`."""
        from .symbolic import symbolic_models
        return symbolic_models(self)

