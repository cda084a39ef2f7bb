"""Shared robotics test models (issue 13): the Pinocchio model built from an MDH table, and the elastic
XY cross-slide of the notes (``shared/reference/robotics-formalism.md`` §4).

A plain module beside the tests (imported as ``robotics_models``, like ``accuracy``), so the Pinocchio
builder is written once and the reference stays independent of the code under test: it reads the table
rows, never an :class:`~sicomat.robotics.MDHRobot`.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin  # a test dependency ([test] extras, requirements.lock): a missing install fails here

PI = math.pi


def _rz(t: float) -> np.ndarray:
    return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1.0]])


def _rx(t: float) -> np.ndarray:
    return np.array([[1.0, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])


def constant_placement(row: dict) -> tuple[np.ndarray, np.ndarray]:
    """Rot(z,gamma) Trans(z,b) Rot(x,alpha) Trans(x,d) Rot(z,theta) Trans(z,r) with the constant
    theta, r (the joint variable follows as Pinocchio's RZ or PZ joint: Rz and Tz commute)."""
    g, a, t = row.get("gamma", 0.0), row.get("alpha", 0.0), row.get("theta", 0.0)
    rot = _rz(g) @ _rx(a) @ _rz(t)
    pos = np.array([0, 0, row.get("b", 0.0)]) + _rz(g) @ _rx(a) @ np.array([row.get("d", 0.0), 0, 0]) \
        + rot[:, 2] * row.get("r", 0.0)
    return rot, pos


def _inertia(row: dict) -> "pin.Inertia":
    """Pinocchio's inertia of a row's link, about the body frame's origin like Khalil's.

    ``FromDynamicParameters`` divides by the mass: a massless link (the notes' §3.4 pitfall 3, the
    virtual links of lumped elasticity) would give NaN and poison ``rnea``/``aba``; it is built from its
    rotational inertia alone (no mass, no first moment: the table forbids MS without M)."""
    g = lambda key: row.get(key, 0.0)  # noqa: E731
    if g("M") == 0.0:
        tensor = np.array([[g("XX"), g("XY"), g("XZ")], [g("XY"), g("YY"), g("YZ")], [g("XZ"), g("YZ"), g("ZZ")]])
        return pin.Inertia(0.0, np.zeros(3), tensor)
    params = np.array([g("M"), g("MX"), g("MY"), g("MZ"), g("XX"), g("XY"), g("YY"), g("XZ"), g("YZ"), g("ZZ")])
    return pin.Inertia.FromDynamicParameters(params)


def pinocchio_model(frames: list[dict], gravity=(0.0, 0.0, -9.81)):
    """Pinocchio's model of a tree table (notes §3.4): each moving frame a RZ/PZ joint, each fixed frame's
    link appended to its antecedent's joint. Returns ``(model, data)``."""
    model = pin.Model()
    model.gravity.linear = np.array(gravity, dtype=float)
    joint = {0: 0}                       # frame number -> Pinocchio joint carrying it
    in_joint = {0: pin.SE3.Identity()}   # frame number -> its placement in that joint's frame
    for j, row in enumerate(frames, start=1):
        local = pin.SE3(*constant_placement(row))
        a = row["ant"]
        placement = in_joint[a] * local
        if row["sigma"] == 2:
            joint[j], in_joint[j] = joint[a], placement
        else:
            kind = pin.JointModelRZ() if row["sigma"] == 0 else pin.JointModelPZ()
            joint[j] = model.addJoint(joint[a], kind, placement, f"joint{j}")
            in_joint[j] = pin.SE3.Identity()
        model.appendBodyToJoint(joint[j], _inertia(row), in_joint[j])
    return model, model.createData()


def elastic_cross_slide_frames() -> list[dict]:
    """The elastic XY cross-slide of the notes §4: X motor (massless link), X screw deflection, carriage yaw,
    Y motor, Y screw deflection carrying the head, a fixed tool-tip frame h = 0.2 m below."""
    return [dict(ant=0, sigma=1, mu=1, gamma=PI / 2, alpha=PI / 2, IA=30.0),
            dict(ant=1, sigma=1, eta=1, k=2e8),
            dict(ant=2, sigma=0, eta=1, k=5e7, alpha=-PI / 2, theta=-PI / 2,
                 M=120.0, MX=6.0, MY=-9.0, XX=30.0, YY=30.0, ZZ=40.0),
            dict(ant=3, sigma=1, mu=1, alpha=-PI / 2, IA=20.0),
            dict(ant=4, sigma=1, eta=1, k=1.5e8, M=60.0, MX=3.0, XX=8.0, YY=9.0, ZZ=7.0),
            dict(ant=5, sigma=2, alpha=-PI / 2, r=0.2)]


def physical_inertia(rng: np.random.Generator) -> dict[str, float]:
    """A real body about the frame origin: a box of random half-sizes and pose, its inertia about the frame
    origin by the parallel-axis theorem written out here, independently of the code under test."""
    mass = rng.uniform(0.5, 3.0)
    a, b, c = rng.uniform(0.05, 0.4, 3) ** 2
    axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    j_com = axes @ np.diag(mass / 3.0 * np.array([b + c, a + c, a + b])) @ axes.T
    com = rng.uniform(-0.3, 0.3, 3)
    j_o = j_com + mass * (com @ com * np.eye(3) - np.outer(com, com))
    return {"XX": j_o[0, 0], "XY": j_o[0, 1], "XZ": j_o[0, 2], "YY": j_o[1, 1], "YZ": j_o[1, 2],
            "ZZ": j_o[2, 2], "MX": mass * com[0], "MY": mass * com[1], "MZ": mass * com[2], "M": mass}


def xy_inertia_by_lagrange(spec, q) -> np.ndarray:
    """The inertia matrix of ``examples/xy_elastic.toml`` at ``q`` (X, X_screw, yaw, Y, Y_screw): the notes' §4
    closed form (sympy Lagrange on the MDH kinematics), the frame parameters read by name from the model file's
    ``[robot]`` section ``spec`` (shared by the model and mode-map tests)."""
    f = {frame.name: frame for frame in spec.frames}
    M3, ZZ3, MX3, MY3 = f["yaw"].M, f["yaw"].ZZ, f["yaw"].MX, f["yaw"].MY
    M5, MX5, YY5 = f["Y_screw"].M, f["Y_screw"].MX, f["Y_screw"].YY
    IA1, IA4 = f["X"].IA, f["Y"].IA
    y = q[3] + q[4]
    c, s = math.cos(q[2]), math.sin(q[2])
    a13 = -(M5 * y + MY3) * c - (MX3 + MX5) * s
    A = np.zeros((5, 5))
    A[0, 0] = IA1 + M3 + M5
    A[0, 1] = A[1, 1] = M3 + M5
    A[0, 2] = A[1, 2] = a13
    A[0, 3] = A[0, 4] = A[1, 3] = A[1, 4] = -M5 * s
    A[2, 2] = ZZ3 + YY5 + M5 * y ** 2
    A[2, 3] = A[2, 4] = MX5
    A[3, 3] = IA4 + M5
    A[3, 4] = A[4, 4] = M5
    return np.triu(A) + np.triu(A, 1).T
