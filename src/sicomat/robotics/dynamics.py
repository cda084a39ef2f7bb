"""Dynamic models of an :class:`~sicomat.robotics.MDHRobot`: inverse dynamics by recursive
Newton–Euler (one state or a batch), the inertia matrix by composite links, direct dynamics and the
regressor linear in the standard parameters.

Every quantity of link j is in frame j, moments about the origin O_j (Khalil's convention); gravity
enters as the base acceleration ``vd_0 = -g``. The torque of joint j is
``(sigma_j f_j + (1 - sigma_j) n_j) . z_j + IA_j qdd_j + FV_j qd_j + FS_j sign(qd_j)``. Elastic joints
are joints like the others here (their stiffness torque ``-k q`` is applied by the hybrid model,
:mod:`sicomat.robotics.elastic`, and is the extra column of the regressor with ``stiffness=True``);
fixed frames carry their link but have no torque.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError
from . import _kernels
from ._kernels import flat_arrays
from .geometry import joint_states, local_transforms

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["inverse_dynamics", "inverse_dynamics_batch", "inertia_matrix", "inertia_matrix_batch", "direct_dynamics",
           "regressor", "regressor_batch"]


def _states(robot: "MDHRobot", q: Any, qd: Any, qdd: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = joint_states(robot, q, "q"), joint_states(robot, qd, "qd"), joint_states(robot, qdd, "qdd")
    if not arrays[0].shape == arrays[1].shape == arrays[2].shape:
        raise ModelError(f"q, qd and qdd must have the same shape, got {[a.shape for a in arrays]}", path="q")
    return arrays


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis (broadcast): numpy's ``cross`` costs ~20 us a call in axis handling,
    which dominated a one-state Newton–Euler."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _on_frames(robot: "MDHRobot", x: np.ndarray) -> np.ndarray:
    """Joint values (n_states, n) spread on the frames (n_states, NF), 0 on fixed frames."""
    out = np.zeros((x.shape[0], robot.n_frames))
    out[:, robot.joint_frames] = x
    return out


def _rt(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R^T v`` over states: rot (S, 3, 3), v (S, 3)."""
    return np.einsum("sji,sj->si", rot, v)


def _r(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("sij,sj->si", rot, v)


def _forward(robot: "MDHRobot", q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, gravity: np.ndarray):
    """Velocities and accelerations of every frame in its own frame: w, wd, vd (S, NF, 3)."""
    rot, pos = local_transforms(robot, q)
    s, nf = q.shape[0], robot.n_frames
    qd_f, qdd_f = _on_frames(robot, qd), _on_frames(robot, qdd)
    w = np.zeros((s, nf + 1, 3))       # index 0 the base, index row+1 frame row+1
    wd = np.zeros((s, nf + 1, 3))
    vd = np.zeros((s, nf + 1, 3))
    vd[:, 0] = -gravity
    ez = np.array([0.0, 0.0, 1.0])
    for row in range(nf):
        a = int(robot.ant[row])
        rr, p = rot[:, row], pos[:, row]
        wi = _rt(rr, w[:, a])
        # acceleration of O_j in frame a(j): vd_i + wd_i x p + w_i x (w_i x p)
        acc = vd[:, a] + _cross(wd[:, a], p) + _cross(w[:, a], _cross(w[:, a], p))
        vd[:, row + 1] = _rt(rr, acc)
        wd[:, row + 1] = _rt(rr, wd[:, a])
        w[:, row + 1] = wi
        qdz = qd_f[:, row, None] * ez
        if robot.sigma[row] == 0:
            w[:, row + 1] += qdz
            wd[:, row + 1] += qdd_f[:, row, None] * ez + _cross(wi, qdz)
        elif robot.sigma[row] == 1:
            vd[:, row + 1] += qdd_f[:, row, None] * ez + 2.0 * _cross(wi, qdz)
    return rot, pos, w[:, 1:], wd[:, 1:], vd[:, 1:]


_FLOAT64 = np.dtype(np.float64)


def _joint_vector(robot: "MDHRobot", x: Any, name: str) -> np.ndarray:
    """One state as a float64 contiguous (n,) array; anything else goes through :func:`joint_states` for
    its error (finiteness is checked in the kernels)."""
    if x.__class__ is np.ndarray and x.dtype is _FLOAT64 and x.shape == (robot.n_joints,) and x.strides == (8,):
        return x                              # the common case, taken in ~0.1 us (the general path ~0.5 us)
    array = np.asarray(x, dtype=np.float64)
    if array.ndim == 1 and array.shape[0] == robot.n_joints:
        return np.ascontiguousarray(array)
    states = joint_states(robot, x, name)
    if states.shape[0] != 1:
        raise ModelError(f"{name}: this function takes one state", path=name)
    return np.ascontiguousarray(states[0])


def _not_finite(robot: "MDHRobot", **arrays: np.ndarray) -> ModelError:
    for name, x in arrays.items():
        joint_states(robot, x, name)          # raises on the first non-finite one
    return ModelError("joint values must be finite", path="q")  # pragma: no cover - joint_states raised


def inverse_dynamics_batch(robot: "MDHRobot", q: Any, qd: Any, qdd: Any) -> np.ndarray:
    """Joint torques/forces of many states by recursive Newton–Euler, the loop over the states compiled.

    Parameters
    ----------
    q, qd, qdd : array_like, shape (n_states, n) (or (n,) for one state)
        Joint positions, velocities and accelerations (rad or m, per s, per s^2).

    Returns
    -------
    ndarray, shape (n_states, n)
        Torques (N m) of revolute joints, forces (N) of prismatic ones, gravity, rotor inertia ``IA``
        and friction (``FV qd + FS sign(qd)``) included.
    """
    q_, qd_, qdd_ = (np.ascontiguousarray(x) for x in _states(robot, q, qd, qdd))
    ints, geo, chi = flat_arrays(robot)
    tau = np.empty(q_.shape)
    _kernels.rnea_batch(ints, geo, chi, robot.gravity, q_, qd_, qdd_, tau)
    return tau


def inverse_dynamics(robot: "MDHRobot", q: Any, qd: Any, qdd: Any) -> np.ndarray:
    """Joint torques/forces of one state (n,); see :func:`inverse_dynamics_batch`.

    Examples
    --------
    A slide of 2 kg lifted along z0 against gravity at 1 m/s^2 needs 2 (9.81 + 1) N:

    >>> from sicomat.robotics import MDHRobot
    >>> slide = MDHRobot.from_table([{"ant": 0, "sigma": 1, "M": 2.0}])
    >>> inverse_dynamics(slide, [0.0], [0.0], [1.0]).round(6).tolist()
    [21.62]
    """
    q_, qd_, qdd_ = _joint_vector(robot, q, "q"), _joint_vector(robot, qd, "qd"), _joint_vector(robot, qdd, "qdd")
    ints, geo, chi = flat_arrays(robot)
    tau = np.empty(q_.shape[0])
    if not _kernels.rnea(ints, geo, chi, robot.gravity, q_, qd_, qdd_, tau):
        raise _not_finite(robot, q=q_, qd=qd_, qdd=qdd_)
    return tau


def inertia_matrix(robot: "MDHRobot", q: Any) -> np.ndarray:
    """The joint-space inertia matrix ``A(q)`` by composite links (n x n, symmetric; ``IA`` on the diagonal).

    The composite link of frame j (its link and every descendant) is accumulated at O_j in frame j:
    ``J+_i += R J+_j R^T - (p^ S^ + S^ p^) - M+_j p^ p^``, ``MS+_i += S + M+_j p``, ``M+_i += M+_j``
    (``S = R MS+_j``). A unit acceleration of joint j moves it rigidly; the wrench it needs, carried
    down to each ancestor joint, is column j. Compiled (:mod:`sicomat.robotics._kernels`).
    """
    q_ = _joint_vector(robot, q, "q")
    ints, geo, chi = flat_arrays(robot)
    n = q_.shape[0]
    out = np.empty((n, n))
    if not _kernels.crba(ints, geo, chi, q_, out):
        raise _not_finite(robot, q=q_)
    return out


def inertia_matrix_batch(robot: "MDHRobot", q: Any) -> np.ndarray:
    """:func:`inertia_matrix` of many states, ``q`` (n_states, n), result (n_states, n, n)."""
    q_ = np.ascontiguousarray(joint_states(robot, q, "q"))
    ints, geo, chi = flat_arrays(robot)
    n = q_.shape[1]
    out = np.empty((q_.shape[0], n, n))
    _kernels.crba_batch(ints, geo, chi, q_, out)
    return out


def direct_dynamics(robot: "MDHRobot", q: Any, qd: Any, tau: Any) -> np.ndarray:
    """Joint accelerations ``qdd = A(q)^-1 (tau - h(q, qd))`` (n,), ``h`` = inverse dynamics at ``qdd = 0``.

    Raises
    ------
    ModelError
        If the inertia matrix is singular (a joint that moves no mass and has no rotor inertia).
    """
    q_, qd_, tau_ = joint_states(robot, q, "q"), joint_states(robot, qd, "qd"), joint_states(robot, tau, "tau")
    if not q_.shape[0] == qd_.shape[0] == tau_.shape[0] == 1:
        raise ModelError("direct_dynamics takes one state", path="q")
    h = inverse_dynamics(robot, q_[0], qd_[0], np.zeros(robot.n_joints))
    a = inertia_matrix(robot, q_[0])
    try:
        factor = np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        raise ModelError("the inertia matrix is singular at this configuration: a joint moves no mass and has "
                         "no rotor inertia (IA)", path="q") from None
    y = np.linalg.solve(factor, tau_[0] - h)
    return np.linalg.solve(factor.T, y)


def _lmat(w: np.ndarray) -> np.ndarray:
    """``L(w)`` (S, 3, 6) with ``J w = L(w) [XX XY XZ YY YZ ZZ]``."""
    s = w.shape[0]
    out = np.zeros((s, 3, 6))
    out[:, 0, 0:3] = w
    out[:, 1, 1], out[:, 1, 3], out[:, 1, 4] = w[:, 0], w[:, 1], w[:, 2]
    out[:, 2, 2], out[:, 2, 4], out[:, 2, 5] = w[:, 0], w[:, 1], w[:, 2]
    return out


def _skew_batch(v: np.ndarray) -> np.ndarray:
    out = np.zeros((v.shape[0], 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -v[:, 2], v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = v[:, 2], -v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -v[:, 1], v[:, 0]
    return out


def regressor_batch(robot: "MDHRobot", q: Any, qd: Any, qdd: Any, *, stiffness: bool = False) -> np.ndarray:
    """:func:`regressor` over many states, shape (n_states, n, 13 NF), or (n_states, n, 13 NF + n_e) with
    ``stiffness=True``."""
    q_, qd_, qdd_ = _states(robot, q, qd, qdd)
    rot, pos, w, wd, vd = _forward(robot, q_, qd_, qdd_, robot.gravity)
    s, nf, n = q_.shape[0], robot.n_frames, robot.n_joints
    out = np.zeros((s, n, 13 * nf))
    for row in range(nf):
        wj, wdj, vdj = w[:, row], wd[:, row], vd[:, row]
        wsk = _skew_batch(wj)
        block = np.zeros((s, 6, 10))      # the wrench of link j at O_j per unit parameter: f rows, n rows
        block[:, :3, 6:9] = _skew_batch(wdj) + wsk @ wsk
        block[:, :3, 9] = vdj
        block[:, 3:, 0:6] = _lmat(wdj) + wsk @ _lmat(wj)
        block[:, 3:, 6:9] = -_skew_batch(vdj)
        k = row
        while True:
            joint = robot.joint_of_frame[k]
            if joint >= 0:
                out[:, joint, 13 * row:13 * row + 10] = block[:, 2] if robot.sigma[k] == 1 else block[:, 5]
            if robot.ant[k] == 0:
                break
            fr = rot[:, k] @ block[:, :3]
            block = np.concatenate([fr, rot[:, k] @ block[:, 3:] + _skew_batch(pos[:, k]) @ fr], axis=1)
            k = int(robot.ant[k]) - 1
        joint = robot.joint_of_frame[row]
        if joint >= 0:
            col = 13 * row
            out[:, joint, col + 10] = qdd_[:, joint]
            out[:, joint, col + 11] = qd_[:, joint]
            out[:, joint, col + 12] = np.sign(qd_[:, joint])
    if stiffness:
        out = np.concatenate([out, _stiffness_columns(robot, q_)], axis=2)
    return out


def _stiffness_columns(robot: "MDHRobot", q: np.ndarray) -> np.ndarray:
    """The column ``q_j e_j`` of each elastic joint's stiffness ``k_j`` (notes §2.6), (n_states, n, n_e)."""
    elastic = np.flatnonzero(robot.eta[robot.joint_frames] == 1)
    out = np.zeros((q.shape[0], robot.n_joints, len(elastic)))
    out[:, elastic, np.arange(len(elastic))] = q[:, elastic]
    return out


def regressor(robot: "MDHRobot", q: Any, qd: Any, qdd: Any, *, stiffness: bool = False) -> np.ndarray:
    """The regressor ``Phi`` (n x 13 NF) with ``inverse_dynamics(q, qd, qdd) = Phi @ standard_parameters()``.

    Column ``13 (j - 1) + c`` is the torque per unit of the c-th parameter ``XX XY XZ YY YZ ZZ MX MY
    MZ M IA FV FS`` of frame j's link.

    With ``stiffness=True`` the stiffness ``k`` of each elastic joint (``eta = 1``, joint order) adds a
    last column ``q_e e_e`` (n x (13 NF + n_e)): ``Phi @ standard_parameters(stiffness=True)`` is
    ``inverse_dynamics + k q`` on the elastic rows, the left side of the elastic joint's equation
    ``A qdd + h + k q = 0`` (0 at the accelerations of :func:`~sicomat.robotics.elastic.hybrid_dynamics`),
    and the rigid joints' torques on the others (names ``K<frame>``, :meth:`MDHRobot.parameter_names`).
    """
    phi = regressor_batch(robot, q, qd, qdd, stiffness=stiffness)
    if phi.shape[0] != 1:
        raise ModelError("regressor takes one state; use regressor_batch", path="q")
    return phi[0]
