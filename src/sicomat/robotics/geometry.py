"""Geometric and kinematic models of an :class:`~sicomat.robotics.MDHRobot`: the frame transforms
(MDH, SYMORO's order) and the Jacobian of a frame."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["local_transforms", "transforms", "transform", "frame_positions", "jacobian", "joint_states"]


def joint_states(robot: "MDHRobot", q: Any, name: str = "q") -> np.ndarray:
    """``q`` as an array of shape (n_states, n): one state (n,) or many (n_states, n)."""
    array = np.asarray(q, dtype=float)
    if array.ndim == 1:
        array = array[None, :]
    if array.ndim != 2 or array.shape[1] != robot.n_joints:
        raise ModelError(f"{name} must hold {robot.n_joints} joint values per state (frame order, fixed frames "
                         f"excluded), got shape {np.shape(q)}", path=name)
    if not np.all(np.isfinite(array)):
        raise ModelError(f"{name} must be finite", path=name)
    return array


def _constants(robot: "MDHRobot") -> tuple[np.ndarray, np.ndarray]:
    """``C = Rz(gamma) Rx(alpha)`` (NF, 3, 3) and ``p0 = [0, 0, b] + C [d, 0, 0]`` (NF, 3)."""
    cg, sg = np.cos(robot.gamma), np.sin(robot.gamma)
    ca, sa = np.cos(robot.alpha), np.sin(robot.alpha)
    zero, one = np.zeros_like(cg), np.ones_like(cg)
    rz = np.stack([np.stack([cg, -sg, zero], -1), np.stack([sg, cg, zero], -1), np.stack([zero, zero, one], -1)], -2)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, ca, -sa], -1), np.stack([zero, sa, ca], -1)], -2)
    c = rz @ rx
    p0 = c[:, :, 0] * robot.d[:, None]
    p0[:, 2] += robot.b
    return c, p0


def local_transforms(robot: "MDHRobot", q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each frame in its antecedent, ``a(j)T_j = Rz(gamma) Tz(b) Rx(alpha) Tx(d) Rz(theta) Tz(r)``.

    Parameters
    ----------
    q : ndarray, shape (n_states, n)
        Joint variables (added to ``theta`` for a revolute frame, to ``r`` for a prismatic one).

    Returns
    -------
    R : ndarray, shape (n_states, NF, 3, 3)
        Rotation ``a(j)R_j``.
    P : ndarray, shape (n_states, NF, 3)
        Origin of frame j in frame a(j).
    """
    c, p0 = _constants(robot)
    q_frame = np.zeros((q.shape[0], robot.n_frames))
    q_frame[:, robot.joint_frames] = q
    revolute = (robot.sigma == 0).astype(float)
    prismatic = (robot.sigma == 1).astype(float)
    th = robot.theta + revolute * q_frame
    rr = robot.r + prismatic * q_frame
    ct, st = np.cos(th), np.sin(th)
    # R = C Rz(theta): the first two columns mix, the third is C's (Rz keeps z)
    rot = np.empty((q.shape[0], robot.n_frames, 3, 3))
    rot[..., 0] = c[None, :, :, 0] * ct[..., None] + c[None, :, :, 1] * st[..., None]
    rot[..., 1] = -c[None, :, :, 0] * st[..., None] + c[None, :, :, 1] * ct[..., None]
    rot[..., 2] = c[None, :, :, 2]
    pos = p0[None] + c[None, :, :, 2] * rr[..., None]
    return rot, pos


def _frame_number(robot: "MDHRobot", j: object, name: str) -> int:
    if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= int(j) <= robot.n_frames:
        raise ModelError(f"{name} must be a frame number 0..{robot.n_frames} (0 = base)", path=name, value=j)
    return int(j)


def _global(robot: "MDHRobot", q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``0R_j`` (n_states, NF+1, 3, 3) and ``0P_j`` (n_states, NF+1, 3), index 0 the base."""
    rot, pos = local_transforms(robot, q)
    s = q.shape[0]
    g_rot = np.empty((s, robot.n_frames + 1, 3, 3))
    g_pos = np.empty((s, robot.n_frames + 1, 3))
    g_rot[:, 0] = np.eye(3)
    g_pos[:, 0] = 0.0
    for row in range(robot.n_frames):
        a = robot.ant[row]
        g_rot[:, row + 1] = g_rot[:, a] @ rot[:, row]
        g_pos[:, row + 1] = g_pos[:, a] + np.einsum("sij,sj->si", g_rot[:, a], pos[:, row])
    return g_rot, g_pos


def transforms(robot: "MDHRobot", q: Any) -> np.ndarray:
    """Homogeneous transforms ``0T_j`` of every frame in the base, j = 0..NF.

    Returns
    -------
    ndarray, shape (NF+1, 4, 4)
        Entry 0 is the identity (the base), entry j frame j.
    """
    states = joint_states(robot, q)
    if states.shape[0] != 1:
        raise ModelError("transforms takes one state", path="q")
    g_rot, g_pos = _global(robot, states)
    out = np.zeros((robot.n_frames + 1, 4, 4))
    out[:, :3, :3] = g_rot[0]
    out[:, :3, 3] = g_pos[0]
    out[:, 3, 3] = 1.0
    return out


def frame_positions(robot: "MDHRobot", q: Any, j: int) -> np.ndarray:
    """The origin of frame j in the base frame at many states, ``q`` (n_states, n): shape (n_states, 3)."""
    j = _frame_number(robot, j, "j")
    states = joint_states(robot, q)
    return _global(robot, states)[1][:, j]


def transform(robot: "MDHRobot", q: Any, j: int, i: int = 0) -> np.ndarray:
    """``iT_j``: frame j in frame i (4x4), ``(0T_i)^-1 0T_j``.

    Examples
    --------
    >>> from sicomat.robotics import MDHRobot
    >>> slide = MDHRobot.from_table([{"ant": 0, "sigma": 1}])
    >>> transform(slide, [0.25], 1)[:3, 3].tolist()
    [0.0, 0.0, 0.25]
    """
    j = _frame_number(robot, j, "j")
    i = _frame_number(robot, i, "i")
    all_t = transforms(robot, q)
    t_i, t_j = all_t[i], all_t[j]
    out = np.eye(4)
    out[:3, :3] = t_i[:3, :3].T @ t_j[:3, :3]
    out[:3, 3] = t_i[:3, :3].T @ (t_j[:3, 3] - t_i[:3, 3])
    return out


def chain(robot: "MDHRobot", j: int) -> list[int]:
    """Rows of the frames from frame j (row j-1) down to the base, frame j first."""
    rows = []
    row = j - 1
    while row >= 0:
        rows.append(row)
        row = int(robot.ant[row]) - 1
    return rows


def jacobian(robot: "MDHRobot", q: Any, j: int) -> np.ndarray:
    """Jacobian of frame j: ``[v_Oj; omega_j] = J q̇``, both in the base frame.

    Rows 0-2 are the linear velocity of frame j's origin, rows 3-5 the angular velocity of frame j,
    both expressed in frame 0. Column k belongs to joint variable k; it is zero for a joint that is
    not on the chain from the base to frame j. A revolute column is ``[z_k x (P_j - P_k); z_k]``, a
    prismatic one ``[z_k; 0]``.

    Returns
    -------
    ndarray, shape (6, n)
    """
    j = _frame_number(robot, j, "j")
    states = joint_states(robot, q)
    if states.shape[0] != 1:
        raise ModelError("jacobian takes one state", path="q")
    g_rot, g_pos = _global(robot, states)
    out = np.zeros((6, robot.n_joints))
    for row in chain(robot, j):
        k = robot.joint_of_frame[row]
        if k < 0:
            continue
        z = g_rot[0, row + 1][:, 2]
        if robot.sigma[row] == 0:
            out[:3, k] = np.cross(z, g_pos[0, j] - g_pos[0, row + 1])
            out[3:, k] = z
        else:
            out[:3, k] = z
    return out
