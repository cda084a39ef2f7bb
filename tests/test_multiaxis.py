"""Two decoupled axes on a path: the circle test's servo mismatch against the first-order theory,
G-code paths through the CLI, and their error messages."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sicomat
from sicomat.cli.main import app
from sicomat.simulation.paths import circle_test

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
XY = EXAMPLES / "xy_table.toml"

# identical axes: the Y axis made a copy of the X axis (mass and velocity-loop gains)
IDENTICAL = ["axes.Y.mechanics.bodies.table.mass=350 kg", "axes.Y.controller.Kp_normalized=150.8",
             "axes.Y.controller.Ti=5.93 ms"]


def _circle(kv_y: float, clockwise: bool):
    machine = sicomat.load_model(XY, IDENTICAL + [f"axes.Y.controller.Kv={kv_y}"])
    return circle_test(machine, 0.01, 0.02, clockwise=clockwise, feedforward="off", nonlinear=False).circle


def test_identical_axes_have_no_servo_mismatch():
    c = _circle(50.0, clockwise=False)
    assert c.servo_mismatch < 0.02 * abs(c.mean_radial_deviation)
    # a first-order follower at feed v on radius R loses about v^2/(2 Kv^2 R) of radius
    v, kv, r = 0.02, 50.0, 0.01
    # a first-order follower is a physical approximation of the axis: the velocity loop's own lag adds ~1/ω_v to
    # 1/Kv (ω_v/Kv ≈ 10) and the radius error goes as the lag squared: ~10-15 %; the mismatch time is first
    # order in the lag (10 %), its angle 45° to O(w/Kv) ≈ 2.3°: 3°
    assert c.mean_radial_deviation == pytest.approx(-v ** 2 / (2 * kv ** 2 * r), rel=0.15)


@pytest.mark.parametrize("clockwise", [False, True])
def test_unequal_position_gains_tilt_the_circle_at_45_degrees(clockwise):
    c = _circle(40.0, clockwise)
    # the lag mismatch 1/Kv_y - 1/Kv_x of two first-order followers; the velocity loops are identical
    assert c.servo_mismatch_time == pytest.approx(1 / 40.0 - 1 / 50.0, rel=0.1)
    assert abs(abs(np.degrees(c.servo_mismatch_angle)) - 45.0) < 3.0
    ccw = _circle(40.0, not clockwise)
    # a servo mismatch (unlike a squareness error) turns the ellipse when the direction reverses
    assert np.sign(c.servo_mismatch_angle) != np.sign(ccw.servo_mismatch_angle)


runner = CliRunner()


def test_circle_cli_json_contract(tmp_path):
    figure = tmp_path / "circle.png"
    result = runner.invoke(app, ["circle", str(XY), "--radius", "10", "--feed", "1200", "--ccw",
                                 "--feedforward", "on", "--json", "--plot", str(figure)])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    for key in ("circular_deviation", "radial_deviation_min", "radial_deviation_max", "mean_radial_deviation",
                "max_contour_error"):
        assert isinstance(payload[key], float)
    assert payload["radial_deviation_min"] <= payload["mean_radial_deviation"] <= payload["radial_deviation_max"]
    assert payload["clockwise"] is False and payload["feedforward"] == "on"
    assert figure.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args,needle", [
    (["--radius", "0", "--feed", "1000"], "--radius"),
    (["--radius", "10", "--feed", "0"], "--feed"),
    (["--radius", "10", "--feed", "1000", "--feedforward", "maybe"], "--feedforward"),
    (["--radius", "1", "--feed", "60000"], "centripetal"),
])
def test_circle_cli_bad_input(args, needle):
    result = runner.invoke(app, ["circle", str(XY), *args])
    assert result.exit_code == 2
    assert needle in result.stderr and "Traceback" not in result.output


def test_gcode_path_through_the_cli(tmp_path):
    result = runner.invoke(app, ["simulate", str(XY), "--gcode", str(EXAMPLES / "contour.nc"), "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    # lengths summed: a few roundings; 1e-9 slack
    assert payload["path_length"] == pytest.approx(0.04 + np.pi / 2 * 0.02 + 0.03, rel=1e-9)
    assert set(payload["axes"]) == {"x", "y"}
    assert 0 < payload["max_contour_error"] < 1e-3


def test_gcode_errors_name_the_line(tmp_path):
    program = tmp_path / "bad.nc"
    program.write_text("G90 G01 X10 Y0 F1000\nG02 X20 Y0 I1 J0\n")
    result = runner.invoke(app, ["simulate", str(XY), "--gcode", str(program)])
    assert result.exit_code == 2
    assert "line 2" in result.stderr and str(program) in result.stderr
