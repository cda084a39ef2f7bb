"""A robot machine lowered into the :class:`~sicomat.mechanics.Mechanics` every analysis consumes: the
MDH model linearised about a configuration (a full, configuration-dependent M), and the one function that
gives any machine axis its mechanics (:func:`axis_mechanics`).

Linearisation about ``q0`` at rest (``q̇ = 0``): ``A(q0) δq̈ + D δq̇ + (K + ∂g/∂q) δq = B u`` with ``A`` the
inertia matrix (rotor inertias included), ``D`` the joints' viscous coefficients ``FV`` (on an elastic
joint the transmission's damping, on a motorised one the guides' or bearings' friction), ``K`` the elastic
joints' stiffnesses and ``∂g/∂q`` the gravity stiffness (the Hessian of the potential energy). The
constant load ``g(q0) + K q0`` is the preload the motors hold; it does not enter the linear model.
Coriolis and centrifugal terms vanish at rest. Coulomb friction ``FS`` of a joint becomes a friction
link on that joint (stick–slip in simulation).

A robot with closed loops is linearised in its independent coordinates ``q_i`` (the motorised and the
elastic joints, :func:`~sicomat.robotics.loops.independent_joints`) about a closed configuration (the
passive joints solved by :func:`~sicomat.robotics.loops.solve_closure`): with ``G = dq/dq_i``,
``M = Gᵀ A G``, ``D = Gᵀ diag(FV) G`` (every joint's viscous friction, passive pins included), ``K`` the
elastic joints' ``k`` plus the Hessian of the reduced potential ``∂(Gᵀ g)/∂q_i``. A sensor (a sum of joint
variables) reads the sum of their rows of ``G``; a passive joint's Coulomb friction acts on the stretch
``G[j] · q_i``, its sliding. A tree is the case ``G = I`` over every joint. Decisions: ``docs/robotics.md``,
"Into the rest of SICOMAT" and "Closed loops".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..description.robot_table import PRISMATIC
from ..errors import AnalysisError, ModelError
from ..mechanics.lumped import Dof, Link, Load, Measurement, Mechanics
from .loops import closure_error, independent_jacobian, independent_joints, loop_jacobian, passive_joints, solve_closure
from .table import MDHRobot

if TYPE_CHECKING:
    from ..description.machine import Machine
    from ..description.robot import RobotSpec

__all__ = ["Linearization", "robot_model",
           "linearize", "gravity_stiffness", "robot_mechanics", "axis_free_joints", "axis_mechanics", "configuration",
           "closed_configuration"]

# Gravity stiffness by central differences with one Richardson step: truncation O(h^4) of the torque's
# fifth derivative (h = 1e-3 rad or m on a machine of metres: ~1e-12 of the torque scale) and rounding
# ~eps |g| / h = 1e-13 of it; both far below the 1e-9 the tests ask of the whole linear model.
_GRAVITY_STEP = 1e-3
# The closure the lowering asks of solve_closure, relative to the machine's size: Newton converges
# quadratically, so one step below this reaches rounding (~1e-16 of the size); 1e-13 stays ~1e3 above the
# rounding floor of the closure error itself (a chain of a dozen transforms) and never stalls there.
_CLOSURE_TOL = 1e-13
# An entry of G below this fraction of G's largest is a structural zero seen through rounding (the SVD
# solve of the passive joints leaves ~1e-16 cond there): a joint the free coordinates do not move gets no
# friction link, a sensor that reads nothing is dropped. A real lever ratio of 1e-12 does not occur.
_G_ZERO = 1e-12


@dataclass(frozen=True, eq=False)
class Linearization:
    """The matrices of a robot linearised at ``q``, SI units, in its coordinates: every joint of a tree
    (joint order), the independent joints of a robot with closed loops.

    Attributes
    ----------
    q : ndarray, shape (n,)
        Every joint's value (closed, for a robot with loops).
    mass, damping, stiffness, gravity_stiffness : ndarray, shape (n_c, n_c)
        In the coordinates; ``stiffness`` includes ``gravity_stiffness``.
    coordinates : ndarray of int, shape (n_c,)
        Indices in ``q`` of the coordinates: ``arange(n)`` for a tree, the independent joints otherwise.
    jacobian : ndarray, shape (n, n_c)
        ``G = dq/dq_c``: the identity for a tree, :func:`~sicomat.robotics.loops.independent_jacobian`.
    """

    q: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    gravity_stiffness: np.ndarray
    coordinates: np.ndarray
    jacobian: np.ndarray


def robot_model(spec: "RobotSpec") -> MDHRobot:
    """The numeric robot of a model file's ``[robot]`` section (validated there already)."""
    return MDHRobot.from_table([frame.table_row() for frame in spec.frames], gravity=spec.gravity, links=spec.links)


def configuration(spec: "RobotSpec", q: "Sequence[float] | np.ndarray | None" = None) -> np.ndarray:
    """The joint values to linearise about: ``q`` when given (checked), else the section's
    ``configuration``, else zeros."""
    n = len(spec.joint_names)
    if q is None:
        return np.array(spec.configuration if spec.configuration is not None else np.zeros(n), dtype=float)
    values = np.asarray(q, dtype=float)
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise ModelError(f"expected {n} finite joint values (every joint in frame order: "
                         f"{', '.join(spec.joint_names)})", path="robot.configuration", value=list(np.ravel(q)))
    return values


def closed_configuration(spec: "RobotSpec", q: "Sequence[float] | np.ndarray | None" = None,
                         robot: MDHRobot | None = None) -> np.ndarray:
    """:func:`configuration`, its loops closed: the independent joints (motorised, elastic) are kept, the
    passive ones are Newton's start (:func:`~sicomat.robotics.loops.solve_closure`). A tree's is returned as is.

    Raises
    ------
    ModelError
        At ``robot.configuration``: the loops cannot be closed from there (no closure the independent
        joints allow near the passive values given, or a singular configuration).
    """
    q0 = configuration(spec, q)
    robot = robot_model(spec) if robot is None else robot
    if not robot.n_loops:
        return q0
    names = spec.joint_names
    try:
        return solve_closure(robot, q0[independent_joints(robot)], q0, tol=_CLOSURE_TOL)
    except (AnalysisError, ModelError) as exc:
        reason = ("Newton on the passive joints did not converge" if isinstance(exc, AnalysisError) else
                  "the loops do not determine the passive joints there (a singular configuration)")
        raise ModelError(f"the closed loops cannot be closed at this configuration: {reason}. The independent "
                         f"joints ({', '.join(names[j] for j in independent_joints(robot))}) are kept, the passive "
                         f"ones ({', '.join(names[j] for j in passive_joints(robot))}) are only the start: give "
                         "independent values the loops can reach and passive values near that assembly",
                         path="robot.configuration", value=q0.tolist()) from None


def _polished_closure(robot: MDHRobot, q_independent: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """``solve_closure`` and one more Newton step: from ``_CLOSURE_TOL`` to rounding (quadratic convergence),
    so that differences over ``_GRAVITY_STEP`` see the torques' change, not the closure's tolerance."""
    q = solve_closure(robot, q_independent, guess, tol=_CLOSURE_TOL)
    p = passive_joints(robot)
    q[p] -= np.linalg.lstsq(loop_jacobian(robot, q)[:, p], closure_error(robot, q).reshape(-1), rcond=None)[0]
    return q


def gravity_stiffness(robot: MDHRobot, q: "Sequence[float] | np.ndarray") -> np.ndarray:
    """``∂g/∂q`` at ``q``: the derivative of the gravity torques ``g(q) = inverse_dynamics(q, 0, 0)``
    (Coulomb friction is 0 at rest), symmetric (a Hessian); zeros without gravity.

    A robot with closed loops: in its independent coordinates (n_i x n_i), the Hessian of the reduced
    potential ``∂(Gᵀ g)/∂q_i``, each displaced configuration closed again by
    :func:`~sicomat.robotics.loops.solve_closure` from ``q`` (which must be closed).
    """
    q0 = np.asarray(q, dtype=float)
    closed = bool(robot.n_loops)
    coords = independent_joints(robot) if closed else np.arange(robot.n_joints)
    n = len(coords)
    if not np.any(robot.gravity):
        return np.zeros((n, n))
    rest = np.zeros(robot.n_joints)

    def reduced(qi: np.ndarray) -> np.ndarray:
        qc = _polished_closure(robot, qi, q0)
        return independent_jacobian(robot, qc).T @ robot.inverse_dynamics(qc, rest, rest)

    def derivative(h: float) -> np.ndarray:
        if closed:
            plus = [reduced(q0[coords] + h * e) for e in np.eye(n)]
            minus = [reduced(q0[coords] - h * e) for e in np.eye(n)]
            return ((np.array(plus) - np.array(minus)) / (2.0 * h)).T
        states = np.vstack([q0 + h * e for e in np.eye(n)] + [q0 - h * e for e in np.eye(n)])
        tau = robot.inverse_dynamics_batch(states, np.zeros_like(states), np.zeros_like(states))
        return ((tau[:n] - tau[n:]) / (2.0 * h)).T        # column i: ∂g/∂q_i

    h = _GRAVITY_STEP
    jac = (4.0 * derivative(h / 2) - derivative(h)) / 3.0
    return 0.5 * (jac + jac.T)


def linearize(robot: MDHRobot, q: "Sequence[float] | np.ndarray", *, gravity: bool = True) -> Linearization:
    """M, D, K of ``robot`` at rest at ``q``; see the module's docstring. ``gravity=False``: without the
    gravity stiffness (gravity compensated, :func:`robot_mechanics`), which is then not computed. A robot
    with closed loops is linearised in its independent joints at a closed ``q`` (``ModelError`` if it is not:
    :func:`closed_configuration`, :func:`~sicomat.robotics.loops.solve_closure`).

    Examples
    --------
    >>> robot = MDHRobot.from_table([{"ant": 0, "sigma": 1, "mu": 1, "IA": 2.0},
    ...                              {"ant": 1, "sigma": 1, "eta": 1, "k": 100.0, "M": 3.0}], gravity=(0, 0, 0))
    >>> lin = linearize(robot, [0.0, 0.0])
    >>> lin.mass.tolist(), lin.stiffness.tolist()
    ([[5.0, 3.0], [3.0, 3.0]], [[0.0, 0.0], [0.0, 100.0]])
    """
    q0 = np.asarray(q, dtype=float)
    mass = robot.inertia_matrix(q0)
    mass = 0.5 * (mass + mass.T)
    rows = robot.joint_frames
    friction = robot.chi[rows, 11]
    springs = np.where(robot.eta[rows] == 1, robot.k[rows], 0.0)
    if robot.n_loops:
        coords = independent_joints(robot)
        g = independent_jacobian(robot, q0)
        mass = g.T @ mass @ g
        damping = g.T @ (friction[:, None] * g)
        mass, damping = 0.5 * (mass + mass.T), 0.5 * (damping + damping.T)
        stiffness = np.diag(springs[coords])
    else:
        coords, g = np.arange(robot.n_joints), np.eye(robot.n_joints)
        damping, stiffness = np.diag(friction), np.diag(springs)
    kg = gravity_stiffness(robot, q0) if gravity else np.zeros_like(stiffness)
    return Linearization(q=q0, mass=mass, damping=damping, stiffness=stiffness + kg, gravity_stiffness=kg,
                         coordinates=coords, jacobian=g)


def robot_mechanics(spec: "RobotSpec", q: "Sequence[float] | np.ndarray | None" = None, *,
                    free: Sequence[str] | None = None, actuators: Sequence[str] | None = None,
                    gravity: bool = True) -> Mechanics:
    """The robot of ``spec`` linearised at ``q`` as a :class:`Mechanics` in joint coordinates.

    Parameters
    ----------
    spec : RobotSpec
    q : sequence of float, optional
        Every joint value in frame order (default: the section's ``configuration``). With closed loops the
        passive joints' values are only the start of the closure (:func:`closed_configuration`).
    free : sequence of str, optional
        The joints kept as degrees of freedom (default: all); the others are locked at ``q``. With closed
        loops the degrees of freedom are the independent joints (motorised, elastic): locking one holds its
        coordinate (its column of ``G`` drops out); a passive joint always follows the closure, so naming
        it here changes nothing.
    actuators : sequence of str, optional
        The motorised joints that get an actuator (default: every free motorised joint); a joint's
        actuator applies its generalised force (N on a prismatic joint, N·m on a revolute one).
    gravity : bool
        Keep the gravity stiffness ``∂g/∂q`` (default). ``False``: gravity is taken as compensated by the
        controller (a gravity feedforward, or a counterbalanced vertical axis), so neither its load nor its
        stiffness enters the linear model — what a servo axis is tuned on (``docs/robotics.md``).

    Returns
    -------
    Mechanics
        Dofs named after the joints; the sensors of :meth:`RobotSpec.all_sensors` that read a free
        coordinate (a locked joint reads as a constant, so it drops out of the linear model; with closed
        loops a sensor's vector is the sum of its joints' rows of ``G``); couplings = the elastic joints'
        springs (and the gravity stiffness when there is one); frictions = the viscous and Coulomb friction
        of every non-elastic joint that the free coordinates move (with closed loops, on its row of ``G``).

    Raises
    ------
    ModelError
        A configuration of the wrong length or where the loops cannot close, an unknown joint, a linear
        model whose stiffness is not positive semi-definite (an equilibrium that gravity makes unstable with
        the motors locked).
    """
    robot = robot_model(spec)
    names = spec.joint_names
    q0 = closed_configuration(spec, q, robot)
    keep_names = list(names if free is None else free)
    for name in keep_names:
        if name not in names:
            raise ModelError(f"unknown joint {name!r}; expected one of {', '.join(names)}", path="robot.frames")
    try:
        lin = linearize(robot, q0, gravity=gravity)
    except AnalysisError as exc:       # a displaced configuration of the gravity stiffness did not close
        raise ModelError(f"the gravity stiffness needs the loops closed within {_GRAVITY_STEP:g} of this "
                         f"configuration, and they are not ({exc}): too near a singular configuration",
                         path="robot.configuration", value=q0.tolist()) from None
    coords = [names[j] for j in lin.coordinates]
    keep_names = [name for name in keep_names if name in coords]   # passive joints follow the closure
    if not keep_names:
        raise ModelError("no degree of freedom is left free", path="robot.frames")
    local = [coords.index(name) for name in keep_names]
    keep = [int(lin.coordinates[i]) for i in local]
    sub = np.ix_(local, local)
    M, D, K, Kg = lin.mass[sub], lin.damping[sub], lin.stiffness[sub], lin.gravity_stiffness[sub]
    G = lin.jacobian[:, local]
    rounding = _G_ZERO * np.max(np.abs(G))
    G = np.where(np.abs(G) > rounding, G, 0.0)
    n = len(keep)
    sigma = robot.sigma[robot.joint_frames]
    kinds_all = ["translational" if s == PRISMATIC else "rotational" for s in sigma]
    rows = robot.joint_frames[keep]
    kinds = [kinds_all[j] for j in keep]
    dofs = tuple(Dof(name, kind) for name, kind in zip(keep_names, kinds))  # type: ignore[arg-type]
    eye = np.eye(n)
    elastic = [i for i, row in enumerate(rows) if robot.eta[row] == 1]
    springs = [Link(keep_names[i], eye[i].copy(), kinds[i], stiffness=float(robot.k[rows[i]]),  # type: ignore[arg-type]
                    damping=float(robot.chi[rows[i], 11])) for i in elastic]
    scale = max(float(np.max(np.abs(K), initial=0.0)), 1e-300)
    if np.max(np.abs(Kg), initial=0.0) > 1e-12 * scale:
        lowest = float(np.linalg.eigvalsh(K)[0])
        if lowest < -1e-9 * scale:
            raise ModelError(f"the linear model at this configuration has a negative stiffness (eigenvalue "
                             f"{lowest:.3g}): gravity makes the equilibrium unstable with the motors locked",
                             path="robot.configuration", value=q0.tolist())
        couplings = None        # springs and gravity stiffness together: K split into its eigen-components
    else:
        couplings = springs
    frictions = []
    for j in keep + [j for j in range(robot.n_joints) if j not in keep]:   # the free ones first, in dof order
        row = robot.joint_frames[j]
        fv, fs = float(robot.chi[row, 11]), float(robot.chi[row, 12])
        if robot.eta[row] == 1 or not (fv > 0 or fs > 0) or not np.any(G[j]):
            continue
        frictions.append(Link(f"{names[j]}_friction", G[j].copy(), kinds_all[j],  # type: ignore[arg-type]
                              damping=fv, coulomb=fs, static=fs))
    motors = [name for name in spec.motor_names if name in keep_names] if actuators is None else list(actuators)
    loads = []
    for name in motors:
        if name not in keep_names or name not in spec.motor_names:
            raise ModelError(f"{name!r} is not a free motorised joint", path="robot.frames")
        i = keep_names.index(name)
        loads.append(Load(name, eye[i].copy(), kinds[i]))  # type: ignore[arg-type]
    sensors = []
    for name, sensor in spec.all_sensors().items():
        vector = sum((G[names.index(joint)] for joint in sensor.joints), np.zeros(n))
        vector[np.abs(vector) <= rounding] = 0.0       # rows that cancel (a pin and the yaw it undoes)
        if not np.any(vector):
            continue
        unit = spec.joint_kind(sensor.joints[0])
        sensors.append(Measurement(name, vector, sensor.kind, unit, step=sensor.step))
    return Mechanics.from_matrices(dofs, M, D, K, actuators=loads, sensors=sensors, couplings=couplings,
                                   frictions=frictions)


def axis_free_joints(spec: "RobotSpec", axis: str | None) -> list[str]:
    """The joints left free (frame order) in axis ``axis``'s decoupled model: its own motorised joint and
    every joint that is not motorised (the elastic ones); the other motors are locked. ``axis=None``:
    every motor locked (the structure's own modes, ``sicomat modal`` on a robot). With closed loops the
    passive joints (neither motorised nor elastic) follow the closure: they are not degrees of freedom."""
    free = [j for j in spec.joint_names if j == axis or j not in spec.motor_names]
    if spec.links is not None and spec.links < len(spec.frames):
        free = [j for j in free if j == axis or spec.frames[spec.joint_rows[spec.joint_names.index(j)]].eta == 1]
    return free


def axis_mechanics(machine: "Machine", axis: str | None = None) -> Mechanics:
    """The mechanics of one axis of ``machine``, checked: an axis's own mechanics description lowered
    (:func:`sicomat.mechanics.lumped.check_axis_mechanics`), or for a robot's axis the robot linearised at
    its configuration with the other motorised joints locked (held by their servo loops, taken as rigid),
    the elastic joints free and gravity compensated by the controller — the decoupled model each axis is
    tuned on (with gravity, a joint whose motor is free is an inverted pendulum the loop must hold, and its
    gravity torque a load the integral action or a feedforward carries; ``docs/robotics.md``). With closed
    loops the same rule holds in the independent coordinates: on a gantry, the model of drive X1 locks the
    other drive X2 of the same machine axis (held by its own loop), a stiffer model than both moving together
    (``sicomat.servo.coupled.robot_coupled_loop``)."""
    from ..mechanics.conditioning import check_resolvable
    from ..mechanics.lumped import check_axis_mechanics

    name = machine.axis_name(axis)
    spec = machine.axes[name]
    if machine.robot is None or spec.mechanics is not None:
        return check_axis_mechanics(name, spec.mechanics)
    robot = machine.robot
    mech = robot_mechanics(robot, free=axis_free_joints(robot, name), gravity=False)
    check_resolvable(mech)
    return mech
