"""The component catalogue (issue 12, §1-2): schemas, shipped entries, user folders, filters, `sicomat catalog`."""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sicomat.description.parts import KINDS, BallScrewParameters, MotorParameters, unit_of
from sicomat.catalogue.store import ENV, load_catalogue, parse_condition, shipped_folder
from sicomat.cli.main import app
from sicomat.errors import ModelError

runner = CliRunner()
CONTRACT_KINDS = ["motor", "linear-motor", "coupling", "gearbox", "belt", "ball-screw", "rack-pinion", "guide",
                  "table", "encoder", "scale"]

MOTOR = """kind = "motor"
description = "{description}"

[parameters]
rotor_inertia = "{inertia}"

[provenance]
source = "typical"
range = "+-10 %"
"""


def motor_file(folder: Path, id: str, inertia: str = "1 kg*cm^2", description: str = "user motor",
               sub: str = "motor") -> Path:
    (folder / sub).mkdir(parents=True, exist_ok=True)
    path = folder / sub / f"{id}.toml"
    path.write_text(MOTOR.format(inertia=inertia, description=description))
    return path


@pytest.fixture(autouse=True)
def _no_user_catalogue(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)


# --------------------------------------------------------------------------- schemas and shipped data
def test_kind_strings_are_the_contract():
    assert list(KINDS) == CONTRACT_KINDS


def test_ball_screw_axis_parameter_names_are_the_contract():
    names = {"motor": {"rotor_inertia"}, "coupling": {"torsional_stiffness", "inertia"},
             "ball-screw": {"lead", "root_diameter", "diameter", "length", "mounting", "nut_stiffness",
                            "bearing_stiffness", "density", "youngs_modulus", "shear_modulus"},
             "table": {"mass"}}
    for kind, wanted in names.items():
        assert wanted <= set(KINDS[kind].model_fields), kind


def test_every_shipped_entry_loads_and_validates():
    catalogue = load_catalogue()
    assert len(catalogue) >= 60
    assert len({e.kind for e in catalogue}) >= 8
    for entry in catalogue:
        assert isinstance(entry.parameters, KINDS[entry.kind])
        assert entry.provenance.source in ("datasheet", "typical")
        if entry.provenance.source == "typical":
            assert entry.provenance.range.strip()


def test_shipped_motors_are_self_consistent():
    # a sinusoidal PM motor with kT per A rms and kE line-to-line rms: kT = sqrt(3) kE (power balance
    # 3 E_ph I = T w); the stall point I0 kT = M0. The files state both to 4-5 significant digits: 1e-3.
    # (the typical entries, written to satisfy them; datasheet entries state only what their document
    # states and are checked within the datasheet tolerance below)
    motors = [e.parameters for e in load_catalogue() if e.kind == "motor" and e.provenance.source == "typical"]
    assert motors
    for m in motors:
        assert isinstance(m, MotorParameters)
        assert m.torque_constant_basis == "rms" and m.back_emf_basis == "line-to-line-rms"
        assert m.torque_constant is not None and m.back_emf_constant is not None
        assert math.isclose(m.torque_constant, math.sqrt(3) * m.back_emf_constant, rel_tol=1e-3)
        assert m.stall_current is not None and m.stall_torque is not None
        assert math.isclose(m.stall_current * m.torque_constant, m.stall_torque, rel_tol=1e-3)
        # no-load back-EMF at max speed (peak, line to line) below the bus
        assert m.max_speed is not None and m.dc_bus is not None
        assert math.sqrt(2) * m.back_emf_constant * m.max_speed < m.dc_bus


def test_shipped_files_are_package_data_read_through_importlib_resources():
    folder = resources.files("sicomat.catalogue") / "data"
    kinds = {item.name for item in folder.iterdir() if item.is_dir()}
    assert kinds <= set(CONTRACT_KINDS) and len(kinds) >= 8
    text = (folder / "ball-screw" / "ball-screw-32x10-l1000.toml").read_text()
    assert 'kind = "ball-screw"' in text
    assert str(shipped_folder()) == str(folder)
    pyproject = (Path(__file__).resolve().parents[1] / "pyproject.toml").read_text()
    assert '"catalogue/data/*/*.toml"' in pyproject
    assert all(p.parent.parent.name == "data" for p in Path(str(folder)).rglob("*.toml"))   # one level: the glob


def test_quantities_with_units_and_explicit_conventions():
    screw = BallScrewParameters(lead="10 mm/rev", diameter="32 mm", root_diameter="27 mm", length="1.2 m",
                                mounting="fixed-supported")
    assert math.isclose(screw.lead, 0.010, rel_tol=1e-14)
    assert BallScrewParameters(lead="10 mm", diameter=0.032, root_diameter=0.027, length=1.2,
                               mounting="fixed-fixed").lead == 0.010
    assert (screw.density, screw.youngs_modulus, screw.shear_modulus) == (7850.0, 2.06e11, 7.9e10)
    with pytest.raises(ValueError, match="torque_constant_basis"):
        MotorParameters(rotor_inertia=1e-4, torque_constant=1.0)
    with pytest.raises(ValueError, match="root_diameter"):
        BallScrewParameters(lead=0.01, diameter=0.02, root_diameter=0.025, length=1, mounting="fixed-fixed")
    assert unit_of("gearbox", "torsional_stiffness").si == "N*m/rad"


# --------------------------------------------------------------------------- user folders
def test_user_entries_extend_and_shadow_shipped_ones(tmp_path, monkeypatch):
    shipped = load_catalogue().get("servo-motor-400v-11nm")
    mine = tmp_path / "mine"
    motor_file(mine, "servo-motor-400v-11nm", inertia="99 kg*cm^2", description="mine")
    motor_file(mine, "my-motor", inertia="2 kg*cm^2")
    catalogue = load_catalogue([mine])
    assert catalogue.get("servo-motor-400v-11nm").parameters.rotor_inertia == pytest.approx(99e-4, rel=1e-14)
    assert shipped.parameters.rotor_inertia != pytest.approx(99e-4)
    assert catalogue.get("my-motor").kind == "motor"
    assert len(catalogue) == len(load_catalogue()) + 1
    # the environment variable does the same; the explicit folder wins over it
    other = tmp_path / "env"
    motor_file(other, "my-motor", inertia="3 kg*cm^2")
    monkeypatch.setenv(ENV, str(other))
    assert load_catalogue().get("my-motor").parameters.rotor_inertia == pytest.approx(3e-4, rel=1e-14)
    assert load_catalogue([mine]).get("my-motor").parameters.rotor_inertia == pytest.approx(2e-4, rel=1e-14)


def test_duplicate_id_in_a_user_folder(tmp_path):
    motor_file(tmp_path, "twin", sub="a")
    motor_file(tmp_path, "twin", sub="b")
    with pytest.raises(ModelError, match="duplicate catalogue id") as info:
        load_catalogue([tmp_path])
    assert info.value.value == "twin" and str(tmp_path) in str(info.value.source)


@pytest.mark.parametrize("text, path, problem", [
    (MOTOR.replace('rotor_inertia = "{inertia}"', 'rotor_inertia = "2 kg"'), "parameters.rotor_inertia",
     "moment of inertia"),
    (MOTOR.replace('rotor_inertia = "{inertia}"', 'rotor_inertia = 1e-4\nrotor_inertai = 1'),
     "parameters.rotor_inertai", "unknown key"),
    (MOTOR.replace('rotor_inertia = "{inertia}"', ''), "parameters.rotor_inertia", "missing required key"),
    (MOTOR.replace('source = "typical"', 'source = "guess"'), "provenance.source", "datasheet"),
    (MOTOR.replace('range = "+-10 %"', ''), "provenance.range", "missing required key"),
    (MOTOR.replace('kind = "motor"', 'kind = "motorr"'), "kind", "expected a kind"),
])
def test_bad_entry_is_located(tmp_path, text, path, problem):
    (tmp_path / "x.toml").write_text(text.format(inertia="1 kg*cm^2", description="d"))
    with pytest.raises(ModelError) as info:
        load_catalogue([tmp_path])
    assert info.value.source == str(tmp_path / "x.toml")
    assert info.value.path == path
    assert problem in info.value.message


def test_entry_in_the_folder_of_another_kind(tmp_path):
    motor_file(tmp_path, "misplaced", sub="coupling")
    with pytest.raises(ModelError, match="folder of kind coupling"):
        load_catalogue([tmp_path])


def test_unknown_id_suggests_the_closest():
    with pytest.raises(ModelError) as info:
        load_catalogue().get("servo-motor-400v-11")
    assert "servo-motor-400v-11nm" in info.value.message and info.value.value == "servo-motor-400v-11"


# --------------------------------------------------------------------------- filters
def test_filters_compare_si_values_with_units():
    catalogue = load_catalogue()
    in_nm = {e.id for e in catalogue.select("motor", ["peak_torque >= 10 N*m"])}
    in_ncm = {e.id for e in catalogue.select("motor", ["peak_torque >= 1000 N*cm"])}
    assert in_nm == in_ncm
    motors = [e for e in catalogue if e.kind == "motor"]
    assert in_nm == {e.id for e in motors if e.parameters.peak_torque is not None   # type: ignore[attr-defined]
                     and e.parameters.peak_torque >= 10.0}                          # type: ignore[attr-defined]
    assert 0 < len(in_nm) < len(motors)
    # leads in mm; a word compared with ==; filters combine (and)
    screws = catalogue.select("ball-screw", ["lead > 5 mm", "mounting == fixed-fixed"])
    assert screws and all(e.parameters.lead > 0.005 and e.parameters.mounting == "fixed-fixed"  # type: ignore[attr-defined]
                          for e in screws)
    # without a kind: only the kinds that have the parameter
    assert {e.kind for e in catalogue.select(None, ["torsional_stiffness > 0"])} == {"coupling", "gearbox"}
    fine = catalogue.select("encoder", ["resolution >= 1000000"])
    assert {e.id for e in fine} == {"encoder-absolute-20bit", "encoder-absolute-23bit", "encoder-sincos-2048-interpolated"}
    assert parse_condition("max_speed >= 3000 rpm", ["motor"]).values["motor"] == pytest.approx(100 * math.pi)


@pytest.mark.parametrize("expr, problem", [
    ("peak_torque >= 10 kg", "expected a torque"),
    ("peak_torque >= 10 furlongs_per_blip", "unknown unit"),
    ("peak_torq >= 10 N*m", "closest: peak_torque"),
    ("peak_torque ~ 10 N*m", "OPERATOR"),
    ("peak_torque >=", "missing the value"),
    ("mounting > fixed", "compare it with == or !="),
    ("lead >= ten mm", "unknown unit"),
])
def test_bad_filters(expr, problem):
    with pytest.raises(ModelError) as info:
        load_catalogue().select("motor" if "torq" in expr else "ball-screw", [expr])
    assert problem in info.value.message and info.value.source == "--where"


# --------------------------------------------------------------------------- the CLI
def test_cli_list_json_keys():
    result = runner.invoke(app, ["catalog", "list", "motor", "--where", "peak_torque >= 10 N*m", "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert list(payload) == ["items"]
    assert payload["items"] and all(item["kind"] == "motor" and item["parameters"]["peak_torque"] >= 10
                                    for item in payload["items"])
    assert {"id", "kind"} <= set(payload["items"][0])


def test_cli_show_json_keys_and_user_folder(tmp_path):
    motor_file(tmp_path, "servo-motor-400v-11nm", inertia="99 kg*cm^2")
    result = runner.invoke(app, ["catalog", "show", "servo-motor-400v-11nm", "--catalog", str(tmp_path), "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert {"id", "kind", "parameters", "provenance"} <= set(payload)
    assert payload["id"] == "servo-motor-400v-11nm" and payload["kind"] == "motor"
    assert payload["parameters"]["rotor_inertia"] == pytest.approx(99e-4, rel=1e-14)
    assert payload["provenance"] == {"source": "typical", "range": "+-10 %"}


def test_cli_tables():
    assert runner.invoke(app, ["catalog", "list", "ball-screw"]).exit_code == 0
    result = runner.invoke(app, ["catalog", "show", "belt-at10-25mm"])
    assert result.exit_code == 0 and "specific_stiffness" in result.stdout


@pytest.mark.parametrize("args, needle", [
    (["catalog", "show", "ball-screw-32x10"], "closest: "),
    (["catalog", "list", "motorz"], "KIND"),
    (["catalog", "list", "--where", "peak_torque >= 10 kg"], "--where"),
    (["catalog", "list", "--catalog", "/no/such/folder"], "--catalog"),
    (["catalog", "show"], "ID"),
])
def test_cli_bad_input_is_one_line_exit_2(args, needle):
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert needle in result.output and "Traceback" not in result.output


def test_cli_duplicate_in_user_folder_exit_2(tmp_path):
    motor_file(tmp_path, "twin", sub="a")
    motor_file(tmp_path, "twin", sub="b")
    result = runner.invoke(app, ["catalog", "list", "--catalog", str(tmp_path)])
    assert result.exit_code == 2 and "duplicate catalogue id" in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_environment_folder_that_is_not_one(tmp_path, monkeypatch):
    monkeypatch.setenv(ENV, str(tmp_path / "missing"))
    result = runner.invoke(app, ["catalog", "list"])
    assert result.exit_code == 2 and result.output.startswith(f"error: {ENV}: not a folder")


def test_a_link_loop_in_a_user_folder_is_one_error(tmp_path):
    motor_file(tmp_path, "m")
    (tmp_path / "motor" / "loop").symlink_to(tmp_path, target_is_directory=True)
    with pytest.raises(ModelError, match="nest more than"):
        load_catalogue([tmp_path])
