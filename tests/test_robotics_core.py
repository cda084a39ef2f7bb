"""The robotics numeric core (issue 13, first piece): MDH tables, transforms, Jacobian, Newton–Euler,
composite-link inertia matrix, direct dynamics and regressor.

The references are independent of the code under test: Pinocchio (a C++ rigid-body library, built
here from the MDH table with the mapping of ``shared/reference/robotics-formalism.md`` §3.4), the
Lagrange equations of a planar 2R arm written out by hand, and central finite differences.

Tolerances. Every model here is a few dozen floating-point operations per frame on numbers of order
1 (lengths <= ~1 m, masses <= 3 kg, speeds <= 2 rad/s): the rounding of both codes is ~1e-15 of the
torque scale, so a bound of 1e-9 (the issue's) has a margin of ~1e5 over rounding, while any
convention error (a sign, a transposed rotation, a missing Coriolis factor 2, an inertia about the
wrong point) changes torques by O(1) of their scale.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin  # a test dependency ([test] extras, requirements.lock): a missing install fails here
import pytest

from sicomat.errors import ModelError
from sicomat.robotics import MDHRobot

from robotics_models import pinocchio_model

REL = 1e-9


# --------------------------------------------------------------------------- random models
def _physical_inertia(rng: np.random.Generator) -> dict[str, float]:
    """Parameters of a real body about the frame origin: a box of random half-sizes, random pose."""
    mass = rng.uniform(0.5, 3.0)
    sides = rng.uniform(0.05, 0.4, 3)
    a, b, c = sides ** 2
    principal = mass / 3.0 * np.array([b + c, a + c, a + b])      # box of half-sides `sides`
    axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    j_com = axes @ np.diag(principal) @ axes.T
    com = rng.uniform(-0.3, 0.3, 3)
    # parallel-axis theorem, written independently of the code under test: J_O = J_G + M (c.c I - c c^T)
    j_o = j_com + mass * (com @ com * np.eye(3) - np.outer(com, com))
    return {"XX": j_o[0, 0], "XY": j_o[0, 1], "XZ": j_o[0, 2], "YY": j_o[1, 1], "YZ": j_o[1, 2],
            "ZZ": j_o[2, 2], "MX": mass * com[0], "MY": mass * com[1], "MZ": mass * com[2], "M": mass}


def _random_table(seed: int, tree: bool) -> list[dict[str, float]]:
    rng = np.random.default_rng(seed)
    nf = int(rng.integers(4, 8))
    frames: list[dict[str, float]] = []
    for j in range(1, nf + 1):
        # frame 1 moves (a robot whose first frame is fixed is legal but tests little); later ones may be fixed
        sigma = int(rng.choice([0, 1, 2], p=[0.5, 0.35, 0.15])) if j > 1 else int(rng.integers(0, 2))
        ant = int(rng.integers(0, j)) if tree else j - 1
        row: dict[str, float] = {"ant": ant, "sigma": sigma}
        for key in ("gamma", "alpha", "theta"):
            row[key] = rng.uniform(-math.pi, math.pi)
        for key in ("b", "d", "r"):
            row[key] = rng.uniform(-0.5, 0.5)
        row.update(_physical_inertia(rng))
        if sigma != 2:
            row.update(IA=rng.uniform(0.0, 0.2), FV=rng.uniform(0.0, 0.5), FS=rng.uniform(0.0, 0.5))
            row["mu"] = int(rng.integers(0, 2))
            if row["mu"] == 0:
                row["eta"], row["k"] = 1, rng.uniform(1e3, 1e5)
        frames.append(row)
    return frames


def _random_states(robot: MDHRobot, seed: int, count: int):
    rng = np.random.default_rng(seed + 1000)
    n = robot.n_joints
    return (rng.uniform(-math.pi, math.pi, (count, n)), rng.uniform(-2, 2, (count, n)),
            rng.uniform(-5, 5, (count, n)))


CASES = [(seed, tree) for seed in range(6) for tree in (False, True)]


def test_the_random_cases_cover_what_they_claim():
    tables = [_random_table(seed, tree) for seed, tree in CASES]
    assert sum(any(row["sigma"] == 1 for row in t) for t in tables) >= 8           # prismatic joints
    assert sum(any(row["sigma"] == 2 for row in t) for t in tables) >= 4           # fixed frames
    assert sum(any(row["ant"] != j for j, row in enumerate(t)) for t in tables) >= 5   # branches
    assert sum(any(row.get("eta") == 1 for row in t) for t in tables) >= 4         # elastic joints (rigid here)


# --------------------------------------------------------------------------- Pinocchio from the table
# the builder lives in tests/robotics_models.py (shared with the elastic and closed-loop tests)
_pinocchio = pinocchio_model


def _depth_first(model) -> bool:
    """Is every joint's subtree contiguous in Pinocchio's joint order? ``pin.crba`` fills row i over
    ``nvSubtree`` columns from joint i and assumes so (a tree numbered breadth-first, legal in MDH,
    gets zeros there: seen on these random trees)."""
    parents = list(model.parents)
    for i in range(1, model.njoints):
        subtree = {i}
        for j in range(i + 1, model.njoints):
            if parents[j] in subtree:
                subtree.add(j)
        if subtree != set(range(i, i + len(subtree))):
            return False
    return True


def _pinocchio_inertia_matrix(model, data, q) -> np.ndarray:
    """Pinocchio's joint-space inertia matrix: ``crba`` when the joint order allows it, else column by
    column from ``rnea`` (unit acceleration, no velocity, no gravity)."""
    if _depth_first(model):
        m = pin.crba(model, data, q)
        return np.triu(m) + np.triu(m, 1).T
    gravity = model.gravity.linear.copy()
    model.gravity.linear = np.zeros(3)
    m = np.column_stack([pin.rnea(model, data, q, 0 * q, e) for e in np.eye(model.nv)])
    model.gravity.linear = gravity
    return m


def _extras(frames: list[dict], qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """IA qdd + FV qd + FS sign(qd), by hand (Pinocchio has no friction; armature added here too)."""
    moving = [row for row in frames if row["sigma"] != 2]
    ia, fv, fs = (np.array([row.get(key, 0.0) for row in moving]) for key in ("IA", "FV", "FS"))
    return ia * qdd + fv * qd + fs * np.sign(qd)


# --------------------------------------------------------------------------- against Pinocchio
@pytest.mark.parametrize("seed,tree", CASES)
def test_newton_euler_and_inertia_matrix_match_pinocchio(seed, tree):
    frames = _random_table(seed, tree)
    robot = MDHRobot.from_table(frames)
    model, data = _pinocchio(frames)
    assert model.nq == robot.n_joints
    ia = np.array([row.get("IA", 0.0) for row in frames if row["sigma"] != 2])
    for q, qd, qdd in zip(*_random_states(robot, seed, 10)):
        expected = pin.rnea(model, data, q, qd, qdd) + _extras(frames, qd, qdd)
        scale = max(1.0, np.max(np.abs(expected)))
        np.testing.assert_allclose(robot.inverse_dynamics(q, qd, qdd), expected, rtol=0, atol=REL * scale)
        m_pin = _pinocchio_inertia_matrix(model, data, q) + np.diag(ia)
        np.testing.assert_allclose(robot.inertia_matrix(q), m_pin, rtol=0, atol=REL * max(1.0, np.max(np.abs(m_pin))))
        # the geometry too: each moving frame is a Pinocchio joint frame
        pin.forwardKinematics(model, data, q)
        moving = [j for j, row in enumerate(frames, start=1) if row["sigma"] != 2]
        for joint_id, j in enumerate(moving, start=1):
            t = robot.transform(q, j)
            np.testing.assert_allclose(t[:3, :3], data.oMi[joint_id].rotation, atol=1e-12)
            np.testing.assert_allclose(t[:3, 3], data.oMi[joint_id].translation, atol=1e-12)


@pytest.mark.parametrize("seed,tree", CASES[:6])
def test_direct_dynamics_matches_pinocchio_aba(seed, tree):
    frames = _random_table(seed, tree)
    robot = MDHRobot.from_table(frames)
    model, data = _pinocchio(frames)
    model.armature = np.array([row.get("IA", 0.0) for row in frames if row["sigma"] != 2])
    for q, qd, tau in zip(*_random_states(robot, seed, 5)):
        tau = 10 * tau
        # Pinocchio sees the friction as a torque taken off the input
        expected = pin.aba(model, data, q, qd, tau - _extras(frames, qd, 0 * qd))
        # qdd = A^-1 (...): the error is ~cond(A) eps |qdd|; cond(A) of these models is < 1e4
        np.testing.assert_allclose(robot.direct_dynamics(q, qd, tau), expected, rtol=0,
                                   atol=1e-9 * max(1.0, np.max(np.abs(expected))))


# --------------------------------------------------------------------------- consistency
@pytest.mark.parametrize("seed,tree", CASES[:6])
def test_regressor_is_linear_in_the_standard_parameters(seed, tree):
    frames = _random_table(seed, tree)
    robot = MDHRobot.from_table(frames)
    # the same geometry with other parameters: the regressor must not depend on them
    other_frames = [dict(row) for row in frames]
    rng = np.random.default_rng(seed + 7)
    for row in other_frames:
        row.update(_physical_inertia(rng))
        if row["sigma"] != 2:
            row.update(IA=rng.uniform(0, 1), FV=rng.uniform(0, 1), FS=rng.uniform(0, 1))
    other = MDHRobot.from_table(other_frames)
    model, data = _pinocchio(other_frames)
    for q, qd, qdd in zip(*_random_states(robot, seed, 5)):
        phi = robot.regressor(q, qd, qdd)
        assert phi.shape == (robot.n_joints, 13 * robot.n_frames)
        tau = robot.inverse_dynamics(q, qd, qdd)
        np.testing.assert_allclose(phi @ robot.standard_parameters(), tau, rtol=0,
                                   atol=REL * max(1.0, np.max(np.abs(tau))))
        expected = pin.rnea(model, data, q, qd, qdd) + _extras(other_frames, qd, qdd)
        np.testing.assert_allclose(phi @ other.standard_parameters(), expected, rtol=0,
                                   atol=REL * max(1.0, np.max(np.abs(expected))))


@pytest.mark.parametrize("tree", [False, True])
def test_batch_equals_one_by_one(tree):
    robot = MDHRobot.from_table(_random_table(3, tree))
    q, qd, qdd = _random_states(robot, 3, 25)
    batch = robot.inverse_dynamics_batch(q, qd, qdd)
    one_by_one = np.array([robot.inverse_dynamics(*state) for state in zip(q, qd, qdd)])
    # the same compiled recursion per state (the batch kernel loops over states inside numba)
    np.testing.assert_allclose(batch, one_by_one, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(one_by_one))))


@pytest.mark.parametrize("seed,tree", CASES[:4])
def test_direct_dynamics_inverts_inverse_dynamics(seed, tree):
    robot = MDHRobot.from_table(_random_table(seed, tree))
    for q, qd, qdd in zip(*_random_states(robot, seed, 5)):
        tau = robot.inverse_dynamics(q, qd, qdd)
        # |qdd| <= 5: error ~ cond(A) eps |tau| / lambda_min(A), far below 1e-9 for cond(A) < 1e4
        np.testing.assert_allclose(robot.direct_dynamics(q, qd, tau), qdd, rtol=0, atol=1e-9 * 5)


# --------------------------------------------------------------------------- planar 2R by Lagrange
def test_planar_2r_arm_against_lagrange():
    """Two vertical revolute axes (gravity along them does no work), link 2 at d2 = L from axis 1.

    Lagrange, written out: O2 = L (cos q1, sin q1); link 2's first moment in the base is
    Rz(q1 + q2) [MX2, MY2]; with w = qd1 + qd2 the kinetic energy is
        T = 1/2 (ZZ1 + IA1 + L^2 M2) qd1^2 + 1/2 ZZ2 w^2 + 1/2 IA2 qd2^2 + a qd1 w,
    where v_O2 . (w z x Rz(q1+q2) MS2) = L qd1 w (MX2 cos q2 - MY2 sin q2) =: a qd1 w. So
        A11 = ZZ1 + IA1 + L^2 M2 + ZZ2 + 2a,  A12 = ZZ2 + a,  A22 = ZZ2 + IA2,
    and with da/dq2 = -L (MX2 sin q2 + MY2 cos q2) =: -b,
        tau1 = A11 qdd1 + A12 qdd2 - b (2 qd1 qd2 + qd2^2)
        tau2 = A12 qdd1 + A22 qdd2 + b qd1^2          (plus FV qd + FS sign(qd) on each joint).
    """
    L, zz1, ia1, ia2 = 0.7, 0.9, 0.05, 0.02
    m2, mx2, my2 = 2.0, 0.6, -0.2
    # link 2's tensor about O2 must hold its centre of mass 0.3 m, -0.1 m away: ZZ2 >= (MX^2 + MY^2)/M
    zz2, xx2, yy2 = 0.4, 0.1, 0.3
    fv, fs = (0.3, 0.1), (0.2, 0.4)
    robot = MDHRobot.from_table([
        {"ant": 0, "sigma": 0, "mu": 1, "ZZ": zz1, "IA": ia1, "FV": fv[0], "FS": fs[0]},
        {"ant": 1, "sigma": 0, "mu": 1, "d": L, "XX": xx2, "YY": yy2, "ZZ": zz2, "MX": mx2, "MY": my2,
         "M": m2, "IA": ia2, "FV": fv[1], "FS": fs[1]}])
    rng = np.random.default_rng(5)
    for _ in range(10):
        q1, q2 = rng.uniform(-math.pi, math.pi, 2)
        qd1, qd2 = rng.uniform(-2, 2, 2)
        qdd1, qdd2 = rng.uniform(-5, 5, 2)
        a = L * (mx2 * math.cos(q2) - my2 * math.sin(q2))
        b = L * (mx2 * math.sin(q2) + my2 * math.cos(q2))
        a11, a12, a22 = zz1 + ia1 + L ** 2 * m2 + zz2 + 2 * a, zz2 + a, zz2 + ia2
        tau1 = a11 * qdd1 + a12 * qdd2 - b * (2 * qd1 * qd2 + qd2 ** 2) + fv[0] * qd1 + fs[0] * np.sign(qd1)
        tau2 = a12 * qdd1 + a22 * qdd2 + b * qd1 ** 2 + fv[1] * qd2 + fs[1] * np.sign(qd2)
        np.testing.assert_allclose(robot.inverse_dynamics([q1, q2], [qd1, qd2], [qdd1, qdd2]), [tau1, tau2],
                                   rtol=0, atol=1e-12 * 50)     # torques of order 10: rounding ~1e-14
        np.testing.assert_allclose(robot.inertia_matrix([q1, q2]), [[a11, a12], [a12, a22]], rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- Jacobian
@pytest.mark.parametrize("seed,tree", CASES[:6])
def test_jacobian_against_central_differences_of_transform(seed, tree):
    """Central differences with h = 1e-5: truncation h^2/6 |d3T/dq3| <= 1e-10 * ~3 (lever arms of
    at most ~3 m, derivatives of sin/cos bounded by 1) and rounding eps |T| / h ~ 3e-11 * 3; the
    bound 1e-8 leaves a margin of ~30 while a wrong column (missing lever arm, wrong axis, wrong
    frame) is off by O(0.1..1)."""
    robot = MDHRobot.from_table(_random_table(seed, tree))
    h = 1e-5
    q = _random_states(robot, seed, 1)[0][0]
    for j in range(1, robot.n_frames + 1):
        jac = robot.jacobian(q, j)
        numeric = np.zeros_like(jac)
        t0 = robot.transform(q, j)
        for k in range(robot.n_joints):
            dq = np.zeros_like(q)
            dq[k] = h
            tp, tm = robot.transform(q + dq, j), robot.transform(q - dq, j)
            numeric[:3, k] = (tp[:3, 3] - tm[:3, 3]) / (2 * h)
            omega_hat = (tp[:3, :3] - tm[:3, :3]) / (2 * h) @ t0[:3, :3].T    # dR/dq R^T = omega^
            numeric[3:, k] = [omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]]
        np.testing.assert_allclose(jac, numeric, rtol=0, atol=1e-8)


def test_transform_between_frames_composes():
    robot = MDHRobot.from_table(_random_table(2, True))
    q = _random_states(robot, 2, 1)[0][0]
    for i in range(robot.n_frames + 1):
        for j in range(robot.n_frames + 1):
            np.testing.assert_allclose(robot.transform(q, i) @ robot.transform(q, j, i), robot.transform(q, j),
                                       atol=1e-12)


# --------------------------------------------------------------------------- bad tables
GOOD = {"ant": 0, "sigma": 0, "M": 1.0, "XX": 0.1, "YY": 0.1, "ZZ": 0.1}


def _table_with(row: dict) -> list[dict]:
    """Frames 1 and 2 good, the row under test as frame 3 (row index 2)."""
    return [dict(GOOD), dict(GOOD, ant=1), row]


@pytest.mark.parametrize("row,field,words", [
    (dict(GOOD, ant=3), "ant", "antecedent"),                     # itself
    (dict(GOOD, ant=5), "ant", "antecedent"),                     # a later frame
    (dict(GOOD, ant=-1), "ant", "antecedent"),
    (dict(GOOD, ant=1.5), "ant", "integer"),
    (dict(GOOD, sigma=3), "sigma", "sigma must be 0"),
    (dict(GOOD, sigma=-1), "sigma", "sigma must be 0"),
    (dict(GOOD, eta=1, mu=1), "mu", "elastic"),
    (dict(GOOD, sigma=2, mu=1), "mu", "fixed"),
    (dict(GOOD, sigma=2, eta=1), "eta", "fixed"),
    (dict(GOOD, sigma=2, IA=0.1), "IA", "fixed"),
    (dict(GOOD, sigma=2, FS=0.1), "FS", "fixed"),
    (dict(GOOD, M=-1.0), "M", "negative"),
    (dict(GOOD, k=-5.0), "k", "negative"),
    (dict(GOOD, FV=-0.1), "FV", "negative"),
    (dict(GOOD, d=float("nan")), "d", "finite"),
    (dict(GOOD, ZZ=float("inf")), "ZZ", "finite"),
    (dict(GOOD, r="0.1"), "r", "number"),
    (dict(GOOD, nu=1), "nu", "unknown field"),
    ({"sigma": 0}, "ant", "required"),
    ({"ant": 1}, "sigma", "required"),
    # a tensor with a negative principal moment about the origin itself
    (dict(GOOD, XY=0.5), "XX..ZZ", "positive semi-definite"),
    # positive definite about the origin, but not about the centre of mass 0.5 m away along x:
    # YY_G = YY_O - M c^2 = 0.1 - 0.25 < 0
    (dict(GOOD, MX=0.5), "XX..ZZ", "centre of mass"),
    (dict(GOOD, M=0.0, MX=0.1), "MX", "massless"),
])
def test_bad_tables_are_rejected_naming_frame_and_field(row, field, words):
    with pytest.raises(ModelError) as caught:
        MDHRobot.from_table(_table_with(row))
    error = caught.value
    assert error.path == f"frames[2].{field}"
    assert "frame 3" in str(error) and words in str(error)


def test_the_inertia_check_accepts_a_real_body_offset_from_its_frame():
    # a point mass of 1 kg at 0.5 m on x: about the origin YY = ZZ = 0.25, XX = 0 (tensor about the CoM = 0)
    MDHRobot.from_table([{"ant": 0, "sigma": 0, "M": 1.0, "MX": 0.5, "YY": 0.25, "ZZ": 0.25}])


def test_bad_gravity_and_frames():
    with pytest.raises(ModelError, match="gravity"):
        MDHRobot.from_table([GOOD], gravity=(0.0, -9.81))
    with pytest.raises(ModelError, match="no frames"):
        MDHRobot.from_table([])
    with pytest.raises(ModelError) as caught:
        MDHRobot.from_table([GOOD, 3])
    assert caught.value.path == "frames[1]"


def test_joint_vectors_of_the_wrong_length_are_rejected():
    robot = MDHRobot.from_table([GOOD, dict(GOOD, ant=1, sigma=2), dict(GOOD, ant=2)])
    assert robot.n_joints == 2
    with pytest.raises(ModelError, match="2 joint values"):
        robot.inverse_dynamics([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])


# --------------------------------------------------------------------------- the compiled kernels
# Newton–Euler and the inertia matrix run in numba (robotics/_kernels.py); the regressor stays numpy
# (its own forward recursion, dynamics._forward): the two engines are checked against each other on
# random trees, larger ones too, beside the Pinocchio checks above.
KERNEL_CASES = [(seed, True) for seed in range(6)] + [(seed, False) for seed in range(2)]


def _big_random_table(seed: int) -> list[dict[str, float]]:
    """A random tree of 12-20 frames, built from two random tables joined end to end."""
    first, second = _random_table(seed, True), _random_table(seed + 50, True)
    rng = np.random.default_rng(seed + 99)
    offset = len(first)
    joined = [dict(row) for row in first]
    for row in second:
        row = dict(row)
        row["ant"] = row["ant"] + offset if row["ant"] > 0 else int(rng.integers(0, offset + 1))
        joined.append(row)
    return joined + [dict(row, ant=row["ant"] + len(joined) if row["ant"] > 0 else len(joined))
                     for row in _random_table(seed + 77, False)]


@pytest.mark.parametrize("seed,tree", KERNEL_CASES)
@pytest.mark.parametrize("big", [False, True])
def test_compiled_kernels_equal_the_numpy_regressor_engine(seed, tree, big):
    frames = _big_random_table(seed) if big else _random_table(seed, tree)
    robot = MDHRobot.from_table(frames)
    chi = robot.standard_parameters()
    n = robot.n_joints
    q, qd, qdd = _random_states(robot, seed, 4)
    for state in zip(q, qd, qdd):
        tau = robot.inverse_dynamics(*state)
        reference = robot.regressor(*state) @ chi
        scale = max(1.0, float(np.max(np.abs(reference))))
        np.testing.assert_allclose(tau, reference, rtol=0, atol=1e-12 * scale)
        # column j of A(q): the torques of a unit qdd_j at rest, gravity removed (linear in qdd)
        at_rest = robot.regressor(state[0], np.zeros(n), np.zeros(n)) @ chi
        columns = np.column_stack([robot.regressor(state[0], np.zeros(n), e) @ chi - at_rest for e in np.eye(n)])
        a = robot.inertia_matrix(state[0])
        np.testing.assert_allclose(a, columns, rtol=0, atol=1e-12 * max(1.0, float(np.max(np.abs(columns)))))
        np.testing.assert_array_equal(a, a.T)


@pytest.mark.parametrize("seed", [0, 3])
def test_batch_kernels_equal_one_by_one(seed):
    robot = MDHRobot.from_table(_big_random_table(seed))
    q, qd, qdd = _random_states(robot, seed, 30)
    batch = robot.inverse_dynamics_batch(q, qd, qdd)
    one_by_one = np.array([robot.inverse_dynamics(*state) for state in zip(q, qd, qdd)])
    np.testing.assert_allclose(batch, one_by_one, rtol=0, atol=1e-13 * max(1.0, float(np.max(np.abs(one_by_one)))))
    from sicomat.robotics import inertia_matrix_batch

    matrices = inertia_matrix_batch(robot, q)
    assert matrices.shape == (30, robot.n_joints, robot.n_joints)
    for qs, a in zip(q, matrices):
        np.testing.assert_allclose(a, robot.inertia_matrix(qs), rtol=0, atol=1e-13 * max(1.0, float(np.max(np.abs(a)))))
    # one state given as a (1, n) batch, and as a list
    np.testing.assert_array_equal(robot.inverse_dynamics(q[:1], qd[:1], qdd[:1]), one_by_one[0])
    np.testing.assert_array_equal(robot.inertia_matrix(list(q[0])), matrices[0])


def test_compiled_kernels_reject_non_finite_states_and_wrong_shapes():
    from sicomat.robotics import inertia_matrix_batch

    robot = MDHRobot.from_table(_random_table(1, True))
    n = robot.n_joints
    good = np.zeros(n)
    bad = good.copy()
    bad[-1] = np.nan
    for args, name in (((bad, good, good), "q"), ((good, bad, good), "qd"), ((good, good, bad), "qdd")):
        with pytest.raises(ModelError, match="finite") as caught:
            robot.inverse_dynamics(*args)
        assert caught.value.path == name
        with pytest.raises(ModelError, match="finite"):
            robot.inverse_dynamics_batch(*(np.tile(x, (3, 1)) for x in args))
    with pytest.raises(ModelError, match="finite"):
        robot.inertia_matrix(bad)
    with pytest.raises(ModelError, match="finite"):
        inertia_matrix_batch(robot, np.tile(bad, (2, 1)))
    with pytest.raises(ModelError, match="one state"):
        robot.inverse_dynamics(np.zeros((2, n)), np.zeros((2, n)), np.zeros((2, n)))
    with pytest.raises(ModelError, match="one state"):
        robot.inertia_matrix(np.zeros((2, n)))
    with pytest.raises(ModelError, match=f"{n} joint values"):
        robot.inertia_matrix(np.zeros(n + 1))


def test_kernel_arrays_are_prepared_once_per_robot_and_read_only():
    from sicomat.robotics._kernels import flat_arrays

    robot = MDHRobot.from_table(_random_table(2, True))
    first = flat_arrays(robot)
    robot.inverse_dynamics(*(np.zeros(robot.n_joints),) * 3)
    assert all(a is b for a, b in zip(first, flat_arrays(robot)))
    assert not any(a.flags.writeable for a in first)
    # the table's gamma, b, alpha, d, theta, r reproduce the local transforms of the numpy geometry
    from sicomat.robotics.geometry import local_transforms

    q = _random_states(robot, 2, 1)[0]
    rot, pos = local_transforms(robot, q)
    ints, geo, _ = first
    c = geo[:, :9].reshape(-1, 3, 3)
    np.testing.assert_allclose(c[:, :, 2], rot[0, :, :, 2], atol=1e-15)
    revolute = robot.sigma != 1                    # r is constant there: the origin is p0 + C[:, 2] r
    np.testing.assert_allclose((geo[:, 9:12] + c[:, :, 2] * geo[:, 13:14])[revolute], pos[0][revolute], atol=1e-15)
    assert ints[:, 0].tolist() == robot.ant.tolist() and ints[:, 2].tolist() == robot.joint_of_frame.tolist()
