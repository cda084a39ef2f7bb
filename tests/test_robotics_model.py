"""A machine described by the robotics formalism in the model file (issue 13): the ``[robot]`` section, its
lowering into the Mechanics every analysis consumes, and the commands that read it.

References, independent of the code under test: the elastic XY cross-slide's inertia matrix written out
by Lagrange in the working notes (shared/reference/robotics-formalism.md §4); a pendulum's gravity
stiffness by hand; the same single axis written as lumped masses and springs (the existing, separately
tested lumped builder) — the MDH/lumped equivalence; scipy's symmetric eigensolver for the modes.

Tolerances: the matrices are a few dozen operations on numbers of order 1..1e3 (M) or 1e8 (K), so their
rounding is ~1e-15 relative; the eigen-solvers and the frequency-response engine add ~1e-12 relative
(their own documented contracts). 1e-10 leaves a margin of 100 over that and still catches any wrong
term (a missing mass, a sign, an inertia about the wrong point changes entries by O(1) of their size).
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
from sicomat.io import load_model, machine_from_dict
from sicomat.robotics.lowering import axis_mechanics, gravity_stiffness, linearize, robot_mechanics, robot_model

from robotics_models import xy_inertia_by_lagrange as _xy_inertia_by_lagrange  # the notes' §4 closed form, shared

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
XY = EXAMPLES / "xy_elastic.toml"
runner = CliRunner()
REL = 1e-10


def run(*args: str):
    return runner.invoke(app, list(args))


# --------------------------------------------------------------------------- the elastic XY example
@pytest.mark.parametrize("q", [[0.0, 0.0, 0.0, 0.15, 0.0], [0.3, 1e-5, 0.02, -0.2, 2e-5], [-0.5, 0.0, -0.7, 0.4, 0.0]])
def test_xy_example_linear_model_is_the_notes_closed_form(q):
    machine = load_model(XY)
    mech = robot_mechanics(machine.robot, q)
    assert mech.dof_names == ("X", "X_screw", "yaw", "Y", "Y_screw")
    expected = _xy_inertia_by_lagrange(machine.robot, q)
    np.testing.assert_allclose(mech.mass, expected, rtol=0, atol=REL * np.abs(expected).max())
    # gravity along z0 does no work on horizontal slides and a yaw about z0: no gravity stiffness
    np.testing.assert_array_equal(np.diag(mech.stiffness), [0.0, 1.8e8, 4e7, 0.0, 1.2e8])
    assert [c.name for c in mech.couplings] == ["X_screw", "yaw", "Y_screw"]
    np.testing.assert_array_equal(np.diag(mech.damping), [300.0, 6000.0, 2000.0, 200.0, 4000.0])
    assert [(f.name, f.coulomb) for f in mech.frictions] == [("X_friction", 120.0), ("Y_friction", 80.0)]
    assert [a.name for a in mech.actuators] == ["X", "Y"]


def test_modal_q_locks_the_motors_and_matches_eigh_of_the_closed_form():
    machine = load_model(XY)
    q = [0.1, 0.0, 0.0, 0.35, 0.0]
    result = run("modal", str(XY), "--q", ",".join(str(v) for v in q), "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["locked"] == ["X", "Y"] and payload["configuration"]["Y"] == 0.35
    A = _xy_inertia_by_lagrange(machine.robot, q)
    free = [1, 2, 4]                                   # the elastic joints: X_screw, yaw, Y_screw
    K = np.diag([1.8e8, 4e7, 1.2e8])
    expected = np.sqrt(scipy.linalg.eigh(K, A[np.ix_(free, free)], eigvals_only=True)) / (2 * math.pi)
    np.testing.assert_allclose(payload["undamped_hz"], expected, rtol=1e-9)
    # the yaw mode moves with Y (its inertia grows as M5 y^2): the coupling the issue asks to see
    far = json.loads(run("modal", str(XY), "--q", "0.1,0,0,-0.35,0", "--json").stdout)
    near = json.loads(run("modal", str(XY), "--q", "0.1,0,0,0.0,0", "--json").stdout)
    assert far["undamped_hz"][2] < near["undamped_hz"][2] - 1.0


def test_modal_q_takes_units_and_rejects_a_wrong_count():
    with_units = run("modal", str(XY), "--q", "100mm,0,0deg,350mm,0", "--json")
    assert with_units.exit_code == 0, with_units.output
    assert json.loads(with_units.stdout)["configuration"]["X"] == pytest.approx(0.1, rel=1e-15)
    short = run("modal", str(XY), "--q", "0,0,0,0.4")
    assert short.exit_code == 2 and "--q" in short.output and "expected 5 values" in short.output
    assert "Traceback" not in short.output


def test_robot_axes_are_the_motorised_joints_and_get_servo_loops():
    machine = load_model(XY)
    assert list(machine.axes) == ["X", "Y"] and machine.axes["X"].mechanics is None
    mech = axis_mechanics(machine, "X")
    # the other motor (Y) is locked, every elastic joint stays free
    assert mech.dof_names == ("X", "X_screw", "yaw", "Y_screw")
    assert [a.name for a in mech.actuators] == ["X"]
    from sicomat.servo.loop import build_servo_loop

    loop = build_servo_loop(machine, "X")
    # the tool of X is its load side (motor + screw deflection); the rigid mass is everything X carries
    np.testing.assert_array_equal(loop.tool, [1.0, 1.0, 0.0, 0.0])
    f = {frame.name: frame for frame in machine.robot.frames}
    assert loop.m_rigid == pytest.approx(f["X"].IA + f["yaw"].M + f["Y_screw"].M, rel=1e-12)


def test_a_model_file_with_only_a_robot_section_is_valid():
    machine = machine_from_dict({"robot": {"frames": [
        {"ant": 0, "sigma": 1, "mu": 1, "IA": "2 kg"},
        {"ant": 1, "sigma": 1, "eta": 1, "k": "1e6 N/m", "M": "3 kg"}]}})
    assert list(machine.axes) == ["q1"]
    assert machine.robot.default_sensors().keys() == {"q1", "q2", "q1_load"}


# --------------------------------------------------------------------------- MDH = lumped
def _single_axis(IA=90.0, M=350.0, k=1.8e8, c=6000.0, fv=300.0, fs=120.0):
    common = {
        "drive": {"type": "first-order", "force_constant": "942.5 N/A", "bandwidth": "1500 Hz"},
        "controller": {"type": "P-PI", "Kv": 50, "Kp_normalized": 150, "Ti": "6 ms", "velocity_period": "125 us",
                       "position_period": "1 ms"}}
    robot = machine_from_dict({"robot": {"gravity": [0, 0, -9.81], "frames": [
        {"name": "X", "ant": 0, "sigma": 1, "mu": 1, "gamma": "90 deg", "alpha": "90 deg", "IA": IA, "FV": fv, "FS": fs},
        {"name": "screw", "ant": 1, "sigma": 1, "eta": 1, "k": k, "FV": c, "M": M}]},
        "axes": {"X": {**common, "controller": {**common["controller"], "position_sensor": "X_load",
                                                "velocity_sensor": "X"}}}})
    lumped = machine_from_dict({"axes": {"X": {
        "mechanics": {"type": "lumped", "bodies": {"motor": {"mass": IA}, "table": {"mass": M}},
                      "couplings": {"screw": {"between": ["motor", "table"], "stiffness": k, "damping": c}},
                      "frictions": {"guides": {"between": ["motor", "ground"], "viscous": fv, "coulomb": fs}},
                      "actuators": {"motor": {"body": "motor"}},
                      "sensors": {"encoder": {"body": "motor"}, "scale": {"body": "table"}}},
        "tool": "table", **common,
        "controller": {**common["controller"], "position_sensor": "scale", "velocity_sensor": "encoder"}}}})
    return robot, lumped


def test_a_single_axis_by_mdh_is_the_same_lumped_model():
    robot, lumped = _single_axis()
    mr, ml = axis_mechanics(robot, "X"), axis_mechanics(lumped, "X")
    # joint coordinates (motor, screw deflection) = T @ absolute ones (motor, table) with T = [[1, 0], [-1, 1]];
    # the lumped model in joint coordinates: M_j = T^-T M T^-1 with T^-1 = [[1, 0], [1, 1]]
    Tinv = np.array([[1.0, 0.0], [1.0, 1.0]])
    for name in ("mass", "damping", "stiffness"):
        expected = Tinv.T @ getattr(ml, name) @ Tinv
        np.testing.assert_allclose(getattr(mr, name), expected, rtol=0, atol=1e-14 * np.abs(expected).max())
    np.testing.assert_allclose(mr.modes().undamped_hz, ml.modes().undamped_hz, rtol=1e-12)
    # the same servo loop: margins of both loops agree to the frequency engine's accuracy
    from sicomat.frequency.loops import LoopAnalysis
    from sicomat.frequency.margins import stability_margins
    from sicomat.servo.loop import build_servo_loop

    la, lb = build_servo_loop(robot, "X"), build_servo_loop(lumped, "X")
    assert la.m_rigid == pytest.approx(lb.m_rigid, rel=1e-14)
    for which in ("velocity-open", "position-open"):
        a = stability_margins(LoopAnalysis.of(la).response(which))
        b = stability_margins(LoopAnalysis.of(lb).response(which))
        for key in ("phase_margin_deg", "gain_margin_db", "gain_crossover_rad_s", "modulus_margin"):
            np.testing.assert_allclose(getattr(a, key), getattr(b, key), rtol=1e-9)


# --------------------------------------------------------------------------- gravity stiffness
def test_gravity_stiffness_of_a_pendulum_by_hand():
    m, l, g0, k = 3.0, 0.4, 9.81, 500.0
    # joint 1 turns about z0, which is horizontal for gravity along -y0: V = m g0 l sin(q), K_g = -m g0 l sin(q)
    robot = machine_from_dict({"robot": {"gravity": [0.0, -g0, 0.0], "frames": [
        {"ant": 0, "sigma": 0, "mu": 1, "IA": 0.1},
        {"ant": 1, "sigma": 0, "eta": 1, "k": k, "M": m, "MX": m * l, "ZZ": m * l * l + 0.01, "YY": m * l * l,
         "XX": 0.01}]}}).robot
    model = robot_model(robot)
    for q1 in (-1.2, 0.0, 0.4, 1.5):
        q = np.array([q1, 0.0])
        kg = gravity_stiffness(model, q)
        np.testing.assert_allclose(kg, -m * g0 * l * math.sin(q1) * np.ones((2, 2)), rtol=0, atol=1e-9 * m * g0 * l)
        lin = linearize(model, q)
        np.testing.assert_allclose(lin.stiffness, kg + np.diag([0.0, k]), rtol=0, atol=1e-9 * k)
    # hanging upside down beyond what the spring holds: refused, not a plausible unstable model
    weak = robot.model_copy(update={"frames": [robot.frames[0], robot.frames[1].model_copy(update={"k": 5.0})]})
    with pytest.raises(ModelError, match="negative stiffness"):
        robot_mechanics(weak, [math.pi / 2, 0.0], free=["q2"])


# --------------------------------------------------------------------------- bad tables, from the file
GOOD_ROWS = ['{ ant = 0, sigma = 1, mu = 1, IA = "2 kg" }',
             '{ ant = 1, sigma = 1, eta = 1, k = "1e6 N/m", M = "3 kg", XX = 0.1, YY = 0.1, ZZ = 0.1 }']


@pytest.mark.parametrize("row, field, words", [
    ('{ ant = 3, sigma = 1, M = 1 }', "robot.frames.2.ant", "antecedent must be a frame before frame 3"),
    ('{ ant = 2, sigma = 3 }', "robot.frames.2.sigma", "sigma must be 0 (revolute), 1 (prismatic) or 2"),
    ('{ ant = 2, sigma = 0, eta = 1, mu = 1, k = 10 }', "robot.frames.2.mu", "cannot be motorised"),
    ('{ ant = 2, sigma = 0, M = 1, MX = 1, XX = 0.1, YY = 0.1, ZZ = 0.1 }', "robot.frames.2.XX..ZZ",
     "not positive semi-definite"),
    ('{ ant = 2, sigma = 1, eta = 1, k = "1e6 N*m/rad" }', "robot.frames.2.k", "linear stiffness"),
    ('{ ant = 2, sigma = 1, mass = 3 }', "robot.frames.2.mass", "unknown key"),
])
def test_bad_tables_name_file_row_and_field(tmp_path, row, field, words):
    model = tmp_path / "bad.toml"
    model.write_text("[robot]\nframes = [\n  " + ",\n  ".join([*GOOD_ROWS, row]) + "\n]\n")
    result = run("check", str(model))
    assert result.exit_code == 2, result.output
    assert str(model) in result.output and field in result.output and words in result.output, result.output
    assert "Traceback" not in result.output
    if "frames.2." in field and words != "unknown key" and "stiffness" not in words:
        assert "frame 3:" in result.output


@pytest.mark.parametrize("text, where, words", [
    ('[robot]\nframes = [{ ant = 0, sigma = 1 }]\n', "robot.frames", "no motorised joint"),
    ('[robot]\nframes = [{ ant = 0, sigma = 1, mu = 1 }]\n[axes.Z.drive]\ntype = "first-order"\n'
     'force_constant = 1\nbandwidth = 100\n', "axes.Z", "not a motorised joint"),
    ('[robot]\nframes = [{ ant = 0, sigma = 1, mu = 1, name = "X" }]\nconfiguration = [0, 1]\n',
     "robot.configuration", "expected 1 joint values"),
    ('[robot]\nframes = [{ ant = 0, sigma = 1, mu = 1, name = "X" }, { ant = 1, sigma = 1, name = "X" }]\n',
     "robot.frames.1.name", "already frame 1"),
    ('[robot]\nframes = [{ ant = 0, sigma = 1, mu = 1 }]\n[robot.sensors.s]\njoints = ["nope"]\n',
     "robot.sensors.s.joints.0", "unknown joint"),
    ('[robot]\nframes = [{ ant = 0, sigma = 1, mu = 1 }]\n[robot.sensors.s]\njoints = ["q1"]\n'
     'resolution = "1 um"\ncounts_per_revolution = 1000\n', "robot.sensors.s.counts_per_revolution", "not both"),
    ('[robot]\nlinks = 1\nframes = [{ ant = 0, sigma = 0, mu = 1 }, { ant = 1, sigma = 0 }, { ant = 1, sigma = 0 }]\n',
     "robot.frames.2.sigma", "closing frame is fixed"),
])
def test_bad_robot_sections(tmp_path, text, where, words):
    model = tmp_path / "bad.toml"
    model.write_text(text)
    result = run("check", str(model))
    assert result.exit_code == 2 and where in result.output and words in result.output, result.output


# --------------------------------------------------------------------------- sicomat robot
def test_robot_inverse_dynamics_cli_is_the_lagrange_model_of_the_file():
    result = run("robot", str(XY), "--inverse-dynamics", "--q", "0.1,0,0.01,150mm,0", "--qd", "0.2,0,0.05,0.1,0",
                 "--qdd", "1,0,0,-2,0", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    machine = load_model(XY)
    q, qd, qdd = np.array([0.1, 0, 0.01, 0.15, 0]), np.array([0.2, 0, 0.05, 0.1, 0]), np.array([1.0, 0, 0, -2, 0])
    np.testing.assert_array_equal(payload["tau"], robot_model(machine.robot).inverse_dynamics(q, qd, qdd))
    # Lagrange on the notes' closed form: tau = A qdd + (dA/dt) qd - d(qd^T A qd / 2)/dq + friction (gravity along
    # z0 does no work on these joints). The derivatives of the closed form by central differences, h = 1e-6:
    # truncation ~h^2 times A's third derivative and rounding ~eps |A| / h, both below 1e-8 of the torque scale.
    spec = machine.robot
    h = 1e-6
    dA = [(_xy_inertia_by_lagrange(spec, q + h * e) - _xy_inertia_by_lagrange(spec, q - h * e)) / (2 * h)
          for e in np.eye(5)]
    A_dot = sum(dA[k] * qd[k] for k in range(5))
    dT = np.array([0.5 * qd @ dA[k] @ qd for k in range(5)])
    f = {frame.name: frame for frame in spec.frames}
    names = ("X", "X_screw", "yaw", "Y", "Y_screw")
    friction = np.array([f[n].FV for n in names]) * qd + np.array([f[n].FS for n in names]) * np.sign(qd)
    tau = _xy_inertia_by_lagrange(spec, q) @ qdd + A_dot @ qd - dT + friction
    np.testing.assert_allclose(payload["tau"], tau, rtol=0, atol=1e-8 * np.abs(tau).max())


def test_robot_base_parameters_cli():
    result = run("robot", str(XY), "--base-parameters", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["count"] == len(payload["names"]) == 24      # the notes' pitfall (a): 24, not 22
    inertial = json.loads(run("robot", str(XY), "--base-parameters", "--inertial-only", "--json").stdout)
    assert inertial["count"] < payload["count"]


def test_robot_command_refuses_what_it_cannot_do(tmp_path):
    none = run("robot", str(EXAMPLES / "paper_5m4s.toml"), "--base-parameters")
    assert none.exit_code == 2 and "no [robot] section" in none.output
    two = run("robot", str(XY), "--base-parameters", "--inverse-dynamics")
    assert two.exit_code == 2 and "give one of" in two.output
    no_q = run("robot", str(XY), "--inverse-dynamics")
    assert no_q.exit_code == 2 and "--q" in no_q.output


# --------------------------------------------------------------------------- coupled servo loops
def test_coupled_xy_servo_loops_show_the_coupling_where_the_closed_form_puts_it():
    """X's move reaches Y's loop only through the Y slide's mass offset MX5 (A34 = A35 = MX5 at q3 = 0 in the
    notes' closed form; A14 = A15 = -M5 sin q3 = 0): with MX5 = 0 the linear coupled run leaves Y at rest to
    rounding (1e-12 of X's error); with the example's MX5 Y sees an error orders of magnitude above rounding;
    X's own error barely changes from its decoupled model."""
    from sicomat import simulate
    from sicomat.motion.setpoints import step_profile, trapezoid_profile
    from sicomat.servo.coupled import robot_coupled_loop
    from sicomat.servo.loop import build_servo_loop
    from sicomat.simulation.coupled import simulate_coupled

    machine = load_model(XY)
    profiles = {"X": trapezoid_profile(0.02, 0.3, 3.0), "Y": step_profile(0.0)}
    run = simulate_coupled(robot_coupled_loop(machine), profiles, 0.3, nonlinear=False)
    error_x = np.abs(run["X"]["following_error"]).max()
    error_y = np.abs(run["Y"]["following_error"]).max()
    assert 1e-5 * error_x < error_y < 0.1 * error_x     # measured 6.6e-4: far above rounding, below X's
    alone = simulate(build_servo_loop(machine, "X"), profiles["X"], 0.3, nonlinear=False)
    assert abs(np.abs(alone["following_error"]).max() - error_x) < 0.01 * error_x

    rows = [f.model_copy(update={"MX": 0.0}) if f.name == "Y_screw" else f for f in machine.robot.frames]
    centred = machine.model_copy(update={"robot": machine.robot.model_copy(update={"frames": rows})})
    run0 = simulate_coupled(robot_coupled_loop(centred), profiles, 0.3, nonlinear=False)
    assert np.abs(run0["Y"]["following_error"]).max() < 1e-12 * error_x


def test_export_symbolic_writes_four_files_that_agree_with_the_numeric_model(tmp_path):
    folder = tmp_path / "models"
    result = run("robot", str(XY), "--export-symbolic", str(folder), "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert sorted(Path(p).name for p in payload["written"]) == sorted(
        f"xy_elastic_models.{ext}" for ext in ("py", "c", "h", "txt"))
    namespace: dict = {}
    exec(compile((folder / "xy_elastic_models.py").read_text(), "xy_elastic_models.py", "exec"), namespace)
    q, qd, qdd = [0.1, 1e-5, 0.01, 0.15, -2e-5], [0.2, 0.0, 0.05, 0.1, 0.0], [1.0, 0.0, 0.0, -2.0, 0.0]
    tau = robot_model(load_model(XY).robot).inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(namespace["inverse_dynamics"](q, qd, qdd), tau, rtol=0, atol=REL * np.abs(tau).max())
    # a file where the folder should be: refused before anything is written
    blocked = tmp_path / "file"
    blocked.write_text("x")
    refused = run("robot", str(XY), "--export-symbolic", str(blocked))
    assert refused.exit_code == 2 and "Traceback" not in refused.output and blocked.read_text() == "x"
