"""``sicomat --catalog DIR``: a user folder that model files' part ids are looked up in (after the shipped
catalogue and SICOMAT_CATALOG), and what a drive-chain drive needs when the motor has no torque constant."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from sicomat.cli.main import app

EXAMPLE = str(Path(__file__).resolve().parents[1] / "examples" / "ballscrew_catalog.toml")
runner = CliRunner()


def _motor(folder: Path, inertia: str, torque_constant: bool = True) -> None:
    folder.mkdir(exist_ok=True)
    lines = ['kind = "motor"', "[parameters]", f'rotor_inertia = "{inertia}"']
    if torque_constant:
        lines += ['torque_constant = "1.6 N*m/A"', 'torque_constant_basis = "rms"']
    lines += ["[provenance]", 'source = "typical"', 'range = "a test entry"']
    (folder / "servo-motor-400v-6nm.toml").write_text("\n".join(lines) + "\n")


def _first_mode(*args: str) -> float:
    result = runner.invoke(app, [*args, "modal", EXAMPLE, "--json"])
    assert result.exit_code == 0, result.output
    return [f for f in json.loads(result.stdout)["undamped_hz"] if f > 0][0]


def test_a_catalog_folder_shadows_the_shipped_motor_in_a_model(tmp_path, monkeypatch):
    monkeypatch.delenv("SICOMAT_CATALOG", raising=False)
    shipped = _first_mode()
    _motor(tmp_path / "parts", "70 kg*cm^2")              # ten times the shipped rotor inertia
    heavier = _first_mode("--catalog", str(tmp_path / "parts"))
    # a heavier rotor behind the same coupling and screw lowers the first (motor-against-table) mode
    assert heavier < shipped
    assert _first_mode() == shipped                      # the option does not stick to later runs


def test_a_missing_catalog_folder_and_a_motor_without_torque_constant_are_one_line_errors(tmp_path):
    result = runner.invoke(app, ["--catalog", str(tmp_path / "nowhere"), "modal", EXAMPLE])
    assert result.exit_code == 2 and "--catalog" in result.output and "nowhere" in result.output
    _motor(tmp_path / "parts", "7 kg*cm^2", torque_constant=False)
    result = runner.invoke(app, ["--catalog", str(tmp_path / "parts"), "modal", EXAMPLE])
    assert result.exit_code == 2
    assert "axes.X.drive.force_constant" in result.output and "torque_constant" in result.output
