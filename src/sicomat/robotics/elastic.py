"""Elastic joints (lumped elasticity, Khalil & Gautier 2000): the hybrid model and the direct dynamics
with the elastic torques applied (notes ``shared/reference/robotics-formalism.md`` §1.5, §2.5).

A joint with ``eta = 1`` is elastic: no motor drives it, its spring and damper do,
``Gamma_e = -k q_e - FV qd_e`` (``k`` the frame's stiffness, ``FV`` its viscous friction read as the
transmission's damping, ``q_e = 0`` the unloaded spring: the row's constant ``theta``/``r`` set the rest
geometry). The others (``eta = 0``) are rigid: their motion is imposed (hybrid model) or their torque
given (direct dynamics).

Bookkeeping of the damping. :func:`~sicomat.robotics.dynamics.inverse_dynamics` adds ``FV qd`` to every
joint's torque, elastic ones included, so at an elastic joint it returns ``Gamma_e + FV qd_e = -k q_e``:
the equation of an elastic joint is ``inverse_dynamics(q, qd, qdd)_e + k q_e = 0`` (the row the
stiffness column of the regressor closes, :func:`~sicomat.robotics.dynamics.regressor`). A rigid-body
code without joint friction (Pinocchio's ``rnea``) returns ``Gamma_e`` itself there.

Decision: an elastic joint has no dry friction. A lumped spring is a virtual joint (a screw's axial
deflection, a carriage's yaw on its guides) with no sliding surface of its own, and ``FS sign(qd_e)``
would chatter on a deflection that oscillates about 0; the notes' ``Gamma_e`` has none. An elastic
frame with ``FS != 0`` (legal in the table, where every joint is a joint) is refused here with a
``ModelError`` naming ``frames[ROW].FS``, rather than ignored silently.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError
from .dynamics import direct_dynamics, inertia_matrix, inverse_dynamics
from .geometry import joint_states

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["HybridDynamics", "hybrid_dynamics", "elastic_direct_dynamics", "elastic_joints", "rigid_joints",
           "elastic_torques"]

_FS = 12      # column of FS among the 13 standard parameters
_FV = 11


def elastic_joints(robot: "MDHRobot") -> np.ndarray:
    """Indices in ``q`` of the elastic joints (``eta = 1``), in joint order."""
    return np.flatnonzero(robot.eta[robot.joint_frames] == 1)


def rigid_joints(robot: "MDHRobot") -> np.ndarray:
    """Indices in ``q`` of the rigid joints (``eta = 0``), in joint order."""
    return np.flatnonzero(robot.eta[robot.joint_frames] == 0)


def _check_no_dry_friction(robot: "MDHRobot") -> None:
    for joint in elastic_joints(robot):
        row = int(robot.joint_frames[joint])
        fs = float(robot.chi[row, _FS])
        if fs != 0.0:
            raise ModelError(f"frame {row + 1}: an elastic joint (eta = 1) has no dry friction in the hybrid model "
                             "(Gamma_e = -k q - FV qd): FS must be 0", path=f"frames[{row}].FS", value=fs)


def _one_state(robot: "MDHRobot", x: Any, name: str, size: int | None = None) -> np.ndarray:
    if size is None:
        return _single(robot, x, name)
    array = np.asarray(x, dtype=float)
    if array.shape != (size,):
        raise ModelError(f"{name} must hold {size} values (one per {name.split('_')[-1]} joint, joint order), "
                         f"got shape {np.shape(x)}", path=name)
    if not np.all(np.isfinite(array)):
        raise ModelError(f"{name} must be finite", path=name)
    return array


def _single(robot: "MDHRobot", x: Any, name: str) -> np.ndarray:
    states = joint_states(robot, x, name)
    if states.shape[0] != 1:
        raise ModelError(f"{name}: this function takes one state", path=name)
    return states[0]


def elastic_torques(robot: "MDHRobot", q: Any, qd: Any) -> np.ndarray:
    """``Gamma_e = -k q_e - FV qd_e`` of the elastic joints (n_e,), the spring and damper on each."""
    q_, qd_ = _one_state(robot, q, "q"), _one_state(robot, qd, "qd")
    e = elastic_joints(robot)
    rows = robot.joint_frames[e]
    return -robot.k[rows] * q_[e] - robot.chi[rows, _FV] * qd_[e]


@dataclass(frozen=True, eq=False)
class HybridDynamics:
    """The hybrid model at one state (all arrays in joint order within their group).

    Attributes
    ----------
    qdd_elastic : ndarray, shape (n_e,)
        Accelerations of the elastic joints.
    tau_rigid : ndarray, shape (n_r,)
        Torques/forces of the rigid joints (motors; gravity, ``IA`` and friction included).
    tau_elastic : ndarray, shape (n_e,)
        ``Gamma_e = -k q_e - FV qd_e``, the spring and damper torques the elastic joints carry.
    qdd, tau : ndarray, shape (n,)
        All joints: ``qdd_rigid`` and ``qdd_elastic`` merged; ``tau_rigid`` and ``tau_elastic`` merged
        (the torque vector a frictionless rigid-body code, e.g. Pinocchio's ``aba``, takes for elastic joints).
    rigid, elastic : ndarray of int
        Indices in ``q`` of the rigid and the elastic joints.
    """

    qdd_elastic: np.ndarray
    tau_rigid: np.ndarray
    tau_elastic: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    rigid: np.ndarray
    elastic: np.ndarray


def hybrid_dynamics(robot: "MDHRobot", q: Any, qd: Any, qdd_rigid: Any) -> HybridDynamics:
    """The hybrid model: the rigid joints' accelerations imposed, the elastic joints' found.

    With ``h(qdd) = inverse_dynamics(q, qd, qdd)`` (gravity, ``IA``, friction; linear in ``qdd``):

        A_ee qdd_e = -k q_e - h_e([qdd_r, 0])        (elastic rows: h_e + k q_e = 0)
        tau_r = h_r([qdd_r, qdd_e])

    i.e. the notes' ``qdd_e = A_ee^-1 (Gamma_e - h_e - A_er qdd_r)``, ``Gamma_r = A_rr qdd_r + A_re qdd_e +
    h_r``: two Newton–Euler passes and the inertia matrix's elastic block, factorised by Cholesky.

    Parameters
    ----------
    q, qd : array_like, shape (n,)
        Positions and speeds of all joints (elastic deflections included).
    qdd_rigid : array_like, shape (n_r,)
        Accelerations of the rigid joints, in joint order.

    Raises
    ------
    ModelError
        On a bad state, an elastic joint with ``FS != 0`` (see the module), or an ``A_ee`` that is singular
        (an elastic joint that moves no mass and has no ``IA``).
    """
    _check_no_dry_friction(robot)
    q_, qd_ = _one_state(robot, q, "q"), _one_state(robot, qd, "qd")
    r, e = rigid_joints(robot), elastic_joints(robot)
    qdd_r = _one_state(robot, qdd_rigid, "qdd_rigid", len(r))
    qdd = np.zeros(robot.n_joints)
    qdd[r] = qdd_r
    tau_e = elastic_torques(robot, q_, qd_)
    if len(e):
        rows = robot.joint_frames[e]
        rhs = -robot.k[rows] * q_[e] - inverse_dynamics(robot, q_, qd_, qdd)[e]
        a_ee = inertia_matrix(robot, q_)[np.ix_(e, e)]
        qdd[e] = _cholesky_solve(a_ee, rhs)
    tau = inverse_dynamics(robot, q_, qd_, qdd)
    tau[e] = tau_e
    return HybridDynamics(qdd_elastic=qdd[e], tau_rigid=tau[r], tau_elastic=tau_e, qdd=qdd, tau=tau, rigid=r,
                          elastic=e)


def _cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        factor = np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        raise ModelError("the inertia matrix of the elastic joints is singular at this configuration: an elastic "
                         "joint moves no mass and has no rotor inertia (IA)", path="q") from None
    return np.linalg.solve(factor.T, np.linalg.solve(factor, b))


def elastic_direct_dynamics(robot: "MDHRobot", q: Any, qd: Any, tau_rigid: Any) -> np.ndarray:
    """Accelerations of all joints (n,) under the rigid joints' torques and the elastic joints' springs.

    ``qdd = A^-1 (tau - h(q, qd))`` with ``tau_r = tau_rigid`` and ``tau_e = -k q_e`` (the damping
    ``FV qd_e`` is in ``h`` like every joint's friction): the state derivative of a simulation, and the
    inverse of :func:`hybrid_dynamics` (``hybrid_dynamics(q, qd, qdd[rigid]).qdd_elastic == qdd[elastic]``).

    Parameters
    ----------
    q, qd : array_like, shape (n,)
    tau_rigid : array_like, shape (n_r,)
        Torques/forces of the rigid joints, in joint order.
    """
    _check_no_dry_friction(robot)
    q_, qd_ = _one_state(robot, q, "q"), _one_state(robot, qd, "qd")
    r, e = rigid_joints(robot), elastic_joints(robot)
    tau = np.zeros(robot.n_joints)
    tau[r] = _one_state(robot, tau_rigid, "tau_rigid", len(r))
    tau[e] = -robot.k[robot.joint_frames[e]] * q_[e]
    return direct_dynamics(robot, q_, qd_, tau)
