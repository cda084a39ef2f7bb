"""Closed loops with elastic joints and their linearisation (issue 13): the gantry example
(``examples/gantry.toml``: two ball-screw drives X1, X2, a cross beam pinned to carriage 1 and held by a pin
and a passive slide at carriage 2, a Y slide on the beam), the reduced gravity stiffness of a closed loop, and
the closed-loop lowering's refusals.

References, independent of the code under test:
- the gantry's kinematics written by hand from plane geometry: carriages at x_c1 = X1 + X1_screw (y = 0) and
  x_c2 = X2 + X2_screw (y = L); the beam pinned at (x_c1, 0) and reaching the pin at (x_c2, L), so its yaw is
  psi = atan((x_c1 - x_c2) / L) (positive about z0 turns the beam's direction u = (-sin psi, cos psi)), the
  slide's length sqrt(L^2 + (x_c1 - x_c2)^2), the pin's angle -psi; the beam's centre of mass at c u and the
  head at (Y + Y_screw) u from the pivot. Lagrange: T = 1/2 sum m |v|^2 + 1/2 J psi_dot^2 + the rotors
  1/2 IA q_dot^2, V = 1/2 sum k s^2 (gravity along -z0 does no work on this horizontal mechanism). At
  psi = 0 the inertia matrix is written out by hand; at a skew the body Jacobians are taken by complex
  step (exact to rounding) of those closed-form positions, never from the MDH table or the package;
- the parallelogram linkage of tests/test_robotics_loops.py, whose reduced potential is written there by
  hand: V(q1) = g ((MX1 + MX3 + M2 a) s1 + (MY1 + MY3) c1) + const;
- scipy's symmetric-definite eigensolver for the modes.

Tolerances (error analysis):
- Matrices: a few dozen operations on numbers of order 1..1e3 (kg, kg m^2, 1/m); the code's G comes from an
  SVD solve of a 6x3 loop Jacobian with singular values ~0.3..4 (lever arms of the 2 m machine) at a
  configuration closed to ~1e-16 m (Newton converges quadratically below the 1e-13 asked). Rounding ~1e-14 of
  the largest entry; REL = 1e-9 keeps a margin of ~1e5 while a wrong term (a missing beam share, the head's
  lever, a sign of the yaw) is off by O(1e-2..1) of the entry.
- The inverse dynamics at a skew: the bodies' accelerations by a five-point second difference along the
  motion q(t) = q + t qd + t^2 qdd / 2, h = 2e-3 s. Truncation O(h^4): measured 8.6e-6 N at h = 1e-2 s on forces
  of ~2e3 N, falling as h^4 (5.5e-7 at 5e-3), so ~1.4e-8 N at 2e-3; rounding ~(60/12) eps |p| / h^2 ~ 6e-10 m/s^2
  times masses <= 1e3 kg, ~6e-7 N. Both are below 1e-9 of the force scale; the bound 1e-8 keeps a margin of ~10
  while a wrong term (a missing centripetal acceleration of the beam, the passive joints' friction through G)
  is off by 1e-3..1 of it.
- Modes: eigh and the package's modal analysis each keep ~1e-12 relative (their documented contract): 1e-9.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from typer.testing import CliRunner

from sicomat.cli.main import app
from sicomat.errors import ModelError
from sicomat.io import load_model
from sicomat.robotics import (closed_loop_inertia_matrix, closed_loop_inverse_dynamics, closure_error,
                              independent_jacobian, independent_joints, inverse_dynamics, loop_states,
                              passive_joints, solve_closure)
from sicomat.robotics.lowering import (axis_mechanics, closed_configuration, gravity_stiffness, linearize,
                                       robot_mechanics, robot_model)

GANTRY = Path(__file__).resolve().parents[1] / "examples" / "gantry.toml"
REL = 1e-9
runner = CliRunner()
COORDS = ("X1", "X1_screw", "X2", "X2_screw", "Y", "Y_screw")     # the independent joints, joint order


def _parameters(spec) -> dict:
    """The example's numbers, read by frame name (the formulas below are the test's own)."""
    f = {frame.name: frame for frame in spec.frames}
    return dict(L=f["X2"].d, IA1=f["X1"].IA, IA2=f["X2"].IA, IAY=f["Y"].IA, m1=f["X1_screw"].M,
                m2=f["X2_screw"].M, mb=f["yaw"].M, c=f["yaw"].MY / f["yaw"].M,
                Jb=f["yaw"].ZZ - f["yaw"].MY ** 2 / f["yaw"].M, mh=f["Y_screw"].M, Jh=f["Y_screw"].YY,
                k=np.array([0.0, f["X1_screw"].k, 0.0, f["X2_screw"].k, 0.0, f["Y_screw"].k]),
                fv=np.array([f[n].FV for n in COORDS]), fs=np.array([f[n].FS for n in COORDS]),
                fv_yaw=f["yaw"].FV, fv_slide=f["slide"].FV, fv_pin=f["pin"].FV, fs_yaw=f["yaw"].FS,
                fs_slide=f["slide"].FS, fs_pin=f["pin"].FS)


# --------------------------------------------------------------------------- the closed form, aligned carriages
def _aligned_closed_form(p: dict, y: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, D, K at psi = 0 (x_c1 = x_c2), the head at y from the pivot, in (X1, s1, X2, s2, Y, sY).

    Velocities as rows over the coordinates: carriage 1 a = X1' + s1', carriage 2 b = X2' + s2', yaw
    psi' = (a - b)/L, beam centre x' = a - c psi', head x' = a - y psi' and y' = Y' + sY' (to first order).
    T = 1/2 [IA1 X1'^2 + IA2 X2'^2 + IAY Y'^2 + m1 a^2 + m2 b^2 + mb xb'^2 + mh (xh'^2 + yh'^2) + (Jb + Jh) psi'^2].
    Dissipation: each joint's FV times its rate squared: the yaw pin psi', the cut pin -psi', the slide 0 (its
    length L / cos psi moves at second order)."""
    e = np.eye(6)
    a, b = e[0] + e[1], e[2] + e[3]
    psi = (a - b) / p["L"]
    xb, xh, yh = a - p["c"] * psi, a - y * psi, e[4] + e[5]
    outer = np.outer
    M = (p["IA1"] * outer(e[0], e[0]) + p["IA2"] * outer(e[2], e[2]) + p["IAY"] * outer(e[4], e[4])
         + p["m1"] * outer(a, a) + p["m2"] * outer(b, b) + p["mb"] * outer(xb, xb)
         + p["mh"] * (outer(xh, xh) + outer(yh, yh)) + (p["Jb"] + p["Jh"]) * outer(psi, psi))
    D = np.diag(p["fv"]) + (p["fv_yaw"] + p["fv_pin"]) * outer(psi, psi)
    return M, D, np.diag(p["k"])


@pytest.mark.parametrize("x, y", [(0.0, 1.0), (0.35, 0.4), (-0.6, 1.7)])
def test_gantry_linear_model_is_the_lagrange_closed_form(x, y):
    machine = load_model(GANTRY)
    spec, p = machine.robot, _parameters(machine.robot)
    # carriages side by side at x; the passive joints' values are only the closure's start
    mech = robot_mechanics(spec, [x, 0.0, x, 0.0, 0.05, y, 0.0, 0.01, -0.04])
    assert mech.dof_names == COORDS
    M, D, K = _aligned_closed_form(p, y)
    np.testing.assert_allclose(mech.mass, M, rtol=0, atol=REL * np.abs(M).max())
    np.testing.assert_allclose(mech.damping, D, rtol=0, atol=REL * np.abs(D).max())
    # the screws' springs on their own coordinates; no gravity stiffness (horizontal mechanism)
    np.testing.assert_allclose(mech.stiffness, K, rtol=0, atol=REL * np.abs(K).max())
    assert [c.name for c in mech.couplings] == ["X1_screw", "X2_screw", "Y_screw"]
    assert [a.name for a in mech.actuators] == ["X1", "X2", "Y"]
    sensors = {s.name: s.vector for s in mech.sensors}
    psi = (np.array([1, 1, -1, -1, 0, 0]) / p["L"])
    np.testing.assert_allclose(sensors["yaw"], psi, rtol=0, atol=REL)
    np.testing.assert_allclose(sensors["pin"], -psi, rtol=0, atol=REL)
    np.testing.assert_array_equal(sensors["X1_load"], [1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(sensors["Y_load"], [0, 0, 0, 0, 1, 1])
    assert "slide" not in sensors          # it moves at second order only: nothing to read in the linear model
    frictions = {f.name: f for f in mech.frictions}
    assert set(frictions) == {"X1_friction", "X2_friction", "Y_friction", "yaw_friction", "pin_friction"}
    np.testing.assert_allclose(frictions["yaw_friction"].g, psi, rtol=0, atol=REL)


def test_the_servo_model_of_one_gantry_drive_locks_the_other_and_its_rigid_mass_is_the_closed_form():
    """Axis X1's decoupled model: X2 and Y locked (held by their loops), every elastic joint free. Its rigid
    motion moves X1 with carriage 1 while carriage 2 stays: a = X1', b = 0, so the rigid mass is
    IA1 + m1 + mb (1 - c/L)^2 + mh (1 - y/L)^2 + (Jb + Jh) / L^2 — the beam pivoting about carriage 2's pin."""
    from sicomat.servo.loop import build_servo_loop

    machine = load_model(GANTRY)
    p = _parameters(machine.robot)
    mech = axis_mechanics(machine, "X1")
    assert mech.dof_names == ("X1", "X1_screw", "X2_screw", "Y_screw")
    assert [a.name for a in mech.actuators] == ["X1"]
    y, L = 1.0, p["L"]
    expected = (p["IA1"] + p["m1"] + p["mb"] * (1 - p["c"] / L) ** 2 + p["mh"] * (1 - y / L) ** 2
                + (p["Jb"] + p["Jh"]) / L ** 2)
    loop = build_servo_loop(machine, "X1")
    assert loop.m_rigid == pytest.approx(expected, rel=1e-12)
    np.testing.assert_array_equal(loop.tool, [1.0, 1.0, 0.0, 0.0])


# --------------------------------------------------------------------------- the closed form at a skew
def _bodies(p: dict, qi):
    """Closed-form positions of the gantry's bodies (x, y) and its passive joints, from the independent
    coordinates (complex values allowed: complex-step derivatives)."""
    L, c = p["L"], p["c"]
    xc1, xc2, y = qi[0] + qi[1], qi[2] + qi[3], qi[4] + qi[5]
    psi = np.arctan((xc1 - xc2) / L)
    s, co = np.sin(psi), np.cos(psi)
    return {"c1": (xc1, 0.0 * xc1), "c2": (xc2, L + 0.0 * xc2), "beam": (xc1 - c * s, c * co),
            "head": (xc1 - y * s, y * co)}, {"yaw": psi, "slide": np.sqrt(L ** 2 + (xc1 - xc2) ** 2) - L,
                                               "pin": -psi}


def _gradients(p: dict, qi: np.ndarray) -> tuple[dict, dict]:
    """d/dq_i of every closed-form position and passive joint by complex step (h = 1e-30: exact to rounding)."""
    bodies = {name: np.zeros((2, 6)) for name in ("c1", "c2", "beam", "head")}
    joints = {name: np.zeros(6) for name in ("yaw", "slide", "pin")}
    for i in range(6):
        z = qi.astype(complex)
        z[i] += 1e-30j
        pos, passive = _bodies(p, z)
        for name in bodies:
            bodies[name][:, i] = np.imag(np.array(pos[name])) / 1e-30
        for name in joints:
            joints[name][i] = np.imag(passive[name]) / 1e-30
    return bodies, joints


def _skew_closed_form(p: dict, qi: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """M and D anywhere: T = 1/2 qd^T M qd with M = sum m J^T J + (Jb + Jh) grad(psi) grad(psi)^T + rotors."""
    jac, grad = _gradients(p, qi)
    masses = {"c1": p["m1"], "c2": p["m2"], "beam": p["mb"], "head": p["mh"]}
    M = sum(m * jac[b].T @ jac[b] for b, m in masses.items()) + (p["Jb"] + p["Jh"]) * np.outer(grad["yaw"],
                                                                                              grad["yaw"])
    M = M + np.diag([p["IA1"], 0, p["IA2"], 0, p["IAY"], 0])
    D = np.diag(p["fv"]) + sum(p[f"fv_{j}"] * np.outer(grad[j], grad[j]) for j in ("yaw", "slide", "pin"))
    return M, D, grad


def test_gantry_at_a_skew_against_lagrange_from_plane_geometry():
    """Carriages 0.3 m apart over the 2 m span (psi = 8.5 deg, far beyond any real skew, to exercise G), with
    a Coulomb friction on the passive slide: the closure found from a rough start, M and D against the
    closed form, and the slide's friction acting on its sliding velocity, the closed form's grad(slide)."""
    machine = load_model(GANTRY, ["robot.frames.7.FS=40 N"])
    spec, p = machine.robot, _parameters(machine.robot)
    qi = np.array([0.2, 1e-5, -0.1, -2e-5, 0.7, 1e-5])
    start = [qi[0], qi[1], qi[2], qi[3], 0.0, qi[4], qi[5], 0.0, 0.0]
    q = closed_configuration(spec, start)
    _, passive = _bodies(p, qi)
    # closed to ~1e-16 m: the passive joints to ~1e-15 (levers of 2 m); 1e-12 is a bound with margin
    np.testing.assert_allclose(q[[4, 7, 8]], [passive["yaw"], passive["slide"], passive["pin"]], rtol=0, atol=1e-12)
    mech = robot_mechanics(spec, start)
    M, D, grad = _skew_closed_form(p, qi)
    np.testing.assert_allclose(mech.mass, M, rtol=0, atol=REL * np.abs(M).max())
    np.testing.assert_allclose(mech.damping, D, rtol=0, atol=REL * np.abs(D).max())
    frictions = {f.name: f for f in mech.frictions}
    slide = frictions["slide_friction"]
    assert (slide.coulomb, slide.static, slide.damping, slide.kind) == (40.0, 40.0, p["fv_slide"], "translational")
    np.testing.assert_allclose(slide.g, grad["slide"], rtol=0, atol=REL)
    assert np.abs(grad["slide"]).max() > 0.1          # a real sliding velocity at this skew, not rounding
    sensors = {s.name: s.vector for s in mech.sensors}
    np.testing.assert_allclose(sensors["slide"], grad["slide"], rtol=0, atol=REL)
    # aligned, the slide does not move to first order: no friction link, no sensor
    aligned = robot_mechanics(spec)
    assert "slide_friction" not in {f.name for f in aligned.frictions}


def test_coulomb_friction_of_a_passive_joint_acts_on_its_sliding_in_simulation():
    """A dry friction of 30 N m in the beam's yaw pin (passive). Axis X1 moves 20 mm with X2 locked, so the beam
    yaws about carriage 2 and the pin slides: the simulator's friction on the link whose vector is the pin's
    row of G (its rate is psi' = (x_c1' - x_c2') / L) is -FS sign(psi') wherever the pin slides, and never
    more than FS (stick–slip: the friction of a joint, not of a coordinate)."""
    from sicomat import simulate
    from sicomat.motion.setpoints import trapezoid_profile
    from sicomat.servo.loop import build_servo_loop

    machine = load_model(GANTRY, ["robot.frames.4.FS=30 N*m"])
    loop = build_servo_loop(machine, "X1")
    link = {f.name: f for f in loop.mechanics.frictions}["yaw_friction"]
    L = machine.robot.frames[2].d
    np.testing.assert_allclose(link.g, np.array([1.0, 1.0, -1.0, 0.0]) / L, rtol=0, atol=REL)   # X1, s1, s2, sY
    run = simulate(loop, trapezoid_profile(0.02, 0.3, 3.0), 0.3)
    rate = sum(g * run.signals[dof.velocity] for g, dof in zip(link.g, loop.mechanics.dofs))
    force = run.signals["friction.yaw_friction"]
    assert np.abs(force).max() <= 30.0 * (1 + 1e-12)
    sliding = np.abs(rate) > 1e-3 * np.abs(rate).max()
    assert sliding.sum() > 100                               # the move's ramps and cruise
    np.testing.assert_allclose(force[sliding], -30.0 * np.sign(rate[sliding]), rtol=1e-12)


def test_closed_loop_inverse_dynamics_with_elastic_joints_against_dalembert():
    """At random skewed states with every coordinate moving: the generalised forces on the six independent
    joints (motors and screw deflections) against virtual work on the closed-form kinematics,
        Gamma = sum_b m_b J_b^T a_b + (Jb + Jh) grad(psi) psi'' + IA q''_motor
                + sum_j grad(q_j) (FV_j q_j' + FS_j sign(q_j')),
    with a_b, psi'' the second derivatives along q(t) = q + t qd + t^2 qdd / 2 (five points). The code takes
    Newton–Euler on the tree and G^T."""
    machine = load_model(GANTRY, ["robot.frames.7.FS=40 N", "robot.frames.4.FS=30 N*m"])
    spec, p = machine.robot, _parameters(machine.robot)
    robot = robot_model(spec)
    assert [spec.joint_names[j] for j in independent_joints(robot)] == list(COORDS)
    assert [spec.joint_names[j] for j in passive_joints(robot)] == ["yaw", "slide", "pin"]
    masses = {"c1": p["m1"], "c2": p["m2"], "beam": p["mb"], "head": p["mh"]}
    rng = np.random.default_rng(7)
    for _ in range(4):
        qi = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-1e-4, 1e-4), 0.0, rng.uniform(-1e-4, 1e-4),
                       rng.uniform(0.2, 1.8), rng.uniform(-1e-4, 1e-4)])
        qi[2] = qi[0] + rng.uniform(-0.2, 0.2)
        qd_i, qdd_i = rng.uniform(-0.5, 0.5, 6), rng.uniform(-3, 3, 6)
        q = solve_closure(robot, qi, np.r_[qi[:4], 0.0, qi[4:], 0.0, 0.0], tol=1e-14)
        qd, qdd = loop_states(robot, q, qd_i, qdd_i)
        gamma = closed_loop_inverse_dynamics(robot, q, qd, qdd)

        h = 2e-3
        path = [qi + t * qd_i + 0.5 * t * t * qdd_i for t in (-2 * h, -h, 0.0, h, 2 * h)]
        states = [_bodies(p, x) for x in path]

        def second(values):
            v = np.array(values, dtype=float)
            return (-v[0] + 16 * v[1] - 30 * v[2] + 16 * v[3] - v[4]) / (12 * h * h)

        jac, grad = _gradients(p, qi)
        expected = np.array([p["IA1"], 0, p["IA2"], 0, p["IAY"], 0]) * qdd_i
        for body, m in masses.items():
            expected += m * jac[body].T @ second([np.array(s[0][body], dtype=float) for s in states])
        expected += (p["Jb"] + p["Jh"]) * grad["yaw"] * second([s[1]["yaw"] for s in states])
        expected += p["fv"] * qd_i + p["fs"] * np.sign(qd_i)
        for j in ("yaw", "slide", "pin"):
            rate = grad[j] @ qd_i
            expected += grad[j] * (p[f"fv_{j}"] * rate + p[f"fs_{j}"] * np.sign(rate))
        np.testing.assert_allclose(gamma, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
        # the inertia matrix in the independent joints is the closed form's, and virtual work holds
        M, _, _ = _skew_closed_form(p, qi)
        np.testing.assert_allclose(closed_loop_inertia_matrix(robot, q), M, rtol=0, atol=REL * np.abs(M).max())
        tree = inverse_dynamics(robot, q, qd, qdd)
        assert abs(gamma @ qd_i - tree @ qd) <= 1e-12 * np.abs(tree).max() * np.abs(qd).max() * len(qd)
        np.testing.assert_allclose(independent_jacobian(robot, q) @ qd_i, qd, rtol=0, atol=1e-14)


# --------------------------------------------------------------------------- modes, from the command line
@pytest.mark.parametrize("q, qi", [(None, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
                                   ("0.1,0,0.1,0,0,400mm,0,0,0", [0.1, 0.0, 0.1, 0.0, 0.4, 0.0]),
                                   ("0.25,0,0.05,0,0,1.5,0,0,0", [0.25, 0.0, 0.05, 0.0, 1.5, 0.0])])
def test_modal_of_the_gantry_with_its_motors_locked_is_eigh_of_the_closed_form(q, qi):
    """Motors locked (X1, X2, Y): the screws' deflections (s1, s2, sY) remain; the modes are those of the
    closed form's block, from scipy's eigh (the last case is skewed: the closed form's M by complex step)."""
    args = ["modal", str(GANTRY), "--json"] + ([] if q is None else ["--q", q])
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    p = _parameters(load_model(GANTRY).robot)
    qi = np.array(qi)
    M, _, _ = _skew_closed_form(p, qi)
    free = [1, 3, 5]
    expected = np.sqrt(scipy.linalg.eigh(np.diag(p["k"])[np.ix_(free, free)], M[np.ix_(free, free)],
                                         eigvals_only=True)) / (2 * math.pi)
    assert payload["dofs"] == ["X1_screw", "X2_screw", "Y_screw"] and payload["locked"] == ["X1", "X2", "Y"]
    np.testing.assert_allclose(payload["undamped_hz"], expected, rtol=1e-9)
    # the configuration reported is the closed one: yaw = atan((x_c1 - x_c2) / L)
    assert payload["configuration"]["yaw"] == pytest.approx(math.atan((qi[0] - qi[2]) / p["L"]), abs=1e-12)


def test_the_gantry_runs_through_check_margins_and_simulate():
    for args in (["check", str(GANTRY), "--json"], ["margins", str(GANTRY), "--axis", "X1", "--json"],
                 ["simulate", str(GANTRY), "--axis", "X1", "--move", "20", "--json"]):
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (args, result.output)
    margins = json.loads(runner.invoke(app, ["margins", str(GANTRY), "--axis", "X2", "--json"]).stdout)
    assert margins["stable"] is True


def test_coupled_servo_loops_of_the_gantry_move_both_drives_alike():
    """Every motor free (the coupled model): three rigid modes (X together, the skew, Y), and with the head at
    mid-span the gantry is symmetric, so X1 and X2 given the same setpoint follow it alike and the beam does
    not yaw (to rounding: 1e-9 of the move, the run's floating-point noise on a 20 mm move is ~1e-16 m)."""
    from sicomat.motion.setpoints import step_profile, trapezoid_profile
    from sicomat.servo.coupled import robot_coupled_loop
    from sicomat.simulation.coupled import simulate_coupled

    machine = load_model(GANTRY)
    coupled = robot_coupled_loop(machine)
    assert coupled.mechanics.dof_names == COORDS and coupled.axes == ("X1", "X2", "Y")
    assert coupled.mechanics.rigid_modes().shape == (6, 3)
    move = trapezoid_profile(0.02, 0.3, 3.0)
    run = simulate_coupled(coupled, {"X1": move, "X2": move, "Y": step_profile(0.0)}, 0.15, nonlinear=False)
    x1, x2 = run.axes["X1"], run.axes["X2"]
    x1, x2 = x1.signals, x2.signals
    np.testing.assert_allclose(x1["sensor.X1_load"], x2["sensor.X2_load"], rtol=0, atol=1e-9 * 0.02)
    assert np.abs(x1["sensor.yaw"]).max() <= 1e-9 * 0.02 / 2.0
    assert np.abs(x1["sensor.X1_load"]).max() > 0.01          # it did move


# --------------------------------------------------------------------------- reduced gravity stiffness
def test_gravity_stiffness_of_a_closed_loop_is_the_hessian_of_its_reduced_potential():
    """The parallelogram of tests/test_robotics_loops.py, gravity -g y0 in its plane: the reduced potential
    V(q1) = g ((MX1 + MX3 + M2 a) s1 + (MY1 + MY3) c1) (the coupler translates) has the stiffness
    K = -g ((MX1 + MX3 + M2 a) s1 + (MY1 + MY3) c1). Central differences with Richardson on configurations
    closed by Newton: ~1e-12 of g M a (the tree's error analysis), bound 1e-9. The linear model's M and D are
    the closed form's too (every joint turns at |dq_j/dq1| = 1)."""
    from test_robotics_loops import A_CRANK, G0, PARALLELOGRAM_LINKS, _parallelogram

    robot = _parallelogram()
    links = PARALLELOGRAM_LINKS
    mx = links[1]["MX"] + links[3]["MX"] + links[2]["M"] * A_CRANK
    my = links[1]["MY"] + links[3]["MY"]
    inertia = links[1]["ZZ"] + links[3]["ZZ"] + links[2]["M"] * A_CRANK ** 2 + links[1]["IA"] + links[3]["IA"]
    for q1 in (-2.0, -0.7, 0.4, 1.3, 2.6):
        q = solve_closure(robot, [q1], [q1 + 0.05, -q1 - 0.05, q1 - 0.05, -q1 + 0.05], tol=1e-14)
        expected = -G0 * (mx * math.sin(q1) + my * math.cos(q1))
        np.testing.assert_allclose(gravity_stiffness(robot, q), [[expected]], rtol=0, atol=1e-9 * G0 * mx)
        lin = linearize(robot, q)
        assert lin.coordinates.tolist() == [0]
        np.testing.assert_allclose(lin.stiffness, [[expected]], rtol=0, atol=1e-9 * G0 * mx)
        np.testing.assert_allclose(lin.mass, [[inertia]], rtol=0, atol=REL * inertia)
        np.testing.assert_allclose(lin.damping, [[sum(links[j]["FV"] for j in (1, 2, 3, 4))]], rtol=0, atol=REL)
        np.testing.assert_allclose(lin.jacobian[:, 0], [1.0, -1.0, 1.0, -1.0], rtol=0, atol=1e-11)
        assert np.abs(closure_error(robot, lin.q)).max() <= 1e-14 * 3


# --------------------------------------------------------------------------- what cannot close
FOUR_BAR_THAT_CANNOT_REACH = """
[robot]
gravity = [0, 0, -9.81]
links = 3
configuration = ["{crank}", "60 deg", "100 deg", "-30 deg"]

[[robot.frames]]
name = "crank"
ant = 0
sigma = 0
mu = 1
IA = 0.1
M = 1.0
MX = 0.4
XX = 0.01
YY = 0.2
ZZ = 0.2

[[robot.frames]]
name = "coupler"
ant = 1
sigma = 0
d = 0.8

[[robot.frames]]
name = "rocker"
ant = 0
sigma = 0
d = 1.0

[[robot.frames]]
name = "cut"
ant = 3
sigma = 0
d = 0.3

[[robot.frames]]
ant = 2
sigma = 2
d = 0.3
"""


def test_a_closed_loop_that_cannot_close_is_one_clear_error(tmp_path):
    """A four-bar whose coupler and rocker (0.3 m each) cannot span the crank's tip to the rocker's pivot
    beyond 0.6 m: with the crank at 180 deg the tip is 1.8 m away. One ModelError at robot.configuration,
    exit status 2 from the CLI, no traceback; at 80 deg (1.14 m: still out of reach) the same."""
    for crank in ("180 deg", "80 deg"):
        model = tmp_path / "four_bar.toml"
        model.write_text(FOUR_BAR_THAT_CANNOT_REACH.replace("{crank}", crank))
        machine = load_model(model)
        with pytest.raises(ModelError) as caught:
            robot_mechanics(machine.robot)
        assert caught.value.path == "robot.configuration"
        assert "cannot be closed" in str(caught.value)
        for command in (["check", str(model)], ["modal", str(model)]):
            result = runner.invoke(app, command)
            assert result.exit_code == 2, result.output
            assert "robot.configuration" in result.output and "cannot be closed" in result.output
            assert "Traceback" not in result.output and str(model) in result.output
    # reachable (crank at 0 deg: the tip 0.2 m from the rocker's pivot): it closes; with its motor locked the
    # four-bar has no joint of its own left (the passive ones follow the closure), which modal says plainly
    model.write_text(FOUR_BAR_THAT_CANNOT_REACH.replace("{crank}", "0 deg"))
    spec = load_model(model).robot
    q = closed_configuration(spec)
    # Newton stops below 1e-13 of the size (2.4 m here)
    assert np.abs(closure_error(robot_model(spec), q)).max() <= 1e-13 * 2.4
    result = runner.invoke(app, ["modal", str(model)])
    assert result.exit_code == 2 and "no joint left once its motors are locked" in result.output, result.output
