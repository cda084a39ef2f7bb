"""Closed loops described the SYMORO way (notes ``shared/reference/robotics-formalism.md`` §1.3): the
closure equations, their solution for the passive joints, and the closed-loop dynamics.

A robot with ``links = NL`` (:meth:`MDHRobot.from_table`) is a tree of NL links plus B loops, each cut at
one joint: cut frame k (NL < k <= NL + B) is that joint, on link ``ant(k)``, and its closing frame
k + B is fixed on the other link. The loop is closed when ``0T_k(q) = 0T_{k+B}(q)``. The joint variables
``q`` are those of the tree and of the cut joints. The **independent** ones are the motorised joints
(``mu = 1``, the **active** ones: a motor drives them) and the elastic joints (``eta = 1``: a spring's
deflection, a state of its own); every other joint is **passive**, found from the independent ones by
the closure. Without elastic joints the independent joints are the active ones.

Dynamics (notes §1.3): the tree (the cut and closing frames carry no link) has torques ``Gamma_tr``
(:func:`~sicomat.robotics.dynamics.inverse_dynamics` at consistent ``q, qd, qdd``) and inertia matrix
``A_tr``; with ``G = dq/dq_i`` (identity rows for the independent joints, ``dq_p/dq_i`` for the passive
ones) the generalised forces on the independent coordinates are ``Gamma_i = G^T Gamma_tr`` and the closed
loop's inertia matrix is ``G^T A_tr G``: the principle of virtual work, ``Gamma_i . dq_i = Gamma_tr . dq``
for every consistent ``dq = G dq_i`` (the closure's reaction forces do no work). On a motorised row
``Gamma_i`` is the motor's torque; on an elastic row it is what the spring must supply,
``Gamma_i,e = -k q_e`` on a motion of the machine (the elastic joint's equation, as in the tree's hybrid
model, :mod:`sicomat.robotics.elastic`).

Closure error of loop l: ``[P_k - P_{k+B}; rotvec(R_k R_{k+B}^T)]`` in the base frame (m, rad). Its
derivative along a motion is ``(J_k - J_{k+B}) qd`` (the frames' Jacobians; exact for the position rows,
and for the rotation rows where the loop is closed), the loop Jacobian used by Newton and by ``G``.
A planar loop gives only 3 independent rows of 6: the passive joints are found by least squares, and
are determined when the passive columns of the loop Jacobian have full rank (else: a singular
configuration, ``ModelError``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import AnalysisError, ModelError
from .dynamics import _forward, inertia_matrix, inverse_dynamics
from .geometry import _global, jacobian, joint_states

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["loop_frames", "active_joints", "independent_joints", "passive_joints", "closure_error", "loop_jacobian",
           "solve_closure", "constraint_jacobian", "independent_jacobian", "loop_states",
           "closed_loop_inverse_dynamics", "closed_loop_inertia_matrix"]

# A passive column of the loop Jacobian whose singular value is below this fraction of the largest is
# a lost degree of freedom: the singular values of a regular configuration are of the order of the
# lever arms (0.1..1 of the machine's size), rounding leaves ~1e-16 of it on a truly dependent column.
_RANK_RTOL = 1e-9
# The closure a state must meet to be used by the dynamics, relative to the machine's size: Newton
# (solve_closure) reaches ~1e-15; 1e-8 accepts states rounded or integrated with care.
_CLOSED_RTOL = 1e-8


def loop_frames(robot: "MDHRobot") -> list[tuple[int, int]]:
    """``(k, k + B)``, the cut frame and the closing frame of each loop (frame numbers)."""
    nl, b = robot.n_links, robot.n_loops
    return [(k, k + b) for k in range(nl + 1, nl + b + 1)]


def active_joints(robot: "MDHRobot") -> np.ndarray:
    """Indices in ``q`` of the active joints (``mu = 1``)."""
    return np.flatnonzero(robot.mu[robot.joint_frames] == 1)


def independent_joints(robot: "MDHRobot") -> np.ndarray:
    """Indices in ``q`` of the independent joints: the motorised (``mu = 1``) and the elastic (``eta = 1``)
    ones, in joint order; the active joints when there is no elastic joint."""
    rows = robot.joint_frames
    return np.flatnonzero((robot.mu[rows] == 1) | (robot.eta[rows] == 1))


def passive_joints(robot: "MDHRobot") -> np.ndarray:
    """Indices in ``q`` of the passive joints (``mu = eta = 0``: tree joints without a motor or a spring, and
    the cut joints), found by the closure."""
    rows = robot.joint_frames
    return np.flatnonzero((robot.mu[rows] == 0) & (robot.eta[rows] == 0))


def _size(robot: "MDHRobot") -> float:
    """The machine's length scale (m): 1 or the sum of its constant lengths."""
    return max(1.0, float(np.sum(np.abs(robot.b) + np.abs(robot.d) + np.abs(robot.r))))


def _one(robot: "MDHRobot", x: Any, name: str) -> np.ndarray:
    states = joint_states(robot, x, name)
    if states.shape[0] != 1:
        raise ModelError(f"{name}: this function takes one state", path=name)
    return states[0]


def _vector(x: Any, size: int, name: str) -> np.ndarray:
    array = np.asarray(x, dtype=float)
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise ModelError(f"{name} must hold {size} finite values (one per independent joint: motorised or "
                         f"elastic, joint order), got shape {np.shape(x)}", path=name)
    return array


def closure_error(robot: "MDHRobot", q: Any) -> np.ndarray:
    """The closure error of each loop, shape (B, 6): ``P_k - P_{k+B}`` (m) then the rotation vector of
    ``R_k R_{k+B}^T`` (rad), in the base frame. Zero when every loop is closed."""
    t = robot.transforms(_one(robot, q, "q"))
    out = np.zeros((robot.n_loops, 6))
    for loop, (k, c) in enumerate(loop_frames(robot)):
        out[loop, :3] = t[k, :3, 3] - t[c, :3, 3]
        out[loop, 3:] = Rotation.from_matrix(t[k, :3, :3] @ t[c, :3, :3].T).as_rotvec()
    return out


def loop_jacobian(robot: "MDHRobot", q: Any) -> np.ndarray:
    """``d(closure)/dq`` (6B x n): ``J_k - J_{k+B}`` of each loop (linear rows, then angular)."""
    q_ = _one(robot, q, "q")
    return np.vstack([jacobian(robot, q_, k) - jacobian(robot, q_, c) for k, c in loop_frames(robot)]
                     or [np.zeros((0, robot.n_joints))])


def _passive_solve(j_p: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The least-squares solution of ``J_p x = rhs`` when ``J_p`` has full column rank, else ModelError."""
    n_p = j_p.shape[1]
    if n_p == 0:
        return np.zeros((0,) + rhs.shape[1:])
    u, s, vt = np.linalg.svd(j_p, full_matrices=False)
    if len(s) < n_p or s[-1] <= _RANK_RTOL * s[0]:
        raise ModelError(f"the loops do not determine the {n_p} passive joints at this configuration (a singular "
                         "configuration, or passive joints outside every loop)", path="q")
    return vt.T @ ((u.T @ rhs) / (s if rhs.ndim == 1 else s[:, None]))


def solve_closure(robot: "MDHRobot", q_active: Any, q_guess: Any, *, tol: float = 1e-12,
                  max_iterations: int = 50) -> np.ndarray:
    """All joint variables (n,) closing the loops, the active ones given: Newton on the passive joints.

    Parameters
    ----------
    q_active : array_like, shape (n_i,)
        The independent joints' positions (:func:`independent_joints`: motorised and elastic, joint order;
        the active joints' when there is no elastic joint).
    q_guess : array_like, shape (n,)
        A start for every joint; its active entries are replaced. Newton finds the closure nearest to it
        (the assembly mode, e.g. which way a four-bar's elbow points, is chosen by the guess).
    tol : float
        The closure error reached, relative to the machine's size (the sum of its constant lengths, m;
        rad for the rotation rows).

    Raises
    ------
    AnalysisError
        If the loops are not closed after ``max_iterations`` Newton steps (a guess too far, or no closure).
    ModelError
        At a singular configuration (see :func:`constraint_jacobian`).
    """
    a, p = independent_joints(robot), passive_joints(robot)
    q = _one(robot, q_guess, "q_guess").copy()
    q[a] = _vector(q_active, len(a), "q_active")
    target = tol * _size(robot)
    for _ in range(max_iterations):
        error = closure_error(robot, q).reshape(-1)
        if np.max(np.abs(error), initial=0.0) <= target:
            return q
        q[p] -= _passive_solve(loop_jacobian(robot, q)[:, p], error)
    raise AnalysisError(f"the loops did not close in {max_iterations} Newton steps (closure error "
                        f"{np.max(np.abs(closure_error(robot, q))):.3g}): start from a closer q_guess")


def _check_closed(robot: "MDHRobot", q: np.ndarray) -> None:
    error = np.max(np.abs(closure_error(robot, q)), initial=0.0)
    if error > _CLOSED_RTOL * _size(robot):
        raise ModelError(f"q does not close the loops (closure error {error:.3g}): use solve_closure", path="q")


def constraint_jacobian(robot: "MDHRobot", q: Any) -> np.ndarray:
    """``dq_p/dq_i`` (n_p x n_i) at a closed configuration: ``J_p dq_p + J_i dq_i = 0`` solved for the
    passive joints (least squares, exact when the loops are closed); ``dq_p/dq_a`` without elastic joints."""
    q_ = _one(robot, q, "q")
    _check_closed(robot, q_)
    j = loop_jacobian(robot, q_)
    return _passive_solve(j[:, passive_joints(robot)], -j[:, independent_joints(robot)])


def independent_jacobian(robot: "MDHRobot", q: Any) -> np.ndarray:
    """``G = dq/dq_i`` (n x n_i) at a closed configuration: identity rows for the independent joints,
    :func:`constraint_jacobian` for the passive ones. A joint's velocity is ``G[j] @ qd_i``; a sum of joint
    variables (a sensor) moves by the sum of their rows."""
    a, p = independent_joints(robot), passive_joints(robot)
    g = np.zeros((robot.n_joints, len(a)))
    g[a, np.arange(len(a))] = 1.0
    g[p] = constraint_jacobian(robot, q)
    return g





def loop_states(robot: "MDHRobot", q: Any, qd_active: Any, qdd_active: Any) -> tuple[np.ndarray, np.ndarray]:
    """The speeds and accelerations of all joints (n,) consistent with the loops at a closed ``q``, the
    independent joints' given (``qd_active``, ``qdd_active``: (n_i,), joint order).

    ``qd = G qd_i``; ``qdd_p`` from the closure's second derivative ``J qdd + a_rel(q, qd) = 0``, where
    ``a_rel`` is the relative acceleration of the cut and closing frames at ``qdd = 0`` (origins' linear
    and frames' angular accelerations, Newton–Euler's forward pass without gravity)."""
    q_ = _one(robot, q, "q")
    a, p = independent_joints(robot), passive_joints(robot)
    g = independent_jacobian(robot, q_)
    qd = g @ _vector(qd_active, len(a), "qd_active")
    _, _, _, wd, vd = _forward(robot, q_[None], qd[None], np.zeros((1, robot.n_joints)), np.zeros(3))
    rot = _global(robot, q_[None])[0][0]
    bias = np.concatenate([np.concatenate([rot[k] @ vd[0, k - 1] - rot[c] @ vd[0, c - 1],
                                           rot[k] @ wd[0, k - 1] - rot[c] @ wd[0, c - 1]])
                           for k, c in loop_frames(robot)] or [np.zeros(0)])
    qdd = np.zeros(robot.n_joints)
    qdd[a] = _vector(qdd_active, len(a), "qdd_active")
    j = loop_jacobian(robot, q_)
    qdd[p] = _passive_solve(j[:, p], -j[:, a] @ qdd[a] - bias)
    return qd, qdd


def closed_loop_inverse_dynamics(robot: "MDHRobot", q: Any, qd: Any, qdd: Any) -> np.ndarray:
    """The generalised forces on the independent joints (n_i,) ``Gamma_i = Gamma_tr,i + (dq_p/dq_i)^T
    Gamma_tr,p`` at a consistent state of all joints (``q`` closed, ``qd``, ``qdd`` from :func:`loop_states`):
    the motors' torques on the motorised rows; on an elastic row the force the spring must supply (the
    machine moves so when it equals ``-k q_e``). Without elastic joints: the active joints' torques."""
    q_ = _one(robot, q, "q")
    g = independent_jacobian(robot, q_)
    return g.T @ inverse_dynamics(robot, q_, qd, qdd)


def closed_loop_inertia_matrix(robot: "MDHRobot", q: Any) -> np.ndarray:
    """The closed loop's inertia matrix ``G^T A_tr G`` (n_i x n_i) in the independent joints, at a closed ``q``."""
    q_ = _one(robot, q, "q")
    g = independent_jacobian(robot, q_)
    return g.T @ inertia_matrix(robot, q_) @ g
