"""sicomat.io.modelfile: loading, overrides, saving and the error messages of model files."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

from sicomat import (Machine, ModelError, dump_model, load_model, machine_from_dict, save_model,
                     with_overrides)
from sicomat.io.modelfile import parse_override

EXAMPLES_DIR = Path(__file__).resolve().parents[1] / "examples"
EXAMPLE_FILES = sorted(EXAMPLES_DIR.glob("*.toml"))


# --------------------------------------------------------------------------- examples and round trip
def test_there_are_examples():
    assert len(EXAMPLE_FILES) >= 4


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.name)
def test_every_example_loads(path):
    machine = load_model(path)
    assert isinstance(machine, Machine)
    assert machine.axes


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.name)
def test_round_trip(path, tmp_path):
    machine = load_model(path)
    target = tmp_path / "copy.toml"
    assert save_model(machine, target) == target
    again = load_model(target)
    assert again == machine
    assert dump_model(again) == dump_model(machine)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.toml"]   # no temp file left


def test_units_are_parsed_to_si():
    machine = load_model(EXAMPLES_DIR / "ballscrew_3m2s.toml")
    mech = machine.axis().mechanics
    # unit conversions by pint: a few roundings each
    assert_allclose(mech.bodies["motor"].inertia, 23e-4, rtol=1e-12)                 # 23 kg*cm^2
    assert_allclose(mech.couplings["screw_nut"].ratios[0], 0.010 / (2 * 3.141592653589793), rtol=1e-12)


# --------------------------------------------------------------------------- overrides
def test_override_with_units():
    machine = load_model(EXAMPLES_DIR / "paper_5m4s.toml",
                         ["axes.X.mechanics.bodies.load.mass=300 kg"])
    assert machine.axes["X"].mechanics.bodies["load"].mass == 300.0
    # the rest is unchanged
    original = load_model(EXAMPLES_DIR / "paper_5m4s.toml")
    assert machine.axes["X"].mechanics.bodies["primary"] == original.axes["X"].mechanics.bodies["primary"]


def test_override_with_toml_number_and_grams():
    machine = load_model(EXAMPLES_DIR / "paper_5m4s.toml",
                         ["axes.X.mechanics.bodies.load.mass=250",
                          "axes.X.mechanics.bodies.scale_head.mass=12 g"])
    bodies = machine.axes["X"].mechanics.bodies
    assert bodies["load"].mass == 250.0
    assert_allclose(bodies["scale_head"].mass, 0.012, rtol=1e-12)          # "12 g" by pint: one rounding


@pytest.mark.parametrize("item", ["axes.X.mechanics.bodies.load.mass=-3 kg",
                                  "axes.X.mechanics.bodies.load.mass=3 m",
                                  "axes.X.mechanics.bodies.load.masss=3"])
def test_bad_override_raises_model_error_mentioning_set(item):
    with pytest.raises(ModelError) as info:
        load_model(EXAMPLES_DIR / "paper_5m4s.toml", [item])
    text = str(info.value)
    assert "--set" in text
    assert "axes.X.mechanics.bodies.load" in text


def test_override_without_equal_sign():
    with pytest.raises(ModelError, match="--set"):
        parse_override("axes.X.mechanics.bodies.load.mass")


def test_with_overrides_in_python():
    machine = machine_from_dict({"axes": {"X": {"mechanics": {"type": "chain", "masses": [1, 2],
                                                              "stiffnesses": [10]}}}})
    changed = with_overrides(machine, {"axes.X.mechanics.masses.1": "3 kg"})
    assert changed.axes["X"].mechanics.masses == [1.0, 3.0]
    assert machine.axes["X"].mechanics.masses == [1.0, 2.0]           # the original is unchanged


# --------------------------------------------------------------------------- errors
BASE = """\
name = "bad"

[axes.X.mechanics]
type = "lumped"

[axes.X.mechanics.bodies.a]
mass = 2.0

[axes.X.mechanics.bodies.b]
mass = 3.0

[axes.X.mechanics.couplings.k]
between = ["a", "b"]
stiffness = 100.0

[axes.X.mechanics.actuators.motor]
body = "a"
"""

EXTRA_BODY = "\n[axes.X.mechanics.bodies.c]\nmass = 1.0\n"
EXTRA_PAIR = EXTRA_BODY + """
[axes.X.mechanics.bodies.d]
mass = 1.0

[axes.X.mechanics.couplings.k2]
between = ["c", "d"]
stiffness = 5.0
"""

# (id, file text, key path expected in the message, value expected in the message or None)
ERROR_CASES = [
    ("body-without-mass", BASE.replace("mass = 2.0\n", ""), "axes.X.mechanics.bodies.a", None),
    ("coupling-without-between", BASE.replace('between = ["a", "b"]\n', ""),
     "axes.X.mechanics.couplings.k.between", None),
    ("mass-bool", BASE.replace("mass = 2.0", "mass = true"), "axes.X.mechanics.bodies.a.mass", "True"),
    ("mass-list", BASE.replace("mass = 2.0", "mass = [1]"), "axes.X.mechanics.bodies.a.mass", "[1]"),
    ("mass-negative", BASE.replace("mass = 2.0", "mass = -2.5"), "axes.X.mechanics.bodies.a.mass", "-2.5"),
    ("mass-zero", BASE.replace("mass = 2.0", 'mass = "0 kg"'), "axes.X.mechanics.bodies.a.mass", "0 kg"),
    ("stiffness-negative", BASE.replace("stiffness = 100.0", "stiffness = -100.0"),
     "axes.X.mechanics.couplings.k.stiffness", "-100.0"),
    ("unknown-unit", BASE.replace("mass = 2.0", 'mass = "3 kgg"'), "axes.X.mechanics.bodies.a.mass",
     "3 kgg"),
    ("wrong-dimension", BASE.replace("mass = 2.0", 'mass = "3 m"'), "axes.X.mechanics.bodies.a.mass",
     "3 m"),
    ("stiffness-wrong-dimension", BASE.replace("stiffness = 100.0", 'stiffness = "3 kg"'),
     "axes.X.mechanics.couplings.k.stiffness", "3 kg"),
    ("unknown-body", BASE.replace('between = ["a", "b"]', 'between = ["a", "zed"]'),
     "axes.X.mechanics.couplings.k.between", "zed"),
    ("actuator-unknown-body", BASE.replace('body = "a"', 'body = "zed"'),
     "axes.X.mechanics.actuators.motor.body", "zed"),
    ("body-linked-to-nothing", BASE + EXTRA_BODY, "axes.X.mechanics.bodies.c", "c"),
    ("two-groups", BASE + EXTRA_PAIR, "axes.X.mechanics.bodies.c", "d"),
    ("typo", BASE.replace("stiffness = 100.0", "stifness = 100.0"),
     "axes.X.mechanics.couplings.k.stifness", "100.0"),
    ("unknown-top-key", BASE.replace('name = "bad"', 'nmae = "bad"'), "nmae", "bad"),
    ("unknown-mechanics-type", BASE.replace('type = "lumped"', 'type = "lumpy"'),
     "axes.X.mechanics", "lumpy"),
    ("no-mechanics-type", BASE.replace('type = "lumped"\n', ""), "axes.X.mechanics", None),
    ("chain-lengths", 'name = "c"\n[axes.X.mechanics]\ntype = "chain"\nmasses = [1, 2, 3]\n'
                      'stiffnesses = [10]\n', "axes.X.mechanics.stiffnesses", "[10.0]"),
    ("bad-body-name", BASE.replace("bodies.b]", "bodies.2b]").replace('["a", "b"]', '["a", "2b"]'),
     "axes.X.mechanics.bodies", "2b"),
    ("mass-string-without-unit", BASE.replace("mass = 2.0", 'mass = "150"'), "axes.X.mechanics.bodies.a.mass",
     "150"),
    ("mass-integer-beyond-float", BASE.replace("mass = 2.0", "mass = 1" + "0" * 400),
     "axes.X.mechanics.bodies.a.mass", None),
    ("nested-too-deep", BASE.replace("mass = 2.0", "mass = " + "[" * 40 + "]" * 40),
     "axes.X.mechanics.bodies.a.mass", None),
    ("torque-for-a-stiffness", BASE.replace("stiffness = 100.0", 'stiffness = "3 kg*rad/s^2"'),
     "axes.X.mechanics.couplings.k.stiffness", None),
    # a sensor's body that is not a name, with a resolution to parse (was a TypeError, found by mypy)
    ("sensor-body-a-list", BASE + '\n[axes.X.mechanics.sensors.s]\nbody = ["a"]\nresolution = "1 um"\n',
     "axes.X.mechanics.sensors.s.body", None),
]


@pytest.mark.parametrize(("text", "key_path", "value"), [c[1:] for c in ERROR_CASES],
                         ids=[c[0] for c in ERROR_CASES])
def test_model_errors_name_file_path_and_value(tmp_path, text, key_path, value):
    path = tmp_path / "bad_model.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ModelError) as info:
        load_model(path)
    message = str(info.value)
    assert str(path) in message
    assert key_path in message
    assert info.value.path is not None and info.value.path.startswith(key_path)
    if value is not None:
        assert value in message
    assert isinstance(info.value, ValueError)


def test_base_model_is_valid(tmp_path):
    # the error cases above differ from a valid file by one edit
    path = tmp_path / "good.toml"
    path.write_text(BASE, encoding="utf-8")
    assert load_model(path).axes["X"].mechanics.bodies["a"].mass == 2.0


def test_not_toml(tmp_path):
    path = tmp_path / "garbage.toml"
    path.write_text("this is [not toml\n", encoding="utf-8")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(path) in str(info.value)
    assert "TOML" in str(info.value)


def test_not_utf8(tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_a_byte_order_mark_is_dropped(tmp_path):
    """A model, study or catalogue file that a Windows editor saved with a UTF-8 byte-order mark reads as the
    same file without it (tomllib refuses the mark: "Invalid statement (at line 1, column 1)")."""
    from sicomat.catalogue.store import load_catalogue
    from sicomat.studies.spec import load_study

    bom = b"\xef\xbb\xbf"
    source = EXAMPLES_DIR / "paper_5m4s.toml"
    marked = tmp_path / "paper_5m4s.toml"
    marked.write_bytes(bom + source.read_bytes())
    assert dump_model(load_model(marked)) == dump_model(load_model(source))
    study = tmp_path / "study.toml"
    study.write_bytes(bom + b'base = "paper_5m4s.toml"\nanalyses = ["modal"]\n[[parameters]]\n'
                            b'path = "axes.X.mechanics.bodies.load.mass"\nvalues = ["200 kg"]\n')
    spec, base = load_study(study)
    assert spec.analyses == ["modal"] and base == tmp_path / "paper_5m4s.toml"
    parts = tmp_path / "parts"
    parts.mkdir()
    (parts / "motor-with-bom.toml").write_bytes(
        bom + b'kind = "motor"\n[parameters]\nrotor_inertia = "7 kg*cm^2"\ntorque_constant = "1.6 N*m/A"\n'
              b'torque_constant_basis = "rms"\n[provenance]\nsource = "typical"\nrange = "a test entry"\n')
    assert load_catalogue([parts], environment=False).get("motor-with-bom").kind == "motor"


def test_missing_file(tmp_path):
    path = tmp_path / "does_not_exist.toml"
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_machine_from_dict_without_source():
    with pytest.raises(ModelError) as info:
        machine_from_dict({"axes": {"X": {"mechanics": {"type": "chain", "masses": [-1]}}}})
    assert "axes.X.mechanics.masses.0" in str(info.value)
    assert "-1" in str(info.value)


# --------------------------------------------------------------------------- atomic save
def test_save_model_is_atomic(tmp_path, monkeypatch):
    machine = load_model(EXAMPLES_DIR / "paper_5m4s.toml")
    target = tmp_path / "model.toml"
    target.write_text("# the previous content\n", encoding="utf-8")

    def failing_replace(src, dst, *args, **kwargs):
        raise OSError("disk on fire")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk on fire"):
        save_model(machine, target)
    monkeypatch.undo()
    assert target.read_text(encoding="utf-8") == "# the previous content\n"
    assert [p.name for p in tmp_path.iterdir()] == ["model.toml"]


def test_save_model_overwrites(tmp_path):
    target = tmp_path / "model.toml"
    target.write_text("# old\n", encoding="utf-8")
    machine = load_model(EXAMPLES_DIR / "paper_2m1s.toml")
    save_model(machine, target)
    assert load_model(target) == machine
    assert [p.name for p in tmp_path.iterdir()] == ["model.toml"]


def test_overrides_copy_only_their_path_and_never_touch_the_input():
    from sicomat.io.modelfile import _set_path

    data = {"a": {"b": [1, {"c": 2}], "d": {"e": 3}}, "f": 4}
    out = _set_path(data, "a.b.1.c", 5, source="test")
    assert out == {"a": {"b": [1, {"c": 5}], "d": {"e": 3}}, "f": 4}
    assert data == {"a": {"b": [1, {"c": 2}], "d": {"e": 3}}, "f": 4}
    new = _set_path(data, "a.x.y", 6, source="test")            # missing tables are created
    assert new["a"]["x"] == {"y": 6} and "x" not in data["a"]
    with pytest.raises(ModelError, match="not a table"):
        _set_path(data, "f.g.h", 1, source="test")
    assert data["f"] == 4


def test_overrides_are_validated_together_and_an_error_names_the_closest_one():
    path = EXAMPLES_DIR / "paper_5m4s.toml"      # gives velocity_delay = 1 explicitly
    loop_first = ["axes.X.controller.velocity_loop=continuous", "axes.X.controller.velocity_delay=0"]
    for order in (loop_first, loop_first[::-1]):
        assert load_model(path, order).axes["X"].controller.velocity_loop == "continuous"
    with pytest.raises(ModelError) as err:       # the delay left at 1: the error sits at velocity_delay
        load_model(path, ["axes.X.mechanics.bodies.load.mass=300 kg", "axes.X.controller.velocity_loop=continuous"])
    assert err.value.source == "--set axes.X.controller.velocity_loop=continuous"
    assert err.value.path == "axes.X.controller.velocity_delay"


# --------------------------------------------------------------------------- servo blocks
RIGID = (EXAMPLES_DIR / "rigid_1m.toml").read_text(encoding="utf-8")


@pytest.mark.parametrize("old, new, key_path", [
    ('Kp_normalized = "240 1/s"', "Kp_normalized = 0", "axes.X.controller.Kp_normalized"),
    ('Kp_normalized = "240 1/s"', "Kp_normalized = -3", "axes.X.controller.Kp_normalized"),
    ('Kp_normalized = "240 1/s"', "Kp = 0", "axes.X.controller.Kp"),
    ('Kv = "78.5 1/s"', "Kv = 0", "axes.X.controller.Kv"),
    ('Ti = "4.32 ms"', "Ti = 0", "axes.X.controller.Ti"),
    ('Kv = "78.5 1/s"', 'Kv = "12 Hz"', "axes.X.controller.Kv"),            # cycles or radians?
    ('bandwidth = "1000 Hz"', 'bandwidth = "60000 rpm"', "axes.X.drive.bandwidth"),
    ('bandwidth = "1000 Hz"', "bandwidth = inf", "axes.X.drive.bandwidth"),
    ('position_period = "1 ms"', 'position_period = "1e6 s"', "axes.X.controller.position_period"),  # 8e9 Tv
    ('bandwidth = "1000 Hz"', 'time_constant = "1e-300 s"', "axes.X.drive.time_constant"),
    ('force_constant = "120 N/A"', "force_constant = nan", "axes.X.drive.force_constant"),
    ('position_sensor = "scale"', 'position_sensor = "scale"\nvelocity_filter = {type = "low-pass", '
                                  'frequency = 500, damping = inf}', "axes.X.controller.velocity_filter.damping"),
])
def test_servo_values_outside_their_sense_are_refused(tmp_path, old, new, key_path):
    assert old in RIGID
    path = tmp_path / "servo.toml"
    path.write_text(RIGID.replace(old, new), encoding="utf-8")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert key_path in str(info.value) and str(path) in str(info.value)


def test_drive_bandwidth_in_rad_per_s_is_converted_to_hz(tmp_path):
    path = tmp_path / "servo.toml"
    path.write_text(RIGID.replace('bandwidth = "1000 Hz"', 'bandwidth = "6283.185307179586 rad/s"'))
    # 2π·1000 written to 16 digits, divided by 2π: two roundings and the decimal's 1e-16: a few eps (1e-12)
    assert_allclose(load_model(path).axes["X"].drive.bandwidth, 1000.0, rtol=1e-12)


@pytest.mark.parametrize("item", ["axes.X.mechanics.bodies.table.mass=" + "[" * 40 + "]" * 40,
                                  "axes.X.mechanics.bodies.table.mass=" + "[" * 3000 + "]" * 3000,
                                  "axes.X.mechanics.bodies.table.mass=" + "9" * 5000,
                                  "axes.X.mechanics.bodies.table.mass='150'"])
def test_overrides_nested_too_deep_or_too_long_are_model_errors(item):
    with pytest.raises(ModelError) as info:
        load_model(EXAMPLES_DIR / "rigid_1m.toml", [item])
    assert "--set axes.X.mechanics.bodies.table.mass" in str(info.value)


def test_a_file_nested_too_deep_for_the_toml_parser_is_a_model_error(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ModelError, match="nested too deeply"):
        load_model(path)
