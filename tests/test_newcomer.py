"""A newcomer's path (issue 10 §6): version, help that shows every choice, JSON names as the model
file's, one unit rule, tables that never cut numbers, labelled plots, a README that runs."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
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
                                     "reduce", "step", "version", "modemap"])
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
        # the two files' loops differ by one rounding of Kp: the margins by κ·eps of the response (κ <= 1e6
        # on these grids, ~1e-8 deg), far below 1e-6 deg (comment above)
        assert got[loop]["phase_margin_deg"] == pytest.approx(reference[loop]["phase_margin_deg"], abs=1e-6)
    from sicomat import load_model

    # --write keeps 15 significant digits (5e-15 relative) and the unit factor rounds once: 1e-12
    assert load_model(tuned).axes["X"].controller.Kp_normalized == pytest.approx(v["Kp_normalized"], rel=1e-12)


def test_step_json_names_gains_as_the_model_file():
    from sicomat import load_model
    from sicomat.servo.loop import build_servo_loop

    loop = build_servo_loop(load_model(P5M4S))
    payload = json.loads(run("step", P5M4S, "--Kp-normalized", "120", "--json").stdout)
    # the option echoed (no arithmetic) and Kp = Kp_n·m (one rounding): 1e-12 for both
    assert payload["Kp_normalized"] == pytest.approx(120.0, rel=1e-12)
    assert payload["Kp"] == pytest.approx(120.0 * loop.m_rigid, rel=1e-12)  # physical, as the file's Kp
    old_name = json.loads(run("step", P5M4S, "--Kp", "120", "--json").stdout)
    assert old_name["Kp_normalized"] == payload["Kp_normalized"]


XY = str(EXAMPLES / "xy_table.toml")
JSON_COMMANDS = {
    "check": ["check", P5M4S],
    "modal": ["modal", P5M4S],
    "simulate": ["simulate", P5M4S, "--move", "2"],
    "simulate-gcode": ["simulate", XY, "--gcode", str(EXAMPLES / "contour.nc")],
    "bode": ["bode", P5M4S, "--points", "50"],
    "margins": ["margins", P5M4S],
    "tune": ["tune", P5M4S],
    "tune-time": ["tune", P5M4S, "--method", "time"],
    "step": ["step", P5M4S],
    "circle": ["circle", XY, "--radius", "5", "--feed", "600"],
    "reduce": ["reduce", P5M4S, "--method", "physical", "--keep", "primary,load,structure"],
}


def _items(value, path=""):
    if isinstance(value, dict):
        for key, item in value.items():
            yield path, key, value
            yield from _items(item, f"{path}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _items(item, f"{path}.{i}")


@pytest.fixture(scope="module")
def json_outputs():
    out = {}
    for name, args in JSON_COMMANDS.items():
        result = run(*args, "--json")
        assert result.exit_code == 0, (name, result.output)
        out[name] = json.loads(result.stdout)
    return out


def test_json_units_follow_one_rule(json_outputs):
    """An unsuffixed key is SI; a key still carrying an SI suffix (``_s``, ``_rad_s``) is a deprecated one
    from the table in docs/conventions.md and has the rule's name beside it, same value."""
    from sicomat.cli.jsonkeys import SI_NAMES

    seen = set()
    for name, payload in json_outputs.items():
        for path, key, mapping in _items(payload):
            if key.endswith("_s") and not key.endswith("_samples"):
                assert key in SI_NAMES, f"{name}: {path}.{key} carries an SI suffix and is not in SI_NAMES"
                assert mapping[SI_NAMES[key]] == mapping[key], f"{name}: {path}.{key}"
                seen.add(key)
    assert {"duration_s", "step_s", "bandwidth_rad_s", "velocity_crossover_rad_s"} <= seen
    conventions = (ROOT / "docs" / "conventions.md").read_text()
    for old, new in SI_NAMES.items():
        assert f"`{old}`" in conventions and f"`{new}`" in conventions, old


def test_json_echoes_options_in_their_own_units(json_outputs):
    circle = json_outputs["circle"]
    # unit conversions mm/min -> m/s and mm -> m and back: a few roundings of a decimal factor (1e-12)
    assert circle["feed_mm_min"] == pytest.approx(600.0, rel=1e-12) and circle["feed"] == pytest.approx(0.01, rel=1e-12)
    assert circle["radius_mm"] == pytest.approx(5.0, rel=1e-12) and circle["radius"] == pytest.approx(5e-3, rel=1e-12)
    drive = json_outputs["check"]["axes"]["X"]["drive"]
    assert drive["bandwidth_hz"] == drive["bandwidth"] == 1000.0  # the model file's "1000 Hz"
    simulate = json_outputs["simulate"]
    # duration = samples × step, one rounding (half an ulp), and JSON floats round-trip exactly: 1e-12 is ample
    assert simulate["duration"] == pytest.approx(simulate["samples"] * simulate["time_step"], rel=1e-12)


@pytest.mark.parametrize("width", [80, 60, 40])
def test_tables_never_cut_a_number(width):
    modal = json.loads(run("modal", P5M4S, "--json").stdout)
    margins = json.loads(run("margins", P5M4S, "--json").stdout)
    text = run("modal", P5M4S, env={"COLUMNS": str(width)}).stdout
    assert "…" not in text
    for mode in modal["modes"][1:]:
        assert f"{mode['frequency_hz']:.4f}" in text  # the table's own format, whole
    text = run("margins", P5M4S, env={"COLUMNS": str(width)}).stdout
    assert "…" not in text
    for loop in ("velocity", "position"):
        assert f"{margins[loop]['gain_crossover_rad_s']:.4g}" in text
        assert f"{margins[loop]['bandwidth_rad_s']:.4g}" in text
    for args in (["check", P5M4S], ["tune", P5M4S], ["simulate", P5M4S, "--move", "2"]):
        result = run(*args, env={"COLUMNS": str(width)})
        assert result.exit_code == 0 and "…" not in result.stdout, result.stdout


@pytest.mark.parametrize("width", [80, 60])
def test_print_table_keeps_long_numbers_whole_in_a_narrow_console(width):
    import io

    from rich.console import Console
    from rich.table import Table

    from sicomat.cli.layout import print_table

    values = [f"{1.7430000123456e5 * 10 ** k:.10e}" for k in range(9)]
    table = Table(title="wide")
    for k in range(len(values)):
        table.add_column(f"column {k}", justify="right")
    table.add_row(*values)
    console = Console(width=width, file=io.StringIO(), color_system=None)
    print_table(console, table)
    text = console.file.getvalue()
    assert all(value in text for value in values), text
    assert max(len(line) for line in text.splitlines()) <= width


# ------------------------------------------------------------------------------------------- plots
def _series(model: str, move: float = 1e-3):
    from sicomat import load_model
    from sicomat.servo.loop import build_servo_loop
    from sicomat.motion.setpoints import trapezoid_profile
    from sicomat.simulation import simulate

    loop = build_servo_loop(load_model(model))
    return simulate(loop, trapezoid_profile(move, 0.1, 1.0), duration=0.05)


@pytest.mark.parametrize("model, unit", [(P5M4S, "(N)"), (str(EXAMPLES / "ballscrew_3m2s.toml"), "(N·m)")])
def test_effort_axis_has_the_actuators_unit(model, unit):
    series = _series(model)
    effort_axis = series.plot().axes[2]
    assert effort_axis.get_ylabel().endswith(unit)
    chosen = series.plot(["drive.effort", "drive.current", "load.x" if model == P5M4S else "table.x"])
    assert [ax.get_ylabel().rsplit(" ", 1)[-1] for ax in chosen.axes] == [unit, "(A)", "(m)"]


def test_mode_shapes_plot_has_a_y_label_and_a_legend():
    from sicomat import build_mechanics, load_model, modal_analysis

    result = modal_analysis(build_mechanics(load_model(P5M4S).axis("X").mechanics))
    fig = result.plot()
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert all(ax.get_ylabel() for k, ax in enumerate(visible) if k % 4 == 0)
    assert fig.legends and len(fig.legends[0].get_texts()) == 2


def test_contour_plot_magnifies_the_deviation_visibly_by_default():
    from scipy.spatial import cKDTree

    from sicomat import load_model
    from sicomat.tasks.simulate import simulate_gcode

    _, run_ = simulate_gcode(load_model(XY), EXAMPLES / "contour.nc", None, None, None)
    fig = run_.plot()
    ax = fig.axes[0]
    programmed, actual = ax.get_lines()[:2]
    label = actual.get_label()
    factor = float(label.split("×")[1].rstrip(")"))
    assert factor > 1 and f"×{factor:g}" in fig.get_suptitle()
    # the drawn deviation (mm) measured independently: distance of each drawn point to the nearest
    # setpoint sample; the samples are one position period apart (<= 0.04 mm at 2000 mm/min), so this
    # overestimates the distance to the polyline by at most half of that, against a drawn deviation of mm
    drawn = np.column_stack(actual.get_data())
    sp = np.column_stack(programmed.get_data())
    deviation = cKDTree(sp).query(drawn)[0].max()
    size = 0.5 * np.linalg.norm(np.ptp(sp, axis=0))
    assert 0.05 < deviation / size < 0.25, deviation / size  # the rule: 8-20 % (the setpoint trace's
    # rounded corners and the sample spacing move the measured value a little either way)
    assert "×3)" in run_.plot(3.0).axes[0].get_lines()[1].get_label()  # an explicit factor wins


def test_contour_magnification_option_is_checked():
    result = run("simulate", XY, "--gcode", str(EXAMPLES / "contour.nc"), "--magnification", "0")
    assert result.exit_code == 2 and "--magnification: expected a finite factor > 0" in result.stderr


@pytest.mark.parametrize("model", [P5M4S, str(EXAMPLES / "paper_2m1s.toml"), str(EXAMPLES / "ballscrew_3m2s.toml")])
def test_nichols_labels_do_not_overlap(model):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from sicomat import load_model
    from sicomat.plots.frequency import nichols_figure
    from sicomat.servo.loop import build_servo_loop
    from sicomat.frequency.loops import LoopAnalysis, default_omega
    from sicomat.frequency.margins import stability_margins

    loop = build_servo_loop(load_model(model))
    frf = LoopAnalysis.of(loop).response("velocity-open", default_omega(loop, "velocity-open", 2000))
    fig = nichols_figure([frf], margins=stability_margins(frf))
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    texts = [t for t in fig.axes[0].texts if t.get_visible() and t.get_text().strip()]
    assert any(t.get_text().startswith("PM ") for t in texts) and any(t.get_text().startswith("GM ") for t in texts)
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts]
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1:]:
            assert not box_a.overlaps(box_b), (a, b)


# ------------------------------------------------------------------------------------------ README
README = (ROOT / "README.md").read_text()


def _blocks(language: str) -> list[str]:
    import re

    return re.findall(rf"```{language}\n(.*?)```", README, re.S)


def _readme_commands() -> list[list[str]]:
    import shlex

    commands = []
    for block in _blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words and words[0] == "sicomat":
                commands.append(words[1:])
    return commands


def test_readme_opens_with_the_two_make_commands():
    first = _blocks("sh")[0].splitlines()
    assert [line.split("#")[0].strip() for line in first] == ["make demo", "make test"]


def test_readme_says_how_to_get_sicomat_on_the_path_before_its_commands():
    section = README[README.index("## Command line"):]
    first_command = section.index("sicomat check")
    assert "source .venv/bin/activate" in section[:first_command] and ".venv/bin/sicomat" in section[:first_command]


def test_readme_lists_every_command():
    import typer.main

    listed = {words[0] for words in _readme_commands() if words and not words[0].startswith("-")}
    registered = set(typer.main.get_command(app).commands)
    assert listed <= registered, listed - registered
    assert registered - {"version"} <= listed, registered - listed  # `version` is in a comment there


def test_readme_commands_run_as_written(tmp_path, monkeypatch):
    import shutil

    shutil.copytree(EXAMPLES, tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    for words in _readme_commands():
        result = run(*words)
        assert result.exit_code == 0, (words, result.output)


def test_readme_python_block_runs_as_written(tmp_path, monkeypatch, capsys):
    import shutil

    shutil.copytree(EXAMPLES, tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    (code,) = _blocks("python")
    namespace: dict = {"__name__": "__readme__"}
    exec(compile(code, "README.md", "exec"), namespace)
    assert 75.0 < namespace["modes"].f_meca_hz < 85.0  # paper IV.B: "a first mode near f_meca = 80 Hz"
    assert namespace["tuned"].tuned.Kp > 0 and f"{namespace['modes'].f_meca_hz}" in capsys.readouterr().out


# -------------------------------------------------------------------------------------------- docs
def test_table_1_states_the_crossings_the_tool_reports():
    import re

    numbers = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9}
    text = (ROOT / "docs" / "table-1.md").read_text()
    stated = re.search(r"crosses 0 dB (\w+) times", text).group(1)
    assert "sicomat margins examples/paper_5m4s.toml --json" in text
    payload = json.loads(run("margins", P5M4S, "--json").stdout)
    assert numbers[stated] == len(payload["velocity"]["gain_crossovers"])


def test_docs_link_only_inside_the_repository():
    import re

    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text()
        assert "../shared" not in text, doc.name
        for target in re.findall(r"\]\(([^)#\s]+)", text):
            if "://" in target:
                continue
            resolved = (doc.parent / target).resolve()
            assert resolved.is_relative_to(ROOT) and resolved.exists(), (doc.name, target)


def test_servo_doc_lists_every_trajectory_type():
    import typing

    from sicomat.description import motion as servo_spec

    row = next(line for line in (ROOT / "docs" / "servo.md").read_text().splitlines()
               if line.startswith("| trajectory generator"))
    kinds = set()
    for name in dir(servo_spec):
        cls = getattr(servo_spec, name)
        fields = getattr(cls, "model_fields", {})
        if name.endswith("Setpoint") and "type" in fields:
            kinds.update(typing.get_args(fields["type"].annotation))
    assert {"step", "ramp", "trapezoid", "s-curve"} <= kinds
    assert all(f"`{kind}`" in row for kind in kinds), row
    assert "issue" not in row


def test_circle_plot_magnification_is_automatic_round_and_shown():
    from sicomat import load_model
    from sicomat.simulation.paths import circle_test

    test = circle_test(load_model(XY), 5e-3, 0.01, clockwise=False)
    fig = test.plot()
    ax = fig.axes[0]
    actual = next(line for line in ax.get_lines() if line.get_label().startswith("actual"))
    factor = float(actual.get_label().split("×")[1].rstrip(")"))
    mantissa = factor / 10 ** np.floor(np.log10(factor))
    # a 1-2-5 factor, as printed: the division by a power of ten rounds once (a few eps; 1e-9)
    assert min(abs(mantissa - m) for m in (1, 2, 5)) < 1e-9
    assert f"×{factor:g}" in fig.get_suptitle()
    drawn = np.max(np.abs(np.asarray(actual.get_ydata()) - 1.0))  # nominal circle at 1: fraction of R
    # the rule's window (8-20 % of R), plus the rounding of fractions of R near 1 drawn (a few eps; 1e-12)
    assert 0.08 - 1e-12 <= drawn <= 0.2 + 1e-12, drawn
    assert "×7)" in next(line.get_label() for line in test.plot(7.0).axes[0].get_lines()
                         if line.get_label().startswith("actual"))


# ---------------------------------------------------------------------------------------- progress
class _Recorder:
    def __init__(self):
        self.calls = []

    def __call__(self, task, done, total):
        self.calls.append((task, done, total))


def test_library_reports_progress_through_a_callback():
    from sicomat import build_mechanics, load_model, modal_analysis
    from sicomat.servo.loop import build_servo_loop
    from sicomat.motion.setpoints import trapezoid_profile
    from sicomat.simulation import simulate
    from sicomat.tuning.frequency import tune_frequency

    machine = load_model(P5M4S)
    rec = _Recorder()
    modal_analysis(build_mechanics(machine.axis("X").mechanics), progress=rec)
    assert [(done, total) for _, done, total in rec.calls] == [(0, 4), (1, 4), (2, 4), (3, 4), (4, 4)]
    loop = build_servo_loop(machine)
    rec = _Recorder()
    series = simulate(loop, trapezoid_profile(1e-3, 0.1, 1.0), 0.02, progress=rec)
    assert rec.calls[-1][1:] == (series.info["samples"],) * 2
    rec = _Recorder()
    result = tune_frequency(loop, suggest_notch=False, progress=rec)
    assert rec.calls and rec.calls[-1][1] == result.evaluations
    assert [done for _, done, _ in rec.calls] == sorted(done for _, done, _ in rec.calls)


def test_batch_with_progress_gives_the_same_figures():
    from sicomat import load_model
    from sicomat.servo.loop import build_servo_loop
    from sicomat.motion.setpoints import trapezoid_profile
    from sicomat.simulation import simulate_batch

    loop = build_servo_loop(load_model(P5M4S))
    loops = [loop.with_gains(Kv=loop.Kv * f) for f in np.linspace(0.5, 1.5, 5)]
    profile = trapezoid_profile(1e-3, 0.1, 1.0)
    whole = simulate_batch(loops, profile, 0.02)
    rec = _Recorder()
    chunked = simulate_batch(loops, profile, 0.02, progress=rec)
    # the variants are independent in the kernel: the same operations on the same numbers, whether
    # they run in one call or in several
    np.testing.assert_array_equal(chunked.max_following_error, whole.max_following_error)
    np.testing.assert_array_equal(chunked.final_error, whole.final_error)
    assert rec.calls[-1][1:] == (5, 5)


@pytest.fixture
def terminal_stderr(monkeypatch):
    """Make the CLI believe stderr is a terminal, with the bar shown at once."""
    import io

    from rich.console import Console

    import sicomat.cli.progress as progress

    screen = io.StringIO()
    monkeypatch.setattr(progress, "_stderr_is_terminal", lambda: True)
    monkeypatch.setattr(progress, "DELAY", 0.0)
    monkeypatch.setattr(progress, "_console", lambda: Console(file=screen, force_terminal=True, width=100))
    return screen


@pytest.mark.parametrize("args", [["simulate", P5M4S, "--move", "5", "--duration", "1"],
                                  ["tune", P5M4S], ["modal", P5M4S],
                                  ["circle", XY, "--radius", "5", "--feed", "600"]])
def test_json_stdout_stays_pure_with_the_progress_bar_on(terminal_stderr, args):
    result = run(*args, "--json")
    assert result.exit_code == 0, result.output
    json.loads(result.stdout)  # one JSON object, nothing else
    assert terminal_stderr.getvalue().strip(), "the bar was not drawn"


def test_no_progress_bar_when_stderr_is_not_a_terminal():
    result = run("simulate", P5M4S, "--move", "5", "--duration", "1", "--json")
    assert result.exit_code == 0 and result.stderr == ""


def test_tune_table_prints_the_suggested_notch_as_fields_not_a_python_dict():
    result = run("tune", P5M4S)
    assert result.exit_code == 0, result.output
    line = next(line for line in result.stdout.splitlines() if line.strip().startswith("notch:"))
    assert "{" not in line and "frequency_hz 374" in line
