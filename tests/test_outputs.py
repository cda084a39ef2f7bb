"""Output files (docs/outputs.md): never an input, only a regular or a new file, the extension of the
format, errors that name the user's path, and saved models that keep the original's comments and units."""

from __future__ import annotations

import json
import os
import shutil
import stat
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sicomat import load_model, save_model
from sicomat.cli.main import app
from sicomat.errors import OutputError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
runner = CliRunner()


def run(*args) -> "object":
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture
def model(tmp_path) -> Path:
    path = tmp_path / "M.toml"
    shutil.copy(EXAMPLES / "paper_5m4s.toml", path)
    return path


def refused(result, path, *needles) -> None:
    """Exit 2, one line naming ``path`` as given, no traceback, no temporary file named."""
    assert result.exit_code == 2, result.output
    line = result.stderr.strip()
    assert "\n" not in line and "Traceback" not in result.output
    assert line.startswith(f"error: {path}:"), line
    for needle in needles:
        assert needle in line, line
    assert ".tmp" not in line and f".{Path(str(path)).name}." not in line


def only(folder: Path, *names: str) -> None:
    """Nothing else (no temporary file) was left in ``folder``."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)


# --------------------------------------------------------------------------- an output is never an input
def test_simulate_out_onto_its_model_is_refused(model):
    before = model.read_bytes()
    refused(run("simulate", model, "--out", model), model, "model file")
    assert model.read_bytes() == before


def test_simulate_out_onto_its_model_even_when_the_extension_fits(tmp_path):
    # the model file may have any name: the input check, not the extension check, must refuse it
    model = tmp_path / "model.csv"
    shutil.copy(EXAMPLES / "paper_5m4s.toml", model)
    before = model.read_bytes()
    refused(run("simulate", model, "--step", "1", "--duration", "0.01", "--out", model), model, "model file")
    assert model.read_bytes() == before


def test_simulate_out_onto_its_gcode_program_is_refused(tmp_path):
    model = tmp_path / "xy.toml"
    shutil.copy(EXAMPLES / "xy_table.toml", model)
    for name in ("P.nc", "P.csv"):   # P.csv: the extension fits, only the input check can refuse it
        program = tmp_path / name
        shutil.copy(EXAMPLES / "contour.nc", program)
        before = program.read_bytes()
        refused(run("simulate", model, "--gcode", program, "--out", program), program, "G-code file")
        assert program.read_bytes() == before


def test_out_through_a_link_to_the_model_or_a_hard_link_is_refused(model, tmp_path):
    link = tmp_path / "run.csv"
    link.symlink_to(model)
    hard = tmp_path / "hard.csv"
    os.link(model, hard)
    before = model.read_bytes()
    for out in (link, hard):
        refused(run("simulate", model, "--out", out), out, "model file")
    assert model.read_bytes() == before and link.is_symlink()


def test_tune_write_onto_its_model_is_refused(model):
    before = model.read_bytes()
    refused(run("tune", model, "--write", model), model, "--write", "model file")
    assert model.read_bytes() == before


def test_reduce_write_onto_its_model_is_refused(model):
    before = model.read_bytes()
    refused(run("reduce", model, "--method", "physical", "--keep", "primary,load", "--write", model),
            model, "--write", "model file")
    assert model.read_bytes() == before


def test_two_outputs_of_one_command_are_never_the_same_file(model, tmp_path):
    out = tmp_path / "run.csv"
    refused(run("simulate", model, "--out", out, "--plot", out), out, "--out and --plot", "same file")
    alias = tmp_path / "alias.png"   # a link to the CSV: the same file under a figure's name
    alias.symlink_to(out)
    refused(run("simulate", model, "--out", out, "--plot", alias), alias, "--out and --plot", "same file")
    reduced = tmp_path / "r.toml"
    refused(run("reduce", model, "--method", "physical", "--keep", "primary,load", "--write", reduced,
                "--plot", reduced), reduced, "--write and --plot", "same file")
    only(tmp_path, "M.toml", "alias.png")


def test_save_model_never_replaces_the_file_it_is_based_on(model):
    with pytest.raises(OutputError, match="based on"):
        save_model(load_model(model), model, based_on=model)


# --------------------------------------------------------------------------- only regular or new files
def test_out_through_a_symlink_replaces_the_file_it_points_to_and_keeps_the_link(model, tmp_path):
    real = tmp_path / "real.csv"
    real.write_text("old\n")
    link = tmp_path / "latest.csv"
    link.symlink_to(real)
    result = run("simulate", model, "--step", "1", "--duration", "0.01", "--out", link)
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert real.read_text().startswith("time,")
    only(tmp_path, "M.toml", "real.csv", "latest.csv")


def test_a_link_to_a_missing_file_is_refused(model, tmp_path):
    link = tmp_path / "dangling.csv"
    link.symlink_to(tmp_path / "nowhere" / "x.csv")
    refused(run("simulate", model, "--out", link), link, "symbolic link to a missing file")
    assert link.is_symlink()


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="needs /dev/null")
def test_out_onto_a_character_device_is_refused_and_the_device_stays(model, tmp_path):
    # /dev/null is reached only through a link in tmp_path, named .csv so that only the file-type
    # check can refuse it; code without the check replaces the link, never the device itself
    link = tmp_path / "null.csv"
    link.symlink_to("/dev/null")
    refused(run("simulate", model, "--out", link), link, "character device", "regular file")
    assert link.is_symlink()
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_out_onto_a_fifo_is_refused(model, tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    refused(run("simulate", model, "--out", fifo), fifo, "named pipe (FIFO)", "regular file")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_python_writers_refuse_a_folder(tmp_path):
    import pandas as pd

    from sicomat.io.csv import write_frame_csv

    folder = tmp_path / "d.csv"
    folder.mkdir()
    with pytest.raises(OutputError, match=r"d\.csv: is a folder, not a regular file"):
        write_frame_csv(pd.DataFrame({"a": [1.0]}), folder)
    assert folder.is_dir() and not any(folder.iterdir())


# --------------------------------------------------------------------------- the extension fits the format
@pytest.mark.parametrize("command,option,name,expected", [
    (["tune"], "--write", "t.png", ".toml"),
    (["reduce", "--method", "physical", "--keep", "primary,load"], "--write", "r.csv", ".toml"),
    (["simulate"], "--out", "run.txt", ".csv"),
    (["simulate"], "--out", "run", ".csv"),
    (["simulate"], "--plot", "run.jpg", ".png, .svg or .pdf"),
    (["modal"], "--plot", "modes", ".png, .svg or .pdf"),
])
def test_wrong_extension_is_refused_with_the_expected_ones(model, tmp_path, command, option, name, expected):
    out = tmp_path / name
    result = run(command[0], model, *command[1:], option, out)
    refused(result, out, option, f"expected a name ending in {expected}")
    only(tmp_path, "M.toml")


def test_python_save_model_and_save_figure_check_the_extension(tmp_path):
    from matplotlib.figure import Figure

    from sicomat.plots.base import save_figure

    with pytest.raises(OutputError, match=r"m\.png: writes a model file; expected a name ending in \.toml"):
        save_model(load_model(EXAMPLES / "rigid_1m.toml"), tmp_path / "m.png")
    with pytest.raises(OutputError, match=r"fig: writes a figure; expected .*\.png, \.svg or \.pdf, got no"):
        save_figure(Figure(), tmp_path / "fig")
    assert save_figure(Figure(), tmp_path / "FIG.SVG").read_bytes().lstrip().startswith(b"<?xml")
    only(tmp_path, "FIG.SVG")


# --------------------------------------------------------------------------- checked before the work
def test_a_bad_output_fails_before_the_computation(model, tmp_path, monkeypatch):
    import sicomat.simulation
    import sicomat.tuning

    def forbidden(*args, **kwargs):
        raise AssertionError("the computation ran before the output was checked")

    monkeypatch.setattr(sicomat.simulation, "simulate", forbidden)
    monkeypatch.setattr(sicomat.tuning, "tune_frequency", forbidden)
    refused(run("simulate", model, "--plot", tmp_path / "x.jpg"), tmp_path / "x.jpg", "--plot")
    refused(run("simulate", model, "--out", tmp_path / "no" / "x.csv"), tmp_path / "no" / "x.csv",
            "the folder", "does not exist")
    refused(run("tune", model, "--write", tmp_path / "t.png"), tmp_path / "t.png", "--write")
    refused(run("reduce", model, "--method", "modal", "--order", "4", "--write", tmp_path / "r.toml"),
            "--write", "physical")


# --------------------------------------------------------------------------- system errors: the user's path
def test_a_failing_write_names_the_users_path_and_leaves_nothing(model, tmp_path, monkeypatch):
    real_replace = os.replace

    def full_disk(src, dst, *args, **kwargs):
        raise OSError(28, "No space left on device", src)

    target = tmp_path / "fig.png"
    target.write_bytes(b"previous")
    monkeypatch.setattr(os, "replace", full_disk)
    refused(run("modal", model, "--plot", target), target, "No space left on device")
    monkeypatch.setattr(os, "replace", real_replace)
    assert target.read_bytes() == b"previous"
    only(tmp_path, "M.toml", "fig.png")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_writing_into_proc_names_the_users_path_not_the_temporary_file(model):
    refused(run("modal", model, "--plot", "/proc/x.png"), "/proc/x.png", "cannot be written")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root may write in a read-only folder")
def test_a_folder_without_write_permission_is_refused_early(model, tmp_path):
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        refused(run("simulate", model, "--out", folder / "run.csv"), folder / "run.csv", "not writable")
    finally:
        folder.chmod(0o700)


def test_a_replaced_file_keeps_its_permissions(tmp_path):
    target = tmp_path / "m.toml"
    target.write_text("# private\n")
    target.chmod(0o600)
    save_model(load_model(EXAMPLES / "rigid_1m.toml"), target)
    assert stat.S_IMODE(target.stat().st_mode) == 0o600


# --------------------------------------------------------------------------- saved models keep the original text
def _comment_lines(text: str) -> list[str]:
    return [line.strip() for line in text.splitlines() if line.strip().startswith("#")]


def test_tune_write_keeps_comments_and_units_and_loads_with_the_tuned_gains(model, tmp_path):
    tuned = tmp_path / "tuned.toml"
    result = run("tune", model, "--velocity-crossover", "125.6", "--velocity-phase-margin", "45",
                 "--position-phase-margin", "80", "--write", tuned, "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    original, written = model.read_text(), tuned.read_text()
    for comment in _comment_lines(original):       # every comment line of the original is still there
        assert comment in written
    lines = written.splitlines()
    untouched = [line for line in original.splitlines() if not line.startswith(("Kv ", "Kp_normalized ", "Ti "))]
    assert all(line in lines for line in untouched)  # every other line, units and comments, as written
    assert f"from {model}" in lines[0]                 # the header names the source
    controller = {line.split("=")[0].strip(): line for line in lines if line.startswith(("Kv ", "Kp_normalized ", "Ti "))}
    assert '1/s"' in controller["Kv"] and "# was \"24.8 1/s\": Table I, initial tuning" in controller["Kv"]
    assert ' ms"' in controller["Ti"] and '# was "9 ms"' in controller["Ti"]
    assert '1/s"' in controller["Kp_normalized"]
    got = load_model(tuned)
    ctrl = got.axes["X"].controller
    # written in the line's unit with 15 significant digits, read back with 15 (units.parse_quantity):
    # relative error below 1e-14; 1e-13 leaves room for the unit factor's roundings
    assert ctrl.Kp_normalized == pytest.approx(payload["velocity"]["Kp_normalized"], rel=1e-13)
    assert ctrl.Ti == pytest.approx(payload["velocity"]["Ti"], rel=1e-13)
    assert ctrl.Kv == pytest.approx(payload["position"]["Kv"], rel=1e-13)
    before = load_model(model)
    same = {"Kv": ctrl.Kv, "Kp_normalized": ctrl.Kp_normalized, "Ti": ctrl.Ti}
    expected = before.model_copy(update={"axes": {"X": before.axes["X"].model_copy(
        update={"controller": before.axes["X"].controller.model_copy(update=same)})}})
    assert got == expected                            # nothing else changed


def test_tune_write_with_a_notch_appends_it_and_keeps_existing_filters(model, tmp_path):
    from sicomat.tasks.analysis import write_tuned

    text = model.read_text().replace('velocity_delay = 1\n', 'velocity_delay = 1\n\n'
                                     '[[axes.X.controller.current_filters]]\n'
                                     'type = "low-pass"\nfrequency = "2 kHz"   # anti-aliasing\ndamping = 0.7\n')
    model.write_text(text)
    machine = load_model(model)
    gains = {"Kp": 1.0, "Kp_normalized": 100.0, "Ti": 0.008, "Kv": 30.0}
    notch = {"frequency_hz": 80.6, "width": 0.5, "depth": 0.05}
    out = write_tuned(machine, "X", gains, notch, tmp_path / "n.toml", based_on=model)
    written = out.read_text()
    assert 'frequency = "2 kHz"   # anti-aliasing' in written
    filters = load_model(out).axes["X"].controller.current_filters
    assert [f.type for f in filters] == ["low-pass", "notch"]
    assert filters[0].frequency == 2000.0 and filters[1].frequency == 80.6
    assert (filters[1].width, filters[1].depth) == (0.5, 0.05)


def test_tune_write_keeps_set_overrides_in_their_units(model, tmp_path):
    tuned = tmp_path / "tuned.toml"
    result = run("tune", model, "--set", "axes.X.mechanics.bodies.load.mass=300 kg", "--write", tuned)
    assert result.exit_code == 0, result.output
    assert 'mass = "300 kg"' in tuned.read_text()
    assert load_model(tuned).axes["X"].mechanics.bodies["load"].mass == 300.0


def test_save_model_based_on_an_unchanged_model_keeps_the_text_and_round_trips(model, tmp_path):
    machine = load_model(model)
    out = save_model(machine, tmp_path / "copy.toml", based_on=model, header="a copy")
    assert out.read_text() == "# a copy\n\n" + model.read_text()
    assert load_model(out) == machine


def test_reduce_write_keeps_what_it_can_and_says_what_not(model, tmp_path):
    reduced = tmp_path / "reduced.toml"
    result = run("reduce", model, "--method", "physical", "--keep", "primary,load", "--write", reduced, "--json")
    assert result.exit_code == 0, result.output
    text = reduced.read_text()
    header = text.split("\n\n")[0]
    assert f"from {model}" in header and "--method physical" in header and "Not kept" in header
    assert 'bandwidth = "1000 Hz"            # current loop, -3 dB' in text   # the servo part as written
    assert 'mass = "270.2 kg"          # printed as M_sensor' in text         # a surviving body as written
    mechanics = text.split("[axes.X.mechanics]")[1].split("[axes.X.drive]")[0]
    assert "bodies.structure]" not in mechanics and '"structure"' not in mechanics   # merged away
    from sicomat.tasks.reduce import reduce_command

    expected = reduce_command(load_model(model), None, "physical", None, "primary,load", None).machine
    got = load_model(reduced)
    assert got.axes["X"].mechanics.bodies.keys() == expected.axes["X"].mechanics.bodies.keys()
    # the merged primary (92.305 + 0.008 kg) is written in kg with 15 digits: equal to 1e-13
    assert got.axes["X"].mechanics.bodies["primary"].mass == pytest.approx(
        expected.axes["X"].mechanics.bodies["primary"].mass, rel=1e-13)
    assert got.axes["X"].drive == expected.axes["X"].drive and got.axes["X"].controller == expected.axes["X"].controller


def test_tune_write_edits_inline_tables_and_arrays_in_place(tmp_path):
    from sicomat.tasks.analysis import write_tuned

    model = tmp_path / "c.toml"
    model.write_text('axes.X.mechanics = { type = "chain", masses = ["10 kg", "20 kg"], '
                     'stiffnesses = ["1e6 N/m"] }  # inline\n'
                     '[axes.X.drive]\nforce_constant = 100\ntime_constant = "0.5 ms"\n'
                     '[axes.X.controller]\nposition_sensor = "last"\nKv = 30\nKp_normalized = 100\nTi = "10 ms"\n'
                     'current_filters = [{ type = "low-pass", frequency = "3 kHz", damping = 0.7 }]\n')
    machine = load_model(model, ["axes.X.mechanics.masses.1=25 kg"])
    out = write_tuned(machine, "X", {"Kp": 1.0, "Kp_normalized": 90.0, "Ti": 0.009, "Kv": 25.0},
                      {"frequency_hz": 50.0, "width": 0.5, "depth": 0.1}, tmp_path / "t.toml", based_on=model)
    text = out.read_text()
    assert "Written as plain SI numbers" not in text
    assert 'masses = ["10 kg", "25 kg"], stiffnesses = ["1e6 N/m"] }  # inline' in text
    assert 'current_filters = [{ type = "low-pass", frequency = "3 kHz", damping = 0.7 }, {' in text
    assert 'Ti = "9 ms"  # was "10 ms"' in text
    got = load_model(out).axes["X"]
    assert got.mechanics.masses == [10.0, 25.0]
    assert [(f.type, f.frequency) for f in got.controller.current_filters] == [("low-pass", 3000.0), ("notch", 50.0)]


def test_an_edit_that_would_not_read_back_falls_back_to_plain_si_and_says_so(model, tmp_path, monkeypatch):
    import sicomat.io.modelfile as modelfile

    monkeypatch.setattr(modelfile, "_reads_as", lambda text, data: False)
    machine = load_model(model)
    out = save_model(machine, tmp_path / "copy.toml", based_on=model, header="a copy")
    text = out.read_text()
    assert text.startswith("# a copy\n# Written as plain SI numbers: the comments and units of")
    monkeypatch.undo()
    assert load_model(out) == machine
