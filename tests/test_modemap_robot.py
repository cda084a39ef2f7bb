"""The mode map over a robot machine's workspace (`sicomat modemap MODEL --joint NAME=LOW:HIGH`, issue 13).

References, independent of the code under test:
- the elastic XY cross-slide's inertia matrix by Lagrange (the notes' §4, ``robotics_models.xy_inertia_by_lagrange``)
  with the example's spring constants read from its table: with both motors locked the structure is the 3-dof
  (X_screw, yaw, Y_screw) system ``K φ = ω² A_ff φ``, solved by scipy's symmetric eigensolver;
- a pendulum on an elastic joint, by hand: with its motor locked at angle ``a`` (gravity along -y0, the link's
  centre of mass at ``l``), ``ZZ θ̈ + (k - m g l sin a) θ = 0``, so ``f = sqrt((k - m g l sin a) / ZZ) / 2π``,
  and the locked structure is unstable where ``m g l sin a > k``; with its motor free and gravity compensated
  (the axis's model) the two-body chain ``M = [[IA + ZZ, ZZ], [ZZ, ZZ]]``, ``K = diag(0, k)`` has the one
  flexible mode ``ω² = k (IA + ZZ) / (IA ZZ)`` whatever the angle;
- the map's points against ``sicomat modal --q`` / ``modal --axis`` at the same configuration (consistency).

Tolerances: the XY's matrices are a few dozen operations on numbers of order 1..1e3 (A) and 1e8 (K), rounding
~1e-15 relative; the modal analysis (an SVD of √k·G·L⁻ᵀ) adds ~1e-13 relative to a frequency; 1e-9 leaves a
margin of 1e4 and still catches any wrong term (a missing M5 y² moves the yaw mode by percents). The pendulum's
gravity stiffness is a central difference with one Richardson step, ~1e-12 of m g l = 11.8 N·m; against
k - m g l sin a >= 1.9 N·m on the grid below that is < 1e-11 relative in K, half of it in f: 1e-8 is safe.
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
from sicomat.errors import AnalysisError, ModelError
from sicomat.io import load_model
from sicomat.tasks.workspace_map import workspace_mode_map

from robotics_models import xy_inertia_by_lagrange

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
XY = EXAMPLES / "xy_elastic.toml"
ROBOT6 = EXAMPLES / "robot6_elastic.toml"
runner = CliRunner()

# the pendulum: link mass m, centre of mass at l on x, spring k, motor rotor IA (SI)
PEND_M, PEND_L, PEND_K, PEND_IA, G0 = 3.0, 0.4, 5.0, 0.1, 9.81
PEND_ZZ = PEND_M * PEND_L ** 2 + 0.01


def run(*args) -> "object":
    return runner.invoke(app, [str(a) for a in args])


def payload_of(*args) -> dict:
    result = run(*args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def pendulum_model(tmp_path: Path) -> Path:
    path = tmp_path / "pendulum.toml"
    path.write_text(f"""name = "pendulum"
[robot]
gravity = ["0 m/s^2", "-{G0} m/s^2", "0 m/s^2"]

[[robot.frames]]
name = "A"
ant = 0
sigma = 0
mu = 1
IA = {PEND_IA!r}

[[robot.frames]]
name = "e"
ant = 1
sigma = 0
eta = 1
k = {PEND_K!r}
M = {PEND_M!r}
MX = {PEND_M * PEND_L!r}
XX = 0.01
YY = {PEND_M * PEND_L ** 2!r}
ZZ = {PEND_ZZ!r}
""", encoding="utf-8")
    return path


def xy_locked_hz(spec, q) -> np.ndarray:
    """The XY's modes with both motors locked: the Lagrange inertia matrix on the elastic joints and the springs
    of the example's table (gravity along z0 does no work on its slides and yaw: no gravity stiffness)."""
    frames = {f.name: f for f in spec.frames}
    free = [1, 2, 4]                                   # X_screw, yaw, Y_screw in joint order
    K = np.diag([frames["X_screw"].k, frames["yaw"].k, frames["Y_screw"].k])
    A = xy_inertia_by_lagrange(spec, q)[np.ix_(free, free)]
    return np.sqrt(scipy.linalg.eigh(K, A, eigvals_only=True)) / (2 * math.pi)


# --------------------------------------------------------------------------- against closed forms
def test_xy_modes_over_y_are_the_lagrange_closed_form():
    spec = load_model(XY).robot
    payload = payload_of("modemap", XY, "--joint", "Y=-200mm:400mm", "--points", 13)
    assert payload["joints"] == ["Y"] and payload["units"] == ["m"] and payload["locked"] == ["X", "Y"]
    assert payload["axis"] is None and payload["failed"] == []
    base = [payload["configuration"][name] for name in ("X", "X_screw", "yaw", "Y", "Y_screw")]
    assert base == [0.0, 0.0, 0.0, 0.15, 0.0]                      # the file's configuration
    grid = np.array(payload["grid"][0])
    np.testing.assert_allclose(grid, np.linspace(-0.2, 0.4, 13), rtol=0, atol=1e-15)
    assert payload["position"] == payload["grid"][0]
    expected = np.array([xy_locked_hz(spec, [0.0, 0.0, 0.0, y, 0.0]) for y in grid])
    np.testing.assert_allclose(payload["undamped_hz"], expected, rtol=1e-9)
    assert payload["frequencies_hz"] == payload["undamped_hz"]       # one joint: one row per point either way
    # the highest mode (yaw with the Y screw) softens as the Y slide moves out: M5 y² in the yaw inertia
    yaw = np.array(payload["undamped_hz"])[:, 2]
    assert yaw[grid == 0.4][0] < yaw[grid == 0.0][0] - 10.0
    i = int(np.argmin(expected[:, 0]))
    assert payload["worst_position"] == grid[i]
    assert payload["lowest_first_mode_hz"] == pytest.approx(expected[i, 0], rel=1e-9)


def test_pendulum_unstable_points_fail_and_the_others_are_the_closed_form(tmp_path):
    model = pendulum_model(tmp_path)
    payload = payload_of("modemap", model, "--joint", "A=0deg:180deg", "--points", 13)
    grid = np.array(payload["grid"][0])
    stiffness = PEND_K - PEND_M * G0 * PEND_L * np.sin(grid)
    stable = stiffness > 0
    assert stable.sum() == 4 and np.all(np.abs(stiffness) > 0.5)      # no grid point near the threshold
    f = np.array([np.nan if row[0] is None else row[0] for row in payload["undamped_hz"]])
    np.testing.assert_allclose(f[stable], np.sqrt(stiffness[stable] / PEND_ZZ) / (2 * math.pi), rtol=1e-8)
    assert np.all(np.isnan(f[~stable]))
    failed = payload["failed"]
    assert [p["index"] for p in failed] == [[i] for i in np.flatnonzero(~stable)]
    assert [p["position"] for p in failed] == list(grid[~stable])
    assert all("negative stiffness" in p["reason"] for p in failed)
    assert any("9 of 13 configurations failed" in note for note in payload["notes"])
    # the table says the same, each reason once
    table = run("modemap", model, "--joint", "A=0deg:180deg", "--points", 13)
    assert table.exit_code == 0 and table.output.count("failed [") >= 9
    assert "negative stiffness" in table.output and "A (deg)" in table.output


def test_all_points_failing_is_an_error(tmp_path):
    result = run("modemap", pendulum_model(tmp_path), "--joint", "A=60deg:120deg", "--points", 5)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "every configuration failed" in lines[0] and "negative stiffness" in lines[0]
    with pytest.raises(AnalysisError):
        workspace_mode_map(load_model(pendulum_model(tmp_path)), ["A=60deg:120deg"], 5)


def test_axis_map_of_the_pendulum_is_gravity_compensated_and_the_two_body_closed_form(tmp_path):
    payload = payload_of("modemap", pendulum_model(tmp_path), "--joint", "A=0deg:180deg", "--points", 7,
                         "--axis", "A")
    assert payload["axis"] == "A" and payload["locked"] == [] and payload["failed"] == []
    assert payload["modes"] == 1                                     # the motor's rigid mode left out
    omega2 = PEND_K * (PEND_IA + PEND_ZZ) / (PEND_IA * PEND_ZZ)
    np.testing.assert_allclose(payload["undamped_hz"], np.full((7, 1), math.sqrt(omega2) / (2 * math.pi)),
                               rtol=1e-9)


# --------------------------------------------------------------------------- consistency with sicomat modal
def modal_hz(*args) -> list[float]:
    payload = payload_of("modal", *args)
    return [m["undamped_hz"] for m in payload["modes"] if not m["rigid"]]


def test_two_joint_map_points_are_modal_q_and_the_grid_is_row_major():
    payload = payload_of("modemap", XY, "--joint", "X=-100mm:100mm", "--joint", "Y=0mm:400mm", "--points", 5,
                         "--q", "0,0,0.001,0.15,0")
    assert payload["joints"] == ["X", "Y"] and [len(g) for g in payload["grid"]] == [5, 5]
    hz = np.array(payload["undamped_hz"])
    assert hz.shape == (5, 5, 3) and payload["configuration"]["yaw"] == 0.001
    assert len(payload["position"]) == 25 and len(payload["frequencies_hz"]) == 25
    for i, x in enumerate(payload["grid"][0]):
        for j, y in enumerate(payload["grid"][1]):
            assert payload["position"][5 * i + j] == [x, y]
            assert payload["frequencies_hz"][5 * i + j] == payload["undamped_hz"][i][j]
    for i, j in [(0, 0), (2, 3), (4, 4)]:
        x, y = payload["grid"][0][i], payload["grid"][1][j]
        expected = modal_hz(XY, "--q", f"{x!r},0,0.001,{y!r},0")
        # the same lowering and modal analysis: equal but for a future reordering of the arithmetic
        np.testing.assert_allclose(hz[i, j], expected, rtol=1e-12)
    # the X carriage's position is not in the Lagrange inertia matrix (A has no q1): the map is flat along X
    np.testing.assert_allclose(hz, np.broadcast_to(hz[:1], hz.shape), rtol=1e-12)


def test_robot6_map_with_gravity_equals_modal_q():
    machine = load_model(ROBOT6)
    base = list(machine.robot.configuration)
    payload = payload_of("modemap", ROBOT6, "--joint", "A3=30deg:150deg", "--points", 3, "--modes", 4)
    assert payload["locked"] == ["A1", "A2", "A3", "A4", "A5", "A6"]
    for i, a3 in enumerate(payload["grid"][0]):
        q = list(base)
        q[machine.robot.joint_names.index("A3")] = a3
        expected = modal_hz(ROBOT6, "--q", ",".join(repr(v) for v in q))[:4]
        np.testing.assert_allclose(payload["undamped_hz"][i], expected, rtol=1e-12)


@pytest.mark.parametrize("model, axis, joint", [
    (XY, "X", "Y=0mm:300mm"),                   # the middle point is the file's Y = 150 mm
    (ROBOT6, "A2", "A2=-120deg:0deg"),           # the middle point is the file's A2 = -60 deg
])
def test_axis_map_equals_modal_axis_at_the_base_configuration(model, axis, joint):
    payload = payload_of("modemap", model, "--joint", joint, "--points", 3, "--axis", axis, "--modes", 2)
    machine = load_model(model)
    name = joint.split("=")[0]
    assert payload["grid"][0][1] == machine.robot.configuration[machine.robot.joint_names.index(name)]
    assert payload["axis"] == axis and axis not in payload["locked"]
    assert payload["locked"] == [m for m in machine.robot.motor_names if m != axis]
    np.testing.assert_allclose(payload["undamped_hz"][1], modal_hz(model, "--axis", axis)[:2], rtol=1e-12)


# --------------------------------------------------------------------------- figures and the Python API
def test_plots_name_the_joints_in_display_units_and_what_is_locked(tmp_path):
    machine = load_model(XY)
    line = workspace_mode_map(machine, ["Y=0mm:400mm"], 5).plot()
    assert line.axes[0].get_xlabel() == "Y (mm)" and "locked (X, Y)" in line.axes[0].get_title()
    surface = workspace_mode_map(machine, ["yaw=-1deg:1deg", "Y=0mm:400mm"], 5, axis="Y").plot()
    panels = [ax for ax in surface.axes if ax.get_xlabel()]
    assert [ax.get_xlabel() for ax in panels] == ["yaw (deg)", "yaw (deg)"]
    assert [ax.get_ylabel() for ax in panels] == ["Y (mm)", "Y (mm)"]
    assert "axis Y's model" in surface.get_suptitle() and "xy-elastic" in surface.get_suptitle()
    for joints in (["--joint", "Y=0mm:400mm"], ["--joint", "X=0mm:100mm", "--joint", "Y=0mm:400mm"]):
        figure = tmp_path / f"map{len(joints)}.png"
        result = run("modemap", XY, *joints, "--points", 5, "--plot", figure)
        assert result.exit_code == 0, result.output
        assert figure.read_bytes()[:4] == b"\x89PNG" and figure.stat().st_size > 10_000
        assert "worst (lowest f1)" in result.output and "Y (mm)" in result.output


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, words", [
    (["--joint", "Z=0mm:1mm"], "unknown joint 'Z'"),
    (["--joint", "tool=0mm:1mm"], "fixed frame"),
    (["--joint", "Y=400mm:0mm"], "LOW < HIGH"),
    (["--joint", "Y=0mm:0mm"], "LOW < HIGH"),
    (["--joint", "Y=0:0.4"], "no unit"),
    (["--joint", "Y=0deg:90deg"], "prismatic"),
    (["--joint", "yaw=0mm:1mm"], "revolute"),
    (["--joint", "Y"], "give its range"),
    (["--joint", "Y=0mm"], "NAME=LOW:HIGH"),
    (["--joint", "X=0mm:1mm", "--joint", "Y=0mm:1mm", "--joint", "yaw=0deg:1deg"], "expected 1 or 2"),
    (["--joint", "Y=0mm:1mm", "--joint", "Y=0mm:2mm"], "given twice"),
    (["--joint", "X=0mm:1mm", "--joint", "Y=0mm:1mm", "--points", "102"], "--points"),
    ([], "--joint"),
    (["--joint", "Y=0mm:1mm", "--axis", "yaw"], "unknown axis"),
    (["--joint", "Y=0mm:1mm", "--q", "0,0,0"], "--q"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, words):
    figure = tmp_path / "map.png"
    result = run("modemap", XY, *args, "--plot", figure)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], lines
    assert "Traceback" not in result.output and not figure.exists()
    if "--joint" in args and words not in ("--points", "--q", "unknown axis"):
        assert "--joint" in lines[0]


@pytest.mark.parametrize("args", [["--joint", "X=0mm:100mm"], ["--q", "0,0"]])
def test_robot_options_on_a_drive_chain_model_exit_2(args):
    result = run("modemap", EXAMPLES / "ballscrew_catalog.toml", *args)
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "[robot]" in lines[0] and args[0] in lines[0]


def test_the_library_names_the_parameter():
    machine = load_model(XY)
    with pytest.raises(ModelError) as info:
        workspace_mode_map(machine, ["Y=1m:0m"], 5)
    assert info.value.path == "joint"
    with pytest.raises(ModelError) as info:
        workspace_mode_map(machine, ["Y=0m:1m", "X=0m:1m"], 200)
    assert info.value.path == "points"
