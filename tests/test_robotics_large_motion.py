"""Large motions of a robot machine (simulation/nonlinear.py) and the circle test on a [robot] machine
(tasks/circle.py): the nonlinear engine against the exact linear kernel where the robot is linear, against an
independent ODE solution of the robot's nonlinear dynamics where it is not, and the CLI's comparison of the
decoupled, coupled and nonlinear models where physics says what it must show."""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from sicomat.cli.main import app
from sicomat.io import machine_from_dict
from sicomat.motion.setpoints import trapezoid_profile
from sicomat.robotics import MDHRobot
from sicomat.robotics.path_model import rigid_body_dynamics, tool_point
from sicomat.servo.coupled import robot_coupled_loop
from sicomat.simulation.coupled import coupled_run_program
from sicomat.simulation.kernel import run
from sicomat.simulation.nonlinear import run_nonlinear, substeps
from sicomat.simulation.paths import circle_test

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
XY = EXAMPLES / "xy_elastic.toml"


def _xy_data() -> dict:
    with open(XY, "rb") as handle:
        return tomllib.load(handle)


def _cartesian_xy() -> dict:
    """The elastic XY with its yaw joint made a fixed frame: every joint prismatic, so the inertia matrix is
    constant and the robot's dynamics are exactly linear."""
    data = copy.deepcopy(_xy_data())
    yaw = data["robot"]["frames"][2]
    yaw.update(sigma=2)
    for key in ("eta", "k", "FV"):
        yaw.pop(key)
    data["robot"]["configuration"] = ["0 mm", "0 mm", "150 mm", "0 mm"]
    return data


runner = CliRunner()


def _cli(*args: str):
    return runner.invoke(app, list(args))


def _programs(machine, distance: float, duration: float, nonlinear: bool):
    coupled = robot_coupled_loop(machine)
    profiles = {"X": trapezoid_profile(distance, 0.2, 2.0), "Y": trapezoid_profile(-distance, 0.2, 2.0)}
    return coupled, coupled_run_program(coupled, profiles, duration, nonlinear=nonlinear)


def test_on_a_linear_robot_the_engine_is_the_exact_linear_kernel():
    """Constant inertia, no Coriolis: the engine's RK4 differs from the exact discretisation by its truncation
    only. With rho h_sub <= 0.1 the local error is (0.1)^5/120 ~ 1e-7 of a state on the fastest (current-loop)
    pole, which decays, and ~1e-12 on the mechanical modes (omega h_sub ~ 0.02): 1e-6 of each state's range
    bounds the accumulated difference."""
    machine = machine_from_dict(_cartesian_xy())
    _, (program, n) = _programs(machine, 0.02, 0.3, nonlinear=False)
    exact = run(program, n)
    ours = run_nonlinear(program, n, rigid_body_dynamics(machine.robot))
    scale = np.max(np.abs(exact.states), axis=0)
    assert np.all(scale > 0)
    assert np.max(np.abs(ours.states - exact.states) / scale) < 1e-6
    names = list(exact.record_names)
    for axis in ("X", "Y"):
        i = names.index(f"sensor.{axis}")
        assert np.max(np.abs(ours.records[:, i] - exact.records[:, i])) < 1e-6 * np.max(np.abs(exact.records[:, i]))


def test_stick_slip_agrees_with_the_kernel_to_the_event_resolution():
    """With Coulomb friction on both motor joints: the kernel locates stick/slip events to h/2^10, the engine to
    its sub-step h_sub = h/12. An event found up to one sub-step late moves a joint by at most
    a_max h_sub^2 (a_max <= peak force / moving mass = 24 A * 294.5 N/A / 90 kg ~ 80 m/s^2: 9e-9 m), at
    most once per event: 1e-7 m bounds a run with a few tens of events."""
    machine = machine_from_dict(_cartesian_xy())
    _, (program, n) = _programs(machine, 0.02, 0.3, nonlinear=True)
    exact = run(program, n)
    assert exact.events > 0 and np.any(exact.stuck) and not np.all(exact.stuck)
    ours = run_nonlinear(program, n, rigid_body_dynamics(machine.robot))
    assert np.any(ours.stuck) and not np.all(ours.stuck)
    names = list(exact.record_names)
    for axis in ("X", "Y", "X_scale"):
        i = names.index(f"sensor.{axis}")
        assert np.max(np.abs(ours.records[:, i] - exact.records[:, i])) < 1e-7


def _peer_trajectory(machine, record_names, records, n: int, h: float) -> np.ndarray:
    """The states (q - q0, qd, i_X, i_Y) at the samples by scipy's DOP853 (rtol 1e-11) on the robot's
    nonlinear dynamics written here from the model file: ``A(q) qdd + c(q, qd) + FV qd + k dq_elastic =
    kt i`` (robotics ``direct_dynamics``, checked against pin.aba; gravity compensated, so none), each
    drive's current loop ``di/dt = (u - i) / tau`` with tau = 1 / (2 pi bandwidth), the held inputs ``u``
    those the engine latched (its recorded ``<axis>.current.delayed``)."""
    spec = machine.robot
    rows = [frame.table_row() for frame in spec.frames]
    for row in rows:
        row["FS"] = 0.0                       # the linear program drops Coulomb friction
    robot = MDHRobot.from_table(rows, gravity=(0.0, 0.0, 0.0))
    q0 = np.array(spec.configuration)
    names = spec.joint_names
    k = np.array([spec.frames[row].k if spec.frames[row].eta == 1 else 0.0 for row in spec.joint_rows])
    tau = {axis: 1.0 / (2 * np.pi * machine.axes[axis].drive.bandwidth) for axis in ("X", "Y")}
    kt = {axis: machine.axes[axis].drive.force_constant for axis in ("X", "Y")}
    cols = {axis: list(record_names).index(f"{axis}.current.delayed") for axis in ("X", "Y")}
    nq = len(names)

    def rhs(_t, z, u):
        q, qd, cur = q0 + z[:nq], z[nq:2 * nq], z[2 * nq:]
        force = -k * z[:nq]
        force[names.index("X")] += kt["X"] * cur[0]
        force[names.index("Y")] += kt["Y"] * cur[1]
        qdd = robot.direct_dynamics(q, qd, force)
        return np.concatenate([qd, qdd, [(u[0] - cur[0]) / tau["X"], (u[1] - cur[1]) / tau["Y"]]])

    z = np.zeros(2 * nq + 2)
    out = np.empty((n, z.size))
    for step in range(n):
        out[step] = z
        u = (records[step, cols["X"]], records[step, cols["Y"]])
        sol = solve_ivp(rhs, (0.0, h), z, method="DOP853", rtol=1e-11, atol=1e-16, args=(u,))
        z = sol.y[:, -1]
    return out


def test_the_engine_follows_the_robots_nonlinear_dynamics():
    """The elastic XY with a soft carriage yaw (its inertia about the yaw axis changes with Y, Coriolis terms
    couple yaw and Y): the engine's states against an independent ODE solution of the nonlinear dynamics with
    the same held currents. Bound: the engine's RK4 truncation (1e-6 of a state's range, see the linear test)
    plus DOP853's 1e-11. The linear model misses the nonlinearity by far more, so the test can tell them
    apart."""
    data = _xy_data()
    data["robot"]["frames"][2]["k"] = "4e5 N*m/rad"
    machine = machine_from_dict(data)
    _, (program, n) = _programs(machine, 0.03, 0.06, nonlinear=False)
    ours = run_nonlinear(program, n, rigid_body_dynamics(machine.robot))
    peer = _peer_trajectory(machine, ours.record_names, ours.records, n, program.step)
    scale = np.max(np.abs(peer), axis=0)
    error = np.max(np.abs(ours.states - peer) / scale)
    assert error < 1e-6
    linear = run(program, n)
    assert np.max(np.abs(linear.states - peer) / scale) > 100 * max(error, 1e-9)


def test_tool_point_linearisation_is_the_jacobian_read_as_path_coordinates():
    """The XY's tool tip: X's path coordinate is X + X_screw - y yaw (the carriage's yaw moves the tool, offset
    y = 0.15 m from the yaw axis: an Abbe error), Y's is Y + Y_screw; the geometric model agrees with the
    linearisation to second order in a small displacement."""
    machine = machine_from_dict(_xy_data())
    point = tool_point(machine.robot, ["X", "Y"])
    expected = np.array([[1.0, 1.0, -0.15, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 1.0]])
    assert np.allclose(point.linear(), expected, atol=1e-12)
    dq = np.array([1e-4, 2e-6, 3e-6, -2e-4, 1e-6])
    # second-order remainder: |dq|^2 times the tool's 0.15-0.2 m lever, ~1e-9 m here
    assert np.allclose(point.coordinates(dq[None])[0], expected @ dq, atol=1e-8)


def test_circle_on_a_robot_compares_the_three_models():
    out = _cli("circle", str(XY), "--radius", "20", "--feed", "10000", "--json")
    assert out.exit_code == 0, out.output
    payload = json.loads(out.stdout)
    assert payload["model"] == "nonlinear"
    coupling = payload["coupling"]
    for name in ("decoupled", "coupled", "nonlinear"):
        assert coupling[name]["stable"] is True
        assert 1e-6 < coupling[name]["circular_deviation"] < 1e-4
    assert payload["circular_deviation"] == coupling["nonlinear"]["circular_deviation"]
    for key in ("circular_deviation", "max_contour_error"):
        total = coupling["added_by_coupling"][key]
        assert total == pytest.approx(coupling["nonlinear"][key] - coupling["decoupled"][key], abs=1e-15)
        assert total == pytest.approx(coupling["added_by_linear_coupling"][key]
                                      + coupling["added_by_large_motion"][key], abs=1e-15)


def _circle_coupling(tmp_path: Path, data: dict, name: str) -> dict:
    import tomli_w

    model = tmp_path / f"{name}.toml"
    model.write_bytes(tomli_w.dumps(data).encode())
    out = _cli("circle", str(model), "--radius", "20", "--feed", "10000", "--json")
    assert out.exit_code == 0, out.output
    return json.loads(out.stdout)["coupling"]


def test_without_yaw_the_coupling_adds_nothing_and_a_softer_yaw_adds_more(tmp_path):
    """Physics of the XY: with the carriage rigid in yaw every joint is prismatic and the axes orthogonal, so the
    inertia matrix is constant and diagonal in X and Y: the three models give the same contour — to rounding
    without friction (checked in Python, 1e-15 m), and with the guides' Coulomb friction to where each run
    locates its stick/slip events (the kernel to h/2^10 on a grid the other axis's events subdivide, the
    engine to its sub-step): the breakaway of a link whose static and kinetic friction are equal starts from
    zero net force, so a late breakaway costs little; 1e-7 m, as in the stick-slip test above (measured 1e-8).
    With the yaw compliant the tool point's Abbe error y * yaw follows the yaw deflection, quasi-static below
    the yaw mode, so ~1/k: ten times softer adds several times more."""
    machine = machine_from_dict(_cartesian_xy())
    runs = {model: circle_test(machine, 0.02, 10.0 / 60.0, model=model, nonlinear=False)
            for model in ("decoupled", "coupled", "nonlinear")}
    # the engine's RK4 against the exact kernel: 1e-6 of the ~4e-5 m deviation (the linear-robot test)
    assert np.max(np.abs(runs["decoupled"].run.actual - runs["coupled"].run.actual)) < 1e-14
    assert np.max(np.abs(runs["coupled"].run.actual - runs["nonlinear"].run.actual)) < 1e-10
    rigid = _circle_coupling(tmp_path, _cartesian_xy(), "rigid")
    assert abs(rigid["added_by_linear_coupling"]["max_contour_error"]) < 1e-7
    assert abs(rigid["added_by_large_motion"]["max_contour_error"]) < 1e-7
    stiff, soft = _xy_data(), _xy_data()
    stiff["robot"]["frames"][2]["k"] = "4e6 N*m/rad"
    soft["robot"]["frames"][2]["k"] = "4e5 N*m/rad"
    a = _circle_coupling(tmp_path, stiff, "stiff")["added_by_linear_coupling"]["max_contour_error"]
    b = _circle_coupling(tmp_path, soft, "soft")["added_by_linear_coupling"]["max_contour_error"]
    assert a > 1e-7 and b > 5 * a


@pytest.mark.parametrize("args, words", [
    (["--model", "coupled"], "need a machine described by a [robot] section"),
    (["--model", "sideways"], "expected one of decoupled, coupled, nonlinear"),
])
def test_circle_model_option_is_checked(args, words):
    model = EXAMPLES / ("xy_table.toml" if args[1] == "coupled" else "xy_elastic.toml")
    out = _cli("circle", str(model), "--radius", "20", "--feed", "2000", *args)
    assert out.exit_code == 2
    assert words in out.output and "Traceback" not in out.output


def test_an_unknown_tool_frame_is_refused(tmp_path):
    text = XY.read_text().replace('[robot]\n', '[robot]\ntool = "spindle"\n', 1)
    model = tmp_path / "bad.toml"
    model.write_text(text)
    out = _cli("check", str(model))
    assert out.exit_code == 2
    assert "robot.tool" in out.output and "spindle" in out.output and "Traceback" not in out.output


def test_substeps_follow_the_fastest_pole():
    A = np.diag([-1.0, -1.0e4])
    assert substeps(A, 1e-4) == 10          # rho h = 1: ten sub-steps of 0.1


def test_a_gcode_path_on_the_coupled_model_reads_the_tool_point():
    """``simulate --gcode --coupled`` on the XY: the line-arc-line contour (Y travels 50 mm from its 150 mm
    configuration) on the nonlinear coupled dynamics. The XY's coupling is weak (the circle above: +0.4 % of the
    contour error), so the tool point's contour error stays within 10 % of the decoupled axes' — a wrong tool
    frame, offset or axis mapping would put it off by the path's millimetres."""
    contour = str(EXAMPLES / "contour.nc")
    coupled = _cli("simulate", str(XY), "--gcode", contour, "--coupled", "--json")
    assert coupled.exit_code == 0, coupled.output
    decoupled = _cli("simulate", str(XY), "--gcode", contour, "--json")
    a, b = json.loads(coupled.stdout), json.loads(decoupled.stdout)
    assert a["model"] == "nonlinear" and b["model"] == "decoupled" and a["stable"] is True
    assert 1e-7 < b["max_contour_error"] < 1e-3
    assert abs(a["max_contour_error"] - b["max_contour_error"]) < 0.1 * b["max_contour_error"]
