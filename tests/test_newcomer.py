"""A newcomer's path (issue 10 §6): version, help that shows every choice, JSON names as the model
file's, one unit rule, tables that never cut numbers, labelled plots, a README that runs."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sicomat.cli.main import _LOOP_NAMES, app

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
P5M4S = str(EXAMPLES / "paper_5m4s.toml")
runner = CliRunner()


def run(*args: str, **kwargs):
    return runner.invoke(app, list(args), **kwargs)


def test_version_is_the_packages_version():
    expected = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    result = run("--version")
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == f"sicomat {expected}"
    payload = json.loads(run("version", "--json").stdout)
    assert payload["sicomat"] == expected and "numpy" in payload and "python" in payload


def test_bode_help_lists_every_loop_at_80_columns():
    result = run("bode", "--help", env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    for name in _LOOP_NAMES:
        assert name in result.stdout, name


@pytest.mark.parametrize("command", ["check", "modal", "simulate", "bode", "margins", "tune", "circle",
                                     "reduce", "step", "version"])
def test_no_help_text_is_cut_at_80_columns(command):
    result = run(command, "--help", env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    assert "…" not in result.stdout, result.stdout


def _with_gains(tmp_path: Path, name: str, Kp: float, Ti: float, Kv: float) -> str:
    """The 5M4S model file with the controller's gains replaced, ``Kp`` in physical units as the file takes it."""
    text = Path(P5M4S).read_text()
    lines = []
    for line in text.splitlines():
        key = line.split("=")[0].strip()
        if key == "Kp_normalized":
            line = f"Kp = {Kp!r}"
        elif key == "Ti":
            line = f"Ti = {Ti!r}"
        elif key == "Kv":
            line = f"Kv = {Kv!r}"
        lines.append(line)
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.mark.parametrize("method", ["frequency", "time"])
def test_tuned_gains_pasted_into_a_model_file_give_the_tuned_loop(tmp_path, method):
    # issue 10: tune --json's "Kp" was the normalised gain, the model file's "Kp" the physical one, so a
    # pasted value gave a -82 deg phase margin. The same gains must give the same margins: the only
    # difference between the two files is the decimal round trip of Kp (exact for repr) and Kp = Kp_n * m
    # (one rounding, 1e-16 relative), far below the 1e-6 deg compared here.
    tuned = tmp_path / "tuned.toml"
    result = run("tune", P5M4S, "--method", method, "--write", str(tuned), "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    v, p = payload["velocity"], payload["position"]
    pasted = _with_gains(tmp_path, "pasted.toml", v["Kp"], v["Ti"], p["Kv"])
    reference = json.loads(run("margins", str(tuned), "--json").stdout)
    got = json.loads(run("margins", pasted, "--json").stdout)
    for loop in ("velocity", "position"):
        assert got[loop]["phase_margin_deg"] == pytest.approx(reference[loop]["phase_margin_deg"], abs=1e-6)
    from sicomat import load_model

    assert load_model(tuned).axes["X"].controller.Kp_normalized == pytest.approx(v["Kp_normalized"], rel=1e-12)


def test_step_json_names_gains_as_the_model_file():
    from sicomat import load_model
    from sicomat.loop import build_servo_loop

    loop = build_servo_loop(load_model(P5M4S))
    payload = json.loads(run("step", P5M4S, "--Kp-normalized", "120", "--json").stdout)
    assert payload["Kp_normalized"] == pytest.approx(120.0)
    assert payload["Kp"] == pytest.approx(120.0 * loop.m_rigid, rel=1e-12)  # physical, as the file's Kp
    old_name = json.loads(run("step", P5M4S, "--Kp", "120", "--json").stdout)
    assert old_name["Kp_normalized"] == payload["Kp_normalized"]
