"""The `sicomat` program: JSON contracts, --set, and bad input (one line, exit 2, no traceback)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sicomat.cli.main import app

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
P5M4S = str(EXAMPLES / "paper_5m4s.toml")
runner = CliRunner()


def run(*args: str):
    return runner.invoke(app, list(args))


def test_modal_json_contract_on_two_mass_closed_form(tmp_path):
    m1, m2, k = 2.0, 3.0, 5.0e4
    model = tmp_path / "two.toml"
    model.write_text(f'[axes.X.mechanics]\ntype = "chain"\nmasses = [{m1}, {m2}]\nstiffnesses = [{k}]\n')
    result = run("modal", str(model), "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    expected = np.sqrt(k * (m1 + m2) / (m1 * m2)) / (2 * np.pi)
    assert payload["undamped_hz"][0] == 0.0
    # through JSON (repr floats round-trip exactly): the SVD's value to a few eps (1e-12); the damped pole by
    # dgeev after balancing to a few eps, with the mode matching and shape normalisation (1e-9): see test_modal
    np.testing.assert_allclose(payload["undamped_hz"][1], expected, rtol=1e-12)
    assert [m["frequency_hz"] for m in payload["modes"]] == sorted(m["frequency_hz"] for m in payload["modes"])
    flexible = payload["modes"][1]
    np.testing.assert_allclose(flexible["frequency_hz"], expected, rtol=1e-9)
    assert set(flexible["shape"]) == {"m1", "m2"}
    # the flexible mode of a free-free pair: amplitudes in inverse ratio of the masses, opposite signs
    np.testing.assert_allclose(flexible["shape"]["m1"] / flexible["shape"]["m2"], -m2 / m1, rtol=1e-9)
    assert max(abs(v) for v in flexible["shape"].values()) == 1.0


def test_modal_json_5m4s_first_flexible_mode_near_80_hz():
    result = run("modal", P5M4S, "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    flexible = [m for m in payload["modes"] if m["frequency_hz"] > 0]
    assert 75.0 < flexible[0]["frequency_hz"] < 85.0  # paper IV.B: "a first mode near f_meca = 80 Hz"
    assert payload["undamped_hz"][0] == 0.0 and payload["undamped_hz"][1] > 0


def test_set_override_with_units_changes_the_result():
    base = json.loads(run("modal", P5M4S, "--json").stdout)
    heavier = run("modal", P5M4S, "--json", "--set", "axes.X.mechanics.bodies.structure.mass=7334 kg")
    assert heavier.exit_code == 0, heavier.output
    changed = json.loads(heavier.stdout)
    # structure + secondary on 1e9 N/m: doubling the structure's mass lowers that mode by ~sqrt(2)
    f0 = np.sqrt(1e9 / (3667 + 232)) / (2 * np.pi)
    f1 = np.sqrt(1e9 / (7334 + 232)) / (2 * np.pi)
    # a physical approximation: structure + secondary as one body on the 1e9 N/m ground spring, the rest of the
    # axis (~360 kg on 3.8e8 N/m, ~5 times higher) shifts that mode by O(ω²/ω_other²) ≈ 1e-3: 2e-3
    np.testing.assert_allclose(base["undamped_hz"][1], f0, rtol=2e-3)
    np.testing.assert_allclose(changed["undamped_hz"][1], f1, rtol=2e-3)


def test_check_json_lists_axes_dofs_and_links():
    result = run("check", P5M4S, "--json")
    assert result.exit_code == 0, result.output
    axis = json.loads(result.stdout)["axes"]["X"]
    assert [d["name"] for d in axis["dofs"]] == ["structure", "secondary", "primary", "load", "scale_head"]
    assert axis["n_states"] == 10
    assert {c["name"] for c in axis["couplings"]} == {"structure", "secondary", "load", "scale_head"}
    assert axis["sensors"][0]["reads"] == "scale_head.x - structure.x"


def test_check_table_and_modal_plot(tmp_path):
    result = run("check", str(EXAMPLES / "ballscrew_3m2s.toml"))
    assert result.exit_code == 0 and "screw_nut" in result.stdout
    figure = tmp_path / "modes.png"
    result = run("modal", str(EXAMPLES / "ballscrew_3m2s.toml"), "--plot", str(figure))
    assert result.exit_code == 0, result.output
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["modes.png"]  # no temporary file left


BAD = {
    "dimension": ('mass = "3 m"', "axes.X.mechanics.bodies.a.mass", "'3 m'"),
    "unknown_unit": ('mass = "3 kgg"', "axes.X.mechanics.bodies.a.mass", "kgg"),
    "negative": ("mass = -3", "axes.X.mechanics.bodies.a.mass", "-3"),
    "zero": ("mass = 0", "axes.X.mechanics.bodies.a.mass", "0"),
    "wrong_type": ("mass = [1, 2]", "axes.X.mechanics.bodies.a.mass", "[1, 2]"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_body_values_exit_2_with_location(tmp_path, case):
    line, path, value = BAD[case]
    model = tmp_path / f"{case}.toml"
    model.write_text('[axes.X.mechanics]\ntype = "lumped"\n[axes.X.mechanics.bodies.a]\n' + line +
                     '\n[axes.X.mechanics.actuators.m]\nbody = "a"\n')
    result = run("modal", str(model))
    assert result.exit_code == 2
    message = result.stderr
    assert message.count("\n") == 1 and "Traceback" not in result.output
    assert str(model) in message and path in message and value in message


def test_bad_override_names_the_override():
    result = run("modal", P5M4S, "--set", "axes.X.mechanics.couplings.load.stiffness=-1 N/m")
    assert result.exit_code == 2
    assert "--set axes.X.mechanics.couplings.load.stiffness" in result.stderr
    result = run("modal", P5M4S, "--set", "no-equals-sign")
    assert result.exit_code == 2 and "KEY=VALUE" in result.stderr


def test_unknown_axis_and_unwritable_plot(tmp_path):
    result = run("modal", P5M4S, "--axis", "Y")
    assert result.exit_code == 2 and "unknown axis 'Y'" in result.stderr and P5M4S in result.stderr
    result = run("modal", P5M4S, "--plot", str(tmp_path / "missing" / "m.png"))
    assert result.exit_code == 2 and "does not exist" in result.stderr


def test_installed_program_exit_status_and_no_traceback(tmp_path):
    model = tmp_path / "not.toml"
    model.write_text("[axes.X.mechanics\n")
    proc = subprocess.run([sys.executable, "-m", "sicomat.cli.main", "modal", str(model), "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert "not a valid TOML file" in proc.stderr and "Traceback" not in proc.stderr


def test_simulate_json_contract(tmp_path):
    out = tmp_path / "run.csv"
    result = run("simulate", P5M4S, "--move", "5", "--duration", "0.3", "--json", "--out", str(out))
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    for key in ("max_following_error", "rms_following_error", "final_error", "overshoot_percent", "samples",
                "wall_time_s"):
        assert key in payload
    assert payload["samples"] == round(0.3 / 125e-6)
    assert payload["max_following_error"] >= payload["rms_following_error"] > 0
    header = out.read_text().splitlines()[0].split(",")
    assert "following_error" in header and "load.x" in header and "friction.motor" in header
    assert [p.name for p in tmp_path.iterdir()] == ["run.csv"]


@pytest.mark.parametrize("args,needle", [
    (["--set", "axes.X.controller.position_period=0.3 ms"], "whole multiple"),
    (["--set", "axes.X.controller.Kv=-2"], "axes.X.controller.Kv"),
    (["--set", "axes.X.controller.position_delay=500", "--duration", "0.2"], "not shorter than the run"),
    (["--set", "axes.X.mechanics.sensors.scale.body=ghost"], "unknown body 'ghost'"),
    (["--set", "axes.X.controller.velocity_sensor=nowhere"], "unknown sensor 'nowhere'"),
    (["--step", "1", "--move", "2"], "either --step or --move"),
])
def test_simulate_bad_input_exit_2(args, needle):
    result = run("simulate", P5M4S, *args)
    assert result.exit_code == 2, result.output
    assert needle in result.stderr and "Traceback" not in result.output


def test_simulate_model_without_actuator(tmp_path):
    model = tmp_path / "m.toml"
    model.write_text('[axes.X.mechanics]\ntype = "lumped"\n[axes.X.mechanics.bodies.a]\nmass = 1\n'
                     '[axes.X.mechanics.frictions.f]\nbetween = ["a", "ground"]\nviscous = 1\n'
                     '[axes.X.mechanics.sensors.s]\nbody = "a"\n'
                     '[axes.X.drive]\nforce_constant = 1\ntime_constant = 0.001\n'
                     '[axes.X.controller]\nposition_sensor = "s"\nKv = 1\nKp = 1\nTi = 1\n')
    result = run("simulate", str(model), "--step", "1")
    assert result.exit_code == 2 and "no actuator" in result.stderr


def test_tune_json_contract_and_written_model(tmp_path):
    tuned = tmp_path / "tuned.toml"
    result = run("tune", P5M4S, "--velocity-crossover", "125.6", "--velocity-phase-margin", "45",
                 "--position-phase-margin", "80", "--write", str(tuned), "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert set(payload["velocity"]) >= {"Kp", "Kp_normalized", "Ti"} and "Kv" in payload["position"]
    for key in ("velocity_phase_margin_deg", "velocity_crossover_rad_s", "position_phase_margin_deg",
                "position_crossover_rad_s", "gain_margin_db", "targets_met", "notch"):
        assert key in payload["achieved"]
    assert payload["equivalent_delay_s"] > 0 and payload["wall_time_s"] > 0
    assert set(payload["initial"]) == {"velocity", "position"}
    from sicomat import load_model

    written = load_model(tuned).axes["X"].controller
    # floats round-trip through TOML and JSON exactly: 1e-12 is slack
    assert written.Kp_normalized == pytest.approx(payload["velocity"]["Kp_normalized"], rel=1e-12)
    assert written.Kv == pytest.approx(payload["position"]["Kv"], rel=1e-12)


def test_margins_and_bode_json(tmp_path):
    result = run("margins", P5M4S, "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["velocity"]["phase_margin_deg"] is not None and payload["position"]["gain_margin_db"] > 0
    result = run("bode", P5M4S, "--loop", "position-closed", "--json", "--points", "50")
    assert result.exit_code == 0, result.output
    frf = json.loads(result.stdout)
    assert frf["loop"] == "position-closed" and len(frf["omega"]) == len(frf["magnitude_db"])
    result = run("bode", P5M4S, "--loop", "nonsense")
    assert result.exit_code == 2 and "unknown loop" in result.stderr
    result = run("tune", P5M4S, "--velocity-crossover", "1e9")
    assert result.exit_code == 2 and "Nyquist" in result.stderr


def test_step_command_is_the_manual_time_approach(tmp_path):
    from sicomat.servo.loop import build_servo_loop
    from sicomat.frequency.loops import LoopAnalysis
    from sicomat.tuning.time import velocity_step

    result = run("step", P5M4S, "--loop", "velocity", "--Kp", "120", "--Ti", "0.02", "--json",
                 "--plot", str(tmp_path / "step.png"))
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    loop = build_servo_loop(sicomat_load(P5M4S))
    expected = velocity_step(LoopAnalysis.of(loop), 120 * loop.m_rigid, 0.02)
    # the same computation in-process and through the CLI: rounding only
    assert payload["overshoot_percent"] == pytest.approx(expected.overshoot_percent, rel=1e-9)
    assert payload["Kp_normalized"] == pytest.approx(120.0)
    # with Ti large (the method's first step) a larger proportional gain gives more overshoot
    low = json.loads(run("step", P5M4S, "--Kp", "200", "--Ti", "0.5", "--json").stdout)
    high = json.loads(run("step", P5M4S, "--Kp", "500", "--Ti", "0.5", "--json").stdout)
    assert high["overshoot_percent"] > low["overshoot_percent"]
    assert run("step", P5M4S, "--loop", "torque").exit_code == 2


def sicomat_load(path):
    from sicomat import load_model

    return load_model(path)
