"""Elastic joints, the hybrid model (issue 13): :func:`sicomat.robotics.hybrid_dynamics` and
:func:`sicomat.robotics.elastic_direct_dynamics`.

References independent of the code under test: Pinocchio's ``rnea``/``aba`` on the model built from the
table (``tests/robotics_models.py``), the joint equations themselves (Newton–Euler fed back the
accelerations found), and the inertia matrix of the elastic XY cross-slide written out in the notes
(``shared/reference/robotics-formalism.md`` §4, sympy Lagrange there).

Tolerances (error analysis, not one run's output):
- Feedback: ``qdd_e`` solves ``A_ee qdd_e = b`` by Cholesky, backward stable, so the residual of the
  elastic rows is ~ n eps (|b| + ||A_ee|| |qdd_e|); Newton–Euler adds rounding of a few hundred operations
  on terms no larger than those. With n <= 8 and eps = 2.2e-16 that is ~1e-14 of the scale
  S = max(|k q|, |h|, ||A_ee|| |qdd_e|); the bound 1e-12 S has a margin of ~100, and a wrong sign, a missing
  coupling block or a torque on the wrong joint is off by O(S).
- Against Pinocchio, accelerations: the error of A^-1 (...) is ~ cond(A) eps |qdd|; cond(A) < 1e4 on these
  models (masses 0.5-3 kg, lengths <= 1 m, IA <= 0.2): 1e-9 of the scale keeps a margin of 1e2..1e3. The
  elastic XY mixes 60-120 kg with IA 20-30 kg: cond(A) ~ 1e2.
- Torques against Pinocchio: both codes' rounding, ~1e-15 of the scale: 1e-9 as in the core's tests.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from sicomat.errors import ModelError
from sicomat.robotics import (MDHRobot, elastic_direct_dynamics, elastic_joints, hybrid_dynamics, inertia_matrix,
                              inverse_dynamics, rigid_joints)

from robotics_models import elastic_cross_slide_frames, pinocchio_model
from test_robotics_core import _random_table

PI = math.pi
FEEDBACK = 1e-12
REL = 1e-9


def _elastic_table(seed: int, tree: bool) -> list[dict]:
    """The core's random tables (about half the joints elastic, k 1e3..1e5) without dry friction on the
    elastic joints (the hybrid model refuses it)."""
    return [dict(row, FS=0.0) if row.get("eta") == 1 else row for row in _random_table(seed, tree)]


CASES = [(seed, tree) for seed in range(6) for tree in (False, True)]


def _states(robot: MDHRobot, seed: int, count: int):
    rng = np.random.default_rng(seed + 500)
    n, nr = robot.n_joints, len(rigid_joints(robot))
    return (rng.uniform(-PI, PI, (count, n)), rng.uniform(-2, 2, (count, n)), rng.uniform(-5, 5, (count, nr)))


def _friction(frames: list[dict], qd: np.ndarray, elastic_too: bool) -> np.ndarray:
    """FV qd + FS sign(qd) of the joints, by hand from the rows (Pinocchio has no friction)."""
    moving = [row for row in frames if row["sigma"] != 2]
    out = np.array([row.get("FV", 0.0) * v + row.get("FS", 0.0) * np.sign(v) for row, v in zip(moving, qd)])
    if not elastic_too:
        out[[i for i, row in enumerate(moving) if row.get("eta") == 1]] = 0.0
    return out


def test_the_cases_have_elastic_and_rigid_joints():
    robots = [MDHRobot.from_table(_elastic_table(seed, tree)) for seed, tree in CASES]
    assert sum(len(elastic_joints(r)) > 0 and len(rigid_joints(r)) > 0 for r in robots) >= 8
    assert sum(len(elastic_joints(r)) >= 2 for r in robots) >= 4       # a coupled A_ee block, not a scalar


@pytest.mark.parametrize("seed,tree", CASES)
def test_fed_back_the_accelerations_inverse_dynamics_returns_the_spring_torques(seed, tree):
    robot = MDHRobot.from_table(_elastic_table(seed, tree))
    e, r = elastic_joints(robot), rigid_joints(robot)
    rows = robot.joint_frames[e]
    k, fv = robot.k[rows], robot.chi[rows, 11]
    for q, qd, qdd_r in zip(*_states(robot, seed, 5)):
        result = hybrid_dynamics(robot, q, qd, qdd_r)
        np.testing.assert_array_equal(result.qdd[r], qdd_r)
        np.testing.assert_array_equal(result.qdd[e], result.qdd_elastic)
        np.testing.assert_array_equal(result.tau_elastic, -k * q[e] - fv * qd[e])     # Gamma_e
        tau = inverse_dynamics(robot, q, qd, result.qdd)
        a_ee = inertia_matrix(robot, q)[np.ix_(e, e)]
        h = inverse_dynamics(robot, q, qd, np.zeros(robot.n_joints))
        scale = max(1.0, np.max(np.abs(k * q[e]), initial=0), np.max(np.abs(h)),
                    np.linalg.norm(a_ee, 2) * np.max(np.abs(result.qdd_elastic), initial=0) if len(e) else 0.0)
        # our Newton–Euler adds the elastic joint's FV qd (its damping) like every joint's friction:
        # at an elastic joint it returns Gamma_e + FV qd_e = -k q_e
        np.testing.assert_allclose(tau[e], result.tau_elastic + fv * qd[e], rtol=0, atol=FEEDBACK * scale)
        np.testing.assert_allclose(tau[e], -k * q[e], rtol=0, atol=FEEDBACK * scale)
        np.testing.assert_array_equal(tau[r], result.tau_rigid)        # the same Newton–Euler call


@pytest.mark.parametrize("seed,tree", CASES)
def test_pinocchio_rnea_and_aba_agree_with_the_hybrid_model(seed, tree):
    frames = _elastic_table(seed, tree)
    robot = MDHRobot.from_table(frames)
    model, data = pinocchio_model(frames)
    model.armature = np.array([row.get("IA", 0.0) for row in frames if row["sigma"] != 2])
    for q, qd, qdd_r in zip(*_states(robot, seed, 5)):
        result = hybrid_dynamics(robot, q, qd, qdd_r)
        # Pinocchio has no friction: the rigid joints' friction comes off their torques; at the elastic
        # joints its torque is Gamma_e = -k q - FV qd itself
        tau_pin = result.tau - _friction(frames, qd, elastic_too=False)
        expected_tau = pin.rnea(model, data, q, qd, result.qdd)
        np.testing.assert_allclose(tau_pin, expected_tau, rtol=0, atol=REL * max(1.0, np.max(np.abs(expected_tau))))
        qdd = pin.aba(model, data, q, qd, tau_pin)
        np.testing.assert_allclose(result.qdd, qdd, rtol=0, atol=REL * max(1.0, np.max(np.abs(qdd))))
        # the full-state direct dynamics with the springs applied is the inverse of the hybrid model
        np.testing.assert_allclose(elastic_direct_dynamics(robot, q, qd, result.tau_rigid), qdd, rtol=0,
                                   atol=REL * max(1.0, np.max(np.abs(qdd))))


# --------------------------------------------------------------------------- the elastic XY of the notes §4
def _notes_inertia_matrix(frames: list[dict], q: np.ndarray) -> np.ndarray:
    """The notes' §4 symbolic A (sympy Lagrange there), y = q4 + q5, c, s = cos, sin q3."""
    p = lambda j, key: frames[j - 1].get(key, 0.0)  # noqa: E731
    m3, m5, mx3, my3, mx5 = p(3, "M"), p(5, "M"), p(3, "MX"), p(3, "MY"), p(5, "MX")
    y, c, s = q[3] + q[4], math.cos(q[2]), math.sin(q[2])
    a13 = -(m5 * y + my3) * c - (mx3 + mx5) * s
    return np.array([
        [p(1, "IA") + m3 + m5, m3 + m5, a13, -m5 * s, -m5 * s],
        [m3 + m5, m3 + m5, a13, -m5 * s, -m5 * s],
        [a13, a13, p(3, "ZZ") + p(5, "YY") + m5 * y ** 2, mx5, mx5],
        [-m5 * s, -m5 * s, mx5, p(4, "IA") + m5, m5],
        [-m5 * s, -m5 * s, mx5, m5, m5]])


def test_elastic_cross_slide_against_the_notes_closed_form():
    """At rest (qd = 0) gravity does no work on the XY (z0 vertical: X, Y horizontal, the yaw about z0), so
    h = 0 and the hybrid model is A_ee qdd_e = -K q_e - A_er qdd_r with the notes' A: X and Y motor
    accelerations, and the screw and yaw deflections, drive the carriage's yaw through M5 y and MX5."""
    frames = elastic_cross_slide_frames()
    robot = MDHRobot.from_table(frames)
    e, r = elastic_joints(robot), rigid_joints(robot)
    assert e.tolist() == [1, 2, 4] and r.tolist() == [0, 3]
    k = np.array([frames[j]["k"] for j in (1, 2, 4)])
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-2e-5, 2e-5), rng.uniform(-1e-4, 1e-4),
                      rng.uniform(-0.4, 0.4), rng.uniform(-2e-5, 2e-5)])      # deflections of a real machine
        qdd_r = rng.uniform(-5, 5, 2)
        a = _notes_inertia_matrix(frames, q)
        np.testing.assert_allclose(inertia_matrix(robot, q), a, rtol=0, atol=1e-12 * np.max(np.abs(a)))
        expected = np.linalg.solve(a[np.ix_(e, e)], -k * q[e] - a[np.ix_(e, r)] @ qdd_r)
        result = hybrid_dynamics(robot, q, np.zeros(5), qdd_r)
        # cond(A_ee) ~ 1e2 here (M5 = 60 kg against ZZ3 + YY5 + M5 y^2 ~ 50): 1e-12 of the scale
        np.testing.assert_allclose(result.qdd_elastic, expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))
        tau_r = a[np.ix_(r, r)] @ qdd_r + a[np.ix_(r, e)] @ result.qdd_elastic
        np.testing.assert_allclose(result.tau_rigid, tau_r, rtol=0, atol=1e-12 * np.max(np.abs(tau_r)))


def test_elastic_cross_slide_against_pinocchio_while_moving():
    frames = elastic_cross_slide_frames()
    robot = MDHRobot.from_table(frames)
    model, data = pinocchio_model(frames)
    model.armature = np.array([row.get("IA", 0.0) for row in frames if row["sigma"] != 2])
    rng = np.random.default_rng(8)
    for _ in range(5):
        q = rng.uniform(-0.5, 0.5, 5) * np.array([1, 1e-4, 1e-3, 1, 1e-4])
        qd = rng.uniform(-1, 1, 5) * np.array([1, 1e-2, 1e-1, 1, 1e-2])
        result = hybrid_dynamics(robot, q, qd, rng.uniform(-5, 5, 2))
        qdd = pin.aba(model, data, q, qd, result.tau)         # no friction in this table
        np.testing.assert_allclose(result.qdd, qdd, rtol=0, atol=REL * np.max(np.abs(qdd)))


# --------------------------------------------------------------------------- edge cases
def test_a_rigid_robot_has_no_elastic_part():
    frames = [dict(row, eta=0, k=0.0, mu=1) if row["sigma"] != 2 else row for row in _random_table(2, True)]
    robot = MDHRobot.from_table(frames)
    q, qd, qdd = (np.random.default_rng(1).uniform(-1, 1, robot.n_joints) for _ in range(3))
    result = hybrid_dynamics(robot, q, qd, qdd)
    assert result.qdd_elastic.shape == (0,) and result.tau_elastic.shape == (0,)
    np.testing.assert_array_equal(result.tau_rigid, inverse_dynamics(robot, q, qd, qdd))
    np.testing.assert_array_equal(result.qdd, qdd)
    np.testing.assert_allclose(elastic_direct_dynamics(robot, q, qd, result.tau_rigid), qdd, rtol=0, atol=1e-9 * 5)


def test_dry_friction_on_an_elastic_joint_is_refused():
    frames = elastic_cross_slide_frames()
    frames[2] = dict(frames[2], FS=3.0)
    robot = MDHRobot.from_table(frames)
    for call in (lambda: hybrid_dynamics(robot, np.zeros(5), np.zeros(5), np.zeros(2)),
                 lambda: elastic_direct_dynamics(robot, np.zeros(5), np.zeros(5), np.zeros(2))):
        with pytest.raises(ModelError, match="dry friction") as caught:
            call()
        assert caught.value.path == "frames[2].FS" and str(caught.value).startswith("frames[2].FS: frame 3:")


def test_bad_arguments_and_a_massless_elastic_joint():
    robot = MDHRobot.from_table(elastic_cross_slide_frames())
    with pytest.raises(ModelError, match="2 values") as caught:
        hybrid_dynamics(robot, np.zeros(5), np.zeros(5), np.zeros(5))
    assert caught.value.path == "qdd_rigid"
    with pytest.raises(ModelError, match="2 values"):
        elastic_direct_dynamics(robot, np.zeros(5), np.zeros(5), np.zeros(3))
    with pytest.raises(ModelError, match="5 joint values"):
        hybrid_dynamics(robot, np.zeros(4), np.zeros(5), np.zeros(2))
    with pytest.raises(ModelError, match="finite"):
        hybrid_dynamics(robot, np.zeros(5), np.zeros(5), [0.0, np.nan])
    # an elastic joint at the end of the chain that carries nothing: A_ee singular
    free = MDHRobot.from_table([{"ant": 0, "sigma": 1, "mu": 1, "M": 1.0}, {"ant": 1, "sigma": 1, "eta": 1, "k": 1.0}])
    with pytest.raises(ModelError, match="singular"):
        hybrid_dynamics(free, [0.0, 0.0], [0.0, 0.0], [1.0])


# --------------------------------------------------------------------------- stiffness columns (notes §2.6)
@pytest.mark.parametrize("seed,tree", CASES[:6])
def test_the_stiffness_columns_close_the_elastic_rows(seed, tree):
    """``Phi_ext chi_ext`` is Newton–Euler plus ``k q`` on the elastic rows: at the hybrid model's
    accelerations those rows are 0 (the elastic joints' equations, FEEDBACK bound of the module's
    analysis: Phi chi sums the same terms as Newton–Euler, in another order) and the rigid rows are the
    motor torques."""
    robot = MDHRobot.from_table(_elastic_table(seed, tree))
    e, r = elastic_joints(robot), rigid_joints(robot)
    chi = robot.standard_parameters(stiffness=True)
    assert len(chi) == 13 * robot.n_frames + len(e)
    names = robot.parameter_names(stiffness=True)
    assert names[13 * robot.n_frames:] == [f"K{row + 1}" for row in robot.joint_frames[e]]
    np.testing.assert_array_equal(chi[13 * robot.n_frames:], robot.k[robot.joint_frames[e]])
    for q, qd, qdd_r in zip(*_states(robot, seed, 4)):
        result = hybrid_dynamics(robot, q, qd, qdd_r)
        phi = robot.regressor(q, qd, result.qdd, stiffness=True)
        np.testing.assert_array_equal(phi[:, :13 * robot.n_frames], robot.regressor(q, qd, result.qdd))
        tau = phi @ chi
        h = inverse_dynamics(robot, q, qd, np.zeros(robot.n_joints))
        a = inertia_matrix(robot, q)
        scale = max(1.0, np.max(np.abs(h)),
                    np.max(np.abs(chi[13 * robot.n_frames:] * q[e]), initial=0),
                    np.linalg.norm(a, 2) * np.max(np.abs(result.qdd)))
        np.testing.assert_allclose(tau[e], 0.0, rtol=0, atol=FEEDBACK * scale)
        np.testing.assert_allclose(tau[r], result.tau_rigid, rtol=0, atol=FEEDBACK * scale)


def test_regressor_batch_with_stiffness():
    from sicomat.robotics import regressor_batch

    robot = MDHRobot.from_table(elastic_cross_slide_frames())
    q, qd, qdd = (np.random.default_rng(3).uniform(-1, 1, (4, 5)) for _ in range(3))
    phi = regressor_batch(robot, q, qd, qdd, stiffness=True)
    assert phi.shape == (4, 5, 13 * 6 + 3)
    # columns K2, K3, K5: q2, q3, q5 on their own rows, 0 elsewhere
    expected = np.zeros((4, 5, 3))
    for column, joint in enumerate((1, 2, 4)):
        expected[:, joint, column] = q[:, joint]
    np.testing.assert_array_equal(phi[:, :, 78:], expected)
    np.testing.assert_array_equal(phi[:, :, :78], regressor_batch(robot, q, qd, qdd))


def test_elastic_cross_slide_base_parameters_with_stiffness():
    """Counted by hand. Without stiffness the notes give 24 (test_robotics_base). At rest (qd = qdd = 0)
    every standard column of the elastic XY is zero: gravity (along -z0) does no work, the prismatic axes
    being x0 and y0 and the yaw axis z0, and the IA, FV, FS columns are qdd, qd, sign(qd). The stiffness
    columns are q2 e2, q3 e3, q5 e5, nonzero at rest on three different rows. A combination
    sum c_i Phi_i + sum kappa_j q_j e_j that vanishes at every state vanishes at rest, so every kappa_j = 0:
    the three K are independent of the 24 and of each other. 24 + 3 = 27, nothing regrouped into or out of
    them, and the 24 keep their relations (the K come last in the order of preference)."""
    robot = MDHRobot.from_table(elastic_cross_slide_frames())
    plain = robot.base_parameters()
    base = robot.base_parameters(stiffness=True)
    assert plain.count == 24 and base.count == 27
    assert base.names == plain.names + ("K2", "K3", "K5")
    assert base.labels[-3:] == ("K2", "K3", "K5")          # no R: nothing regrouped into them
    assert "K" not in "".join(base.dropped) and not any(name.startswith("K") for name in base.unidentifiable)
    np.testing.assert_allclose(base.beta[:24, :], plain.beta, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(base.values[-3:], [2e8, 5e7, 1.5e8])
    assert base.stiffness and base.n_standard == 81 and base.to_dict()["stiffness"] is True
    # the rigid-body inertial set gains the same three: 11 + 3
    assert robot.base_parameters(parameters="inertial", stiffness=True).count == \
        robot.base_parameters(parameters="inertial").count + 3


@pytest.mark.parametrize("seed,tree", CASES[:6])
def test_base_model_with_stiffness_reproduces_the_extended_torques(seed, tree):
    from sicomat.robotics import regressor_batch

    robot = MDHRobot.from_table(_elastic_table(seed, tree))
    base = robot.base_parameters(stiffness=True)
    e = elastic_joints(robot)
    # each K column is the only one linear in its own deflection on its own row (at rest a standard
    # column's row e is a gravity term: trigonometric in a revolute q_e, free of a prismatic one)
    assert base.count == robot.base_parameters().count + len(e)
    q, qd, qdd = (np.random.default_rng(seed + 9).uniform(-2, 2, (20, robot.n_joints)) for _ in range(3))
    phi = regressor_batch(robot, q, qd, qdd, stiffness=True)
    extended = phi @ robot.standard_parameters(stiffness=True)
    # base-parameter torques: rounding of a least-squares regrouping (~1e-13 of the scale), 1e-9 as in
    # test_robotics_base
    np.testing.assert_allclose(phi[:, :, base.indices] @ base.values, extended, rtol=0,
                               atol=REL * np.max(np.abs(extended)))
    with pytest.raises(ValueError, match="one stiffness per elastic joint"):
        base.regroup(np.zeros(13 * robot.n_frames))
