"""The robot's side of a path simulated on the coupled model of a robot machine (``sicomat circle``,
``simulation.paths``): the tool point read as path coordinates (:class:`ToolPoint`) and what the large-motion
engine needs of the robot (:class:`RigidBodyDynamics`). ``docs/robotics.md``, "Large motions and the circle
test of a robot machine"."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import ModelError
from .lowering import configuration, linearize, robot_model
from .table import MDHRobot

if TYPE_CHECKING:
    from ..description.robot import RobotSpec

__all__ = ["RigidBodyDynamics", "rigid_body_dynamics", "ToolPoint", "tool_point"]


@dataclass(frozen=True, eq=False)
class RigidBodyDynamics:
    """What a large-motion simulation needs of a robot (:mod:`sicomat.simulation.nonlinear`): its numeric
    model, the configuration ``q0`` the linear model's coordinates are measured from (``δq = q - q0``, every
    joint in frame order) and ``mass0 = A(q0)``, the linear model's inertia matrix."""

    robot: MDHRobot
    q0: np.ndarray
    mass0: np.ndarray


def rigid_body_dynamics(spec: "RobotSpec", q: "Sequence[float] | np.ndarray | None" = None) -> RigidBodyDynamics:
    """The robot of ``spec`` for a large-motion simulation about ``q`` (default: its configuration), to pair
    with the coupled linear model :func:`robot_mechanics` gives at the same ``q`` with every joint free."""
    robot = robot_model(spec)
    _refuse_loops(robot, spec)
    q0 = configuration(spec, q)
    return RigidBodyDynamics(robot=robot, q0=q0, mass0=linearize(robot, q0, gravity=False).mass)


def _refuse_loops(robot: MDHRobot, spec: "RobotSpec") -> None:
    """Path following on the coupled model and large motions work in every joint's coordinates: a machine
    with closed loops (independent coordinates, no direct dynamics yet) is refused."""
    if robot.n_loops:
        raise ModelError("a path over the coupled or nonlinear model of a machine with closed loops is not "
                         "simulated yet (its linear model is in its independent joints and its direct dynamics "
                         "are not built); simulate its axes decoupled", path="robot.links", value=spec.links)


@dataclass(frozen=True, eq=False)
class ToolPoint:
    """The tool point of a robot machine read as path coordinates of some of its axes.

    A path moves axes ``axes`` (motorised joints). On the rigid, nominal machine, moving axis ``A`` by
    ``δ`` moves the tool point by ``δ e_A``, ``e_A`` the column of the tool point's Jacobian for joint A at
    ``q0``. The tool point's **path coordinates** at any ``q`` are the axis displacements that would
    put the nominal machine's tool point where it is, in the least-squares sense:
    ``c = E⁺ (p(q) - p(q0))``, ``E = [e_A ...]`` (3 x k), ``E⁺`` its pseudo-inverse (an offset out of the
    axes' span, e.g. along Z for an X-Y path, is not a path coordinate). Elastic deflections, the
    carriage's yaw with the tool offset from it (an Abbe error), a link's bending all move ``p`` and so
    the path coordinates: the tool point is what the contour error is measured on.

    Attributes
    ----------
    robot, q0, frame : the numeric robot, the configuration (every joint) and the tool frame's number.
    axes : the path's axes (joint names), in path order; ``columns`` their joint indices.
    to_path : (k, 3) ``E⁺``.
    origin : (3,) ``p(q0)``.
    """

    robot: MDHRobot
    q0: np.ndarray
    frame: int
    axes: tuple[str, ...]
    columns: tuple[int, ...]
    to_path: np.ndarray
    origin: np.ndarray

    def linear(self) -> np.ndarray:
        """(k, n): the path coordinates' linearisation at ``q0``, ``E⁺ J_p(q0)`` (the tool vectors of the
        coupled linear model, one row per path axis)."""
        from .geometry import jacobian

        return self.to_path @ jacobian(self.robot, self.q0, self.frame)[:3]

    def coordinates(self, dq: np.ndarray) -> np.ndarray:
        """(n_states, k): the path coordinates (relative to ``q0``) at the states ``q0 + dq``, dq (n_states, n)."""
        from .geometry import frame_positions

        return (frame_positions(self.robot, self.q0 + np.atleast_2d(dq), self.frame) - self.origin) @ self.to_path.T


def tool_point(spec: "RobotSpec", axes: Sequence[str], q: "Sequence[float] | np.ndarray | None" = None) -> ToolPoint:
    """The :class:`ToolPoint` of ``spec`` for a path moving ``axes`` (motorised joints), about ``q``
    (default: the configuration); the tool frame is ``spec.tool_frame``.

    Raises
    ------
    ModelError
        An axis that is not a motorised joint; axes that do not move the tool point independently (their
        Jacobian columns are dependent: a singular configuration, or an axis off the tool's chain).
    """
    from .geometry import frame_positions, jacobian

    robot = robot_model(spec)
    _refuse_loops(robot, spec)
    q0 = configuration(spec, q)
    names = spec.joint_names
    for axis in axes:
        if axis not in spec.motor_names:
            raise ModelError(f"{axis!r} is not a motorised joint of the robot ({', '.join(spec.motor_names)})",
                             path="robot.frames", value=axis)
    columns = tuple(names.index(axis) for axis in axes)
    frame = spec.tool_frame
    E = jacobian(robot, q0, frame)[:3, list(columns)]
    s = np.linalg.svd(E, compute_uv=False)
    # independent columns: the smallest singular value above 1e-9 of the largest (rounding of J ~1e-16)
    if s.size == 0 or s[-1] <= 1e-9 * max(s[0], 1e-300):
        raise ModelError(f"the axes {', '.join(axes)} do not move the tool point (frame {frame}) independently at "
                         f"this configuration: a path over them has no tool-point coordinates",
                         path="robot.configuration", value=q0.tolist())
    return ToolPoint(robot=robot, q0=q0, frame=frame, axes=tuple(axes), columns=columns, to_path=np.linalg.pinv(E),
                     origin=frame_positions(robot, q0, frame)[0])
