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
