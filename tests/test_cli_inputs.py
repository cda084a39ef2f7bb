"""Every bad input through every command: exit status 2, one line on stderr, no traceback.

A corpus, not a list of cases: each row is (command line, model text or example, a fragment the
one-line message must contain). ``{model}`` in a command line is replaced by the model's path.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from sicomat.cli.main import app

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
RIGID = (EXAMPLES / "rigid_1m.toml").read_text(encoding="utf-8")
XY = (EXAMPLES / "xy_table.toml").read_text(encoding="utf-8")
P5M4S = str(EXAMPLES / "paper_5m4s.toml")
P5M4S_TEXT = (EXAMPLES / "paper_5m4s.toml").read_text(encoding="utf-8")
GCODE = str(EXAMPLES / "contour.nc")
COMMANDS = ["check", "modal", "simulate", "bode", "margins", "tune", "step", "reduce"]
runner = CliRunner()


def _fail(args: list[str]):
    result = runner.invoke(app, args)
    assert result.exit_code == 2, (args, result.exit_code, result.output, result.exception)
    assert "Traceback" not in result.output and result.stdout == "", result.output
    message = result.stderr
    assert message.startswith("error: ") and message.count("\n") == 1, message
    return message


# ------------------------------------------------------------------ numeric options of every command
OPTIONS = [
    (["simulate", P5M4S, "--move", "nan"], "--move: expected a finite number"),
    (["simulate", P5M4S, "--move", "inf"], "--move: expected a finite number"),
    (["simulate", P5M4S, "--move", "0"], "--move: expected a non-zero value"),
    (["simulate", P5M4S, "--step", "-inf"], "--step: expected a finite number"),
    (["simulate", P5M4S, "--move", "5", "--duration", "nan"], "--duration: expected a finite number > 0 s"),
    (["simulate", P5M4S, "--move", "5", "--duration", "0"], "--duration: expected a value > 0 s"),
    (["simulate", P5M4S, "--move", "5", "--max-velocity", "nan"], "--max-velocity"),
    (["simulate", P5M4S, "--move", "5", "--max-velocity", "inf"], "--max-velocity"),
    (["simulate", P5M4S, "--move", "5", "--max-acceleration", "-2"], "--max-acceleration: expected a value > 0"),
    (["simulate", str(EXAMPLES / "xy_table.toml"), "--gcode", GCODE, "--feed", "nan"], "--feed"),
    (["simulate", P5M4S, "--move", "abc"], "'--move'"),
    (["simulate", P5M4S, "--no-such-option"], "--no-such-option"),
    (["tune", P5M4S, "--min-gain-margin", "-5"], "--min-gain-margin: expected a value > 0 dB (got -5.0)"),
    (["tune", P5M4S, "--min-gain-margin", "nan"], "--min-gain-margin"),
    (["tune", P5M4S, "--velocity-phase-margin", "200"], "--velocity-phase-margin: expected a value > 0 and < 180"),
    (["tune", P5M4S, "--velocity-phase-margin", "0"], "--velocity-phase-margin"),
    (["tune", P5M4S, "--position-phase-margin", "-1"], "--position-phase-margin"),
    (["tune", P5M4S, "--velocity-crossover", "inf"], "--velocity-crossover"),
    (["tune", P5M4S, "--position-crossover", "0"], "--position-crossover"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "10", "--feed", "1000", "--magnification", "0"],
     "--magnification: expected a value > 0"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "10", "--feed", "1000", "--magnification", "-1"],
     "--magnification"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "nan", "--feed", "1000"], "--radius"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "10", "--feed", "inf"], "--feed"),
    (["step", P5M4S, "--Kp", "inf"], "--Kp"),
    (["step", P5M4S, "--Ti", "nan"], "--Ti"),
    (["step", P5M4S, "--Kv", "inf"], "--Kv"),
    (["step", P5M4S, "--duration", "inf"], "--duration"),
    (["bode", P5M4S, "--points", "-1"], "'--points'"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "10", "--feed", "1e300"], "--feed: expected a magnitude"),
    (["simulate", P5M4S, "--move", "5", "--max-velocity", "1e300"], "--max-velocity"),
    (["step", P5M4S, "--Ti", "1e-300"], "--Ti"),
    (["step", P5M4S, "--duration", "1e-9"], "shorter than two samples"),
    (["modal"], "Missing argument 'model'"),
    (["--bogus"], "No such option: --bogus"),
    (["nosuchcommand"], "No such command 'nosuchcommand'"),
    (["reduce", P5M4S, "--method", "balanced", "--order", "4", "--band", "1e300:1e301"], "--band: expected frequencies"),
    (["reduce", P5M4S, "--method", "balanced", "--order", "4", "--band", "nan:inf"], "--band"),
    (["reduce", P5M4S, "--order", "-1"], "--order"),
]


@pytest.mark.parametrize("args, fragment", OPTIONS, ids=[" ".join(a[:1] + a[2:]) for a, _ in OPTIONS])
def test_numeric_options_outside_their_sense(args, fragment):
    assert fragment in _fail(args)


# ------------------------------------------------------------------ work that cannot fit in memory
# The estimates are far above the 2 GiB default (hundreds of GiB to TiB): no tolerance question.
MEMORY = [
    (["simulate", str(EXAMPLES / "rigid_1m.toml"), "--duration", "1e6"], "this simulation needs about"),
    (["simulate", str(EXAMPLES / "rigid_1m.toml"), "--move", "1e9"], "this simulation needs about"),
    (["simulate", str(EXAMPLES / "xy_table.toml"), "--gcode", GCODE, "--feed", "1e-9"], "this path interpolation"),
    (["circle", str(EXAMPLES / "xy_table.toml"), "--radius", "1e6", "--feed", "1000"], "this path interpolation"),
    (["step", P5M4S, "--duration", "1e6"], "this step response"),
    (["margins", P5M4S, "--set", "axes.X.controller.velocity_delay=1000000"], "velocity_delay of 1000000"),
    (["simulate", P5M4S, "--step", "1", "--set", "axes.X.controller.velocity_period=1 ns",
      "--set", "axes.X.controller.position_period=8 ns"], "this simulation"),
]


@pytest.mark.parametrize("args, fragment", MEMORY, ids=[" ".join(a[:1] + a[2:])[:60] for a, _ in MEMORY])
def test_work_beyond_the_memory_limit_is_refused_before_allocating(args, fragment):
    message = _fail(args)
    assert fragment in message and "SICOMAT_MAX_MEMORY" in message and "limit of 2 GiB" in message


def test_the_memory_limit_is_set_by_the_environment(monkeypatch):
    # the default 0.3 s step run: 2400 steps x 24 values x 8 bytes x 2 = 0.9 MiB, above 100 KiB
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", "100 KiB")
    assert "limit of 100 KiB" in _fail(["simulate", str(EXAMPLES / "rigid_1m.toml"), "--step", "1"])
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", "lots")
    assert "SICOMAT_MAX_MEMORY" in _fail(["simulate", str(EXAMPLES / "rigid_1m.toml"), "--step", "1"])
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", "1 GiB")
    assert runner.invoke(app, ["simulate", str(EXAMPLES / "rigid_1m.toml"), "--step", "1"]).exit_code == 0


# ------------------------------------------------------------------ model files and overrides
MODELS = [
    ("empty", "", "axes: missing required key"),
    ("binary", b"\x00\x01\xff\xfe", "cannot read the model file"),
    ("deep-file", "a = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply"),
    ("deep-value", RIGID.replace('mass = "150 kg"', "mass = " + "[" * 100 + "]" * 100), "nested too deeply"),
    ("huge-integer", RIGID.replace('"150 kg"', "1" + "0" * 400), "axes.X.mechanics.bodies.table.mass"),
    ("huge-integer-digits", RIGID.replace('"150 kg"', "9" * 5000), "more than 4300 digits"),
    ("unitless-string", RIGID.replace('"150 kg"', '"150"'), "'150 kg'"),
    ("nan-literal", RIGID.replace('"150 kg"', "nan"), "axes.X.mechanics.bodies.table.mass"),
    ("bandwidth-rpm", RIGID.replace('"1000 Hz"', '"60000 rpm"'), "rotational speed"),
    ("kp-zero", RIGID.replace('"240 1/s"', "0"), "axes.X.controller.Kp_normalized"),
    ("kv-zero", RIGID.replace('Kv = "78.5 1/s"', "Kv = 0"), "axes.X.controller.Kv"),
    ("ti-negative", RIGID.replace('"4.32 ms"', "-1"), "axes.X.controller.Ti"),
    ("unknown-key", RIGID + "\nfoo = 1\n", "unknown key"),
    ("wrong-type", RIGID.replace('"150 kg"', "true"), "axes.X.mechanics.bodies.table.mass"),
    ("mass-1e300", RIGID.replace('"150 kg"', "1e300"), "bodies.table.mass: expected a mass (kg) of magnitude"),
    ("filter-above-nyquist", RIGID.replace('position_sensor = "scale"', 'position_sensor = "scale"\n'
                                           'current_filters = [{type = "notch", frequency = "1 THz"}]'),
     "axes.X.controller.current_filters.0.frequency: filter frequency"),
    ("time-constant-1e-300", RIGID.replace('bandwidth = "1000 Hz"', 'time_constant = "1e-300 s"'),
     "axes.X.drive.time_constant"),
    ("no-axes", 'name = "x"\n', "axes"),
    ("empty-masses", '[axes.X.mechanics]\ntype = "chain"\nmasses = []\n', "axes.X.mechanics.masses"),
    ("duplicate-names", '[axes.X.mechanics]\ntype = "chain"\nmasses = [1, 2]\nstiffnesses = [1]\n'
                        'names = ["a", "a"]\n', "unique"),
    ("stiff-1e30", P5M4S_TEXT.replace('stiffness = "1e12 N/m"', "stiffness = 1e30"),
     "axes.X.mechanics.couplings.secondary.stiffness: couplings 'secondary' and"),
    ("negative-counts", RIGID.replace('[axes.X.mechanics.sensors.scale]\nbody = "table"',
                                      '[axes.X.mechanics.sensors.scale]\nbody = "table"\n'
                                      'counts_per_revolution = -5'), "counts_per_revolution"),
]


# mechanics-only models (no drive, no controller): their defect is reached only by the commands that
# read the mechanics alone; the servo commands stop earlier at the missing controller, so those
# combinations do not apply and are not generated
MECHANICS_ONLY = {"empty-masses", "duplicate-names"}
MECHANICS_COMMANDS = ("check", "modal")
MODEL_CASES = [(command, *model) for model in MODELS for command in COMMANDS
               if model[0] not in MECHANICS_ONLY or command in MECHANICS_COMMANDS]


@pytest.mark.parametrize("command, name, text, fragment", MODEL_CASES,
                         ids=[f"{case[1]}-{case[0]}" for case in MODEL_CASES])
def test_bad_model_files_through_every_command(tmp_path, command, name, text, fragment):
    path = tmp_path / f"{name}.toml"
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    extra = {"simulate": ["--step", "1"], "reduce": ["--order", "2"]}.get(command, [])
    message = _fail([command, str(path), *extra])
    assert fragment in message and str(path) in message


OVERRIDES = [
    ("axes.X.mechanics.bodies.load.mass=" + "[" * 3000 + "]" * 3000, "nested too deeply"),
    ("axes.X.mechanics.bodies.load.mass=" + "{a=" * 100 + "1" + "}" * 100, "nested too deeply"),
    ("axes.X.mechanics.bodies.load.mass='150'", "no unit"),
    ("axes.X.mechanics.bodies.load.mass", "KEY=VALUE"),
    ("axes.X.nonexistent=1", "axes.X.nonexistent"),
    ("axes.X.mechanics.bodies.load.mass.x.y=1", "not a table"),
    ("axes.X.controller.Kp_normalized=0", "Kp_normalized"),
    ("axes.X.drive.bandwidth=nan", "axes.X.drive.bandwidth"),
    ("a." * 5000 + "b=1", "more than 32 levels deep"),                   # a key path, not a value
    ("axes.X.mechanics.bodies.load.mass=1 " + "kg*" * 20000 + "kg", "(60044 characters)"),
]


@pytest.mark.parametrize("item, fragment", OVERRIDES, ids=[o[0][:40] for o in OVERRIDES])
def test_bad_overrides(item, fragment):
    message = _fail(["modal", P5M4S, "--set", item])
    assert fragment in message and len(message) < 1000       # long input is echoed by its start only


def test_a_directory_or_binary_gcode_file(tmp_path):
    xy = str(EXAMPLES / "xy_table.toml")
    assert "directory" in _fail(["simulate", xy, "--gcode", str(tmp_path)])
    binary = tmp_path / "p.nc"
    binary.write_bytes(b"\x00\xff\xfe" * 100)
    assert str(binary) in _fail(["simulate", xy, "--gcode", str(binary)])


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_endless_input_files_are_refused_without_reading_them_whole():
    assert "larger than 16 MiB" in _fail(["check", "/dev/zero"])
    assert "larger than 256 MiB" in _fail(["simulate", str(EXAMPLES / "xy_table.toml"), "--gcode", "/dev/zero"])
