"""Parameter studies (issue 14): the table against the variants run one by one through the public API, seeds,
the distributions' statistics, failed variants as rows, constraints, and bad study files refused up front.

The engine's resilience (worker counts, a killed worker, an interrupted study resumed) is in
``test_studies_engine.py``. These tests run on an in-process Dask client (threads): the table does not depend
on where a chunk runs (that is what the engine tests check with worker processes).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sicomat.errors import ModelError

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
runner = CliRunner()


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        yield c


def write_study(folder: Path, text: str, name: str = "study.toml") -> Path:
    """A study file in ``folder`` whose base is the paper's 5M4S (copied beside it)."""
    (folder / "paper_5m4s.toml").write_text((EXAMPLES / "paper_5m4s.toml").read_text())
    path = folder / name
    path.write_text(text)
    return path


GRID = """
base = "paper_5m4s.toml"
seed = 3
analyses = ["modal", "tune", "margins", "simulate"]
constraints = ["margins.velocity.phase_margin_deg >= 40", "modal.f2_hz > 300"]

[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["200 kg", "0.35 t"]

[[parameters]]
path = "axes.X.mechanics.couplings.load.stiffness"
range = ["2e8 N/m", "6e8 N/m", 2]

[tune]
velocity_crossover = "20 Hz"
velocity_phase_margin = 45

[simulate]
duration = "0.3 s"
"""


def test_a_grid_study_equals_its_variants_run_one_by_one(tmp_path, client):
    """Every row against the same variant through the public API (load_model --set, modal_analysis,
    tune_frequency, stability_margins on the tuned loop, simulate on the tuned loop). The study runs the
    same arithmetic, so the analyses agree to rounding (rtol 1e-12: the only differences are the order of
    a few sums); its simulations run in one batch per structure while simulate() runs one loop, whose
    following errors agree to a few ulps of the 10 mm positions they are differences of (atol 1e-12 m)."""
    from sicomat import load_model, simulate, tune_frequency, build_servo_loop, stability_margins
    from sicomat.frequency import LoopAnalysis
    from sicomat.mechanics.modal import modal_analysis
    from sicomat.robotics.lowering import axis_mechanics
    from sicomat.studies import Study
    from sicomat.tasks.simulate import choose_profile
    from sicomat.simulation.checks import simulation_verdict
    from sicomat.tuning import TuningTargets

    path = write_study(tmp_path, GRID)
    results = Study(path).run(client)
    table = results.to_pandas()
    assert list(table["variant"]) == [0, 1, 2, 3]
    # the grid: the Cartesian product, the last parameter fastest, the inputs in SI
    assert list(table["axes.X.mechanics.bodies.load.mass"]) == [200.0, 200.0, 350.0, 350.0]
    assert list(table["axes.X.mechanics.couplings.load.stiffness"]) == [2e8, 6e8, 2e8, 6e8]
    assert table["error"].isna().all()
    for mass, k, row in zip(["200 kg", "200 kg", "0.35 t", "0.35 t"], ["2e8 N/m", "6e8 N/m"] * 2,
                            table.itertuples(index=False)):
        row = dict(zip(table.columns, row))
        machine = load_model(tmp_path / "paper_5m4s.toml", [f"axes.X.mechanics.bodies.load.mass={mass}",
                                                            f"axes.X.mechanics.couplings.load.stiffness={k}"])
        modes = modal_analysis(axis_mechanics(machine, "X"))
        flexible = sorted(m.undamped_hz for m in modes.modes if not m.rigid)
        assert row["modal.f1_hz"] == pytest.approx(flexible[0], rel=1e-12)
        assert row["modal.f2_hz"] == pytest.approx(flexible[1], rel=1e-12)
        loop = build_servo_loop(machine, "X")
        tuned = tune_frequency(loop, TuningTargets(velocity_crossover=2 * math.pi * 20, velocity_phase_margin=45),
                               suggest_notch=False)
        assert row["tune.targets_met"] == tuned.targets_met
        assert row["tune.Kp"] == pytest.approx(tuned.tuned.Kp, rel=1e-12)
        assert row["tune.Kv"] == pytest.approx(tuned.tuned.Kv, rel=1e-12)
        tuned_loop = tuned.tuned_loop()
        an = LoopAnalysis.of(tuned_loop)
        pm = stability_margins(an.response("velocity-open")).phase_margin_deg
        assert row["margins.velocity.phase_margin_deg"] == pytest.approx(pm, rel=1e-12)
        profile, _ = choose_profile(machine.axes["X"].trajectory, None, None, None, None)
        series = simulate(tuned_loop, profile, 0.3)
        assert series.metrics.settling_time is not None          # the move settles within the run
        assert row["simulate.max_following_error"] == pytest.approx(series.metrics.max_following_error, abs=1e-12)
        assert row["simulate.rms_following_error"] == pytest.approx(series.metrics.rms_following_error, abs=1e-12)
        assert row["simulate.final_error"] == pytest.approx(series.metrics.final_error, abs=1e-12)
        # settling: the same band and start as simulate()'s; the crossing time is interpolated between two
        # samples from the errors above, so it agrees to their 1e-12 m over the error's slope (well under 1 us)
        assert row["simulate.settling_time"] == pytest.approx(series.metrics.settling_time, abs=1e-6)
        assert row["simulate.overshoot_percent"] == pytest.approx(series.metrics.overshoot_percent, abs=1e-6)
        peak = loop.drive.kt * np.max(np.abs(series.signals["current.applied"]))
        assert row["simulate.max_effort"] == pytest.approx(peak, rel=1e-12)
        assert row["simulate.stable"] == simulation_verdict(tuned_loop, series, profile).stable
        assert row["constraints_ok"] == (pm >= 40 and flexible[1] > 300)
    # the table as written, read back
    assert results.results_path.name == "results.parquet"
    pd.testing.assert_frame_equal(pd.read_parquet(results.results_path), table)


TOLERANCES = """
base = "paper_5m4s.toml"
seed = {seed}
analyses = ["modal"]

[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "normal"
mean = "270 kg"
std = "27 kg"
samples = 4000

[[parameters]]
path = "axes.X.mechanics.couplings.load.stiffness"
distribution = "uniform"
low = 0.9
high = 1.1
relative = true
samples = 4000

[[parameters]]
path = "axes.X.mechanics.bodies.primary.mass"
distribution = "lognormal"
mean = "92 kg"
std = "9.2 kg"
samples = 4000
"""


def _plan(tmp_path: Path, text: str, name: str = "study.toml"):
    from sicomat.studies import Study

    return Study(write_study(tmp_path, text, name)).plan


def test_seeds_reproduce_and_the_draws_have_their_distributions(tmp_path):
    """The same seed gives the same variants; another seed others. The draws' sample means and deviations
    match the distributions: bounds of 5 standard errors (sigma/sqrt(n) for the mean, sigma/sqrt(2n) for
    the deviation of a normal sample, the uniform's and lognormal's from their fourth moments rounded up):
    a correct generator fails them with probability below 1e-6 (and the seed is fixed)."""
    a = _plan(tmp_path, TOLERANCES.format(seed=7), "a.toml")
    b = _plan(tmp_path, TOLERANCES.format(seed=7), "b.toml")
    c = _plan(tmp_path, TOLERANCES.format(seed=8), "c.toml")
    n = 4000
    assert a.variants == n and a.grid_shape == ()
    assert [a.settings(v) for v in (0, 1, 3999)] == [b.settings(v) for v in (0, 1, 3999)]
    assert a.settings(0) != c.settings(0)
    inputs = a.inputs(0, n)
    mass = inputs["axes.X.mechanics.bodies.load.mass"]
    assert abs(mass.mean() - 270) < 5 * 27 / math.sqrt(n)
    assert abs(mass.std() - 27) < 5 * 27 / math.sqrt(2 * n)
    k = inputs["axes.X.mechanics.couplings.load.stiffness"] / 3.8e8    # relative to the base model's 3.8e8 N/m
    assert k.min() >= 0.9 and k.max() <= 1.1
    assert abs(k.mean() - 1.0) < 5 * (0.2 / math.sqrt(12)) / math.sqrt(n)
    primary = inputs["axes.X.mechanics.bodies.primary.mass"]
    assert primary.min() > 0                                             # lognormal: never negative
    assert abs(primary.mean() - 92) < 5 * 9.2 / math.sqrt(n)             # mean and std of the variable itself
    assert abs(primary.std() - 9.2) < 5 * 9.2 * 1.2 / math.sqrt(2 * n)
    # the variant's settings are the inputs (SI), as --set receives them
    first = dict(s.split("=", 1) for s in a.settings(0))
    assert first["axes.X.mechanics.bodies.load.mass"] == f'"{float(mass[0])!r} kg"'   # kg is SI: the same number


def test_grid_parameters_cross_the_draws(tmp_path):
    """Grid x samples: variant i is grid point i // samples with draw i % samples (common random numbers)."""
    plan = _plan(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["modal"]
[[parameters]]
path = "axes.X.controller.Kv"
logrange = ["10 1/s", "40 1/s", 3]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "uniform"
low = "250 kg"
high = "290 kg"
samples = 5
""")
    assert plan.variants == 15
    inputs = plan.inputs(0, 15)
    np.testing.assert_allclose(inputs["axes.X.controller.Kv"], np.repeat([10.0, 20.0, 40.0], 5), rtol=1e-14)
    mass = inputs["axes.X.mechanics.bodies.load.mass"]
    np.testing.assert_array_equal(mass[:5], mass[5:10])
    assert ((mass >= 250) & (mass <= 290)).all()


def test_an_unstable_loop_held_by_the_current_limits_is_not_stable(tmp_path, client):
    """``simulate.stable`` is ``sicomat simulate``'s verdict: with the position gain x1000 the drive's current
    limits hold the unstable loop in a bounded oscillation whose figures look plausible (a following error of
    millimetres, no divergence): the row says unstable, as simulation_verdict does for the same run, and a
    constraint on it rejects the variant."""
    from sicomat import build_servo_loop, load_model
    from sicomat.simulation import simulate
    from sicomat.simulation.checks import simulation_verdict
    from sicomat.studies import Study
    from sicomat.tasks.simulate import choose_profile

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["simulate"]
constraints = ["simulate.stable == true"]
[simulate]
duration = "0.3 s"
[[parameters]]
path = "axes.X.controller.Kp_normalized"
values = [1.0, 1000.0]
relative = true
""")
    study = Study(path)
    table = study.run(client).to_pandas()
    assert list(table["simulate.stable"]) == [True, False] and list(table["simulate.diverged"]) == [False, False]
    assert list(table["constraints_ok"]) == [True, False]
    for v in range(2):
        machine = load_model(tmp_path / "paper_5m4s.toml", study.settings(v))     # as sicomat CMD --set reads them
        loop = build_servo_loop(machine)
        profile, _ = choose_profile(machine.axes["X"].trajectory, None, None, None, None)
        series = simulate(loop, profile, 0.3)
        assert table["simulate.stable"][v] == simulation_verdict(loop, series, profile).stable
        assert table["simulate.max_following_error"][v] == pytest.approx(series.metrics.max_following_error,
                                                                          abs=1e-12)


def test_failed_variants_are_rows_with_their_message(tmp_path, client):
    """Draws that make the model invalid (a negative mass) fail their own variant, never the study: the row
    keeps its inputs, has the message in ``error``, NaN metrics and constraints_ok false."""
    from sicomat.studies import Study

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
seed = 1
analyses = ["modal", "margins"]
constraints = ["modal.f1_hz > 0"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "normal"
mean = "20 kg"
std = "40 kg"
samples = 12
""")
    results = Study(path).run(client)
    table = results.to_pandas()
    negative = table["axes.X.mechanics.bodies.load.mass"] <= 0
    assert 0 < negative.sum() < 12                       # the seed gives both (checked, not assumed)
    assert (table["error"].notna() == negative).all()
    assert table.loc[negative, "error"].str.contains("mass").all()
    assert table.loc[negative, "modal.f1_hz"].isna().all()
    assert not table.loc[negative, "constraints_ok"].any()
    assert table.loc[~negative, "constraints_ok"].all()
    summary = results.summary()
    assert summary["failed"] == int(negative.sum())
    assert summary["errors"][0]["variant"] == int(table.index[negative][0])


def test_constraints_are_the_expressions_on_the_table(tmp_path, client):
    from sicomat.studies import Study

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["margins"]
constraints = ["margins.velocity.phase_margin_deg >= 30", "margins.stable == true",
               "margins.position.crossover_hz < margins.velocity.crossover_hz"]
[[parameters]]
path = "axes.X.controller.Kp_normalized"
range = ["60 1/s", "140 1/s", 5]
""")
    table = Study(path).run(client).to_pandas()
    expected = ((table["margins.velocity.phase_margin_deg"] >= 30) & table["margins.stable"].astype(bool)
                & (table["margins.position.crossover_hz"] < table["margins.velocity.crossover_hz"]))
    assert expected.any() and not expected.all()          # the range crosses the 30 degree bound
    assert (table["constraints_ok"].astype(bool) == expected).all()


def test_constraint_bounds_with_units_and_on_inputs(tmp_path, client):
    """A bound with its unit is converted to the column's (kHz to Hz, t to kg), and a constraint may read an input
    (the varied mass) as well as a metric: the same expressions written on the table in its units. Without the
    conversion every variant would pass both; before inputs were joined, none passed the second."""
    from sicomat.studies import Study

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["modal"]
constraints = ["modal.f2_hz >= 0.375 kHz", "axes.X.mechanics.bodies.load.mass >= 0.175 t"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["150 kg", "200 kg", "250 kg", "300 kg", "350 kg"]
""")
    table = Study(path).run(client).to_pandas()
    expected = (table["modal.f2_hz"] >= 375.0) & (table["axes.X.mechanics.bodies.load.mass"] >= 175.0)
    assert (table["modal.f2_hz"] < 375.0).any() and (table["axes.X.mechanics.bodies.load.mass"] < 175.0).any()
    assert expected.any()
    assert (table["constraints_ok"].astype(bool) == expected).all()


@pytest.mark.parametrize("text, unit, bound", [
    ("modal.f1_hz >= 100 rad/s", "Hz", 100 / (2 * math.pi)),       # an angular frequency: / 2 pi
    ("modal.f1_hz >= 0.08 kHz", "Hz", 80.0),
    ("margins.velocity.phase_margin_deg >= 0.5 rad", "°", 0.5 * 180 / math.pi),
    ("margins.velocity.gain_margin_db >= 6 dB", "dB", 6.0),           # logarithmic: as written
    ("simulate.overshoot_percent <= 5 %", "%", 5.0),                 # a percentage column: as written
    ("modal.zeta1 >= 1 %", "1", 0.01),                               # a ratio: 1 % is 0.01
    ("simulate.max_following_error <= 20 um", "m", 20e-6),
    ("modal.moving_mass <= 300 g*m^2", "kg·m²", 0.3),
    ("size.peak_torque <= 4 kN*cm", "N·m", 40.0),
    ("modal.f1_hz >= 80", "Hz", 80.0),                               # a plain number: the column's unit
])
def test_a_bound_with_a_unit_is_converted_to_the_column_unit(text, unit, bound):
    from sicomat.studies.spec import Constraint

    converted = Constraint.parse(text).in_unit(unit)
    assert converted.unit is None and converted.bound == pytest.approx(bound, rel=1e-14)


@pytest.mark.parametrize("text, unit, words", [
    ("margins.velocity.gain_margin_db >= 6 Hz", "dB", "in dB"),
    ("modal.f1_hz >= 80 kg", "Hz", "dimension mass"),
    ("tune.Kp >= 3 N*s/m", None, "no unit"),
    ("modal.f1_hz >= 80 blorb", "Hz", "unknown unit"),
])
def test_a_bound_whose_unit_does_not_fit_is_refused(text, unit, words):
    from sicomat.studies.spec import Constraint

    with pytest.raises(ValueError, match=words):
        Constraint.parse(text).in_unit(unit)


def test_a_batch_too_large_for_the_memory_limit_runs_its_variants_one_by_one(tmp_path, client, monkeypatch):
    """A chunk's simulations run as one batch; when that batch is refused (here the memory limit: one variant's
    records fit, four do not) the chunk runs them one by one instead of failing the study, with the same
    numbers (a variant's results do not depend on its batch). Before, the ResourceError failed the study."""
    from sicomat.studies import Study

    text = """
base = "paper_5m4s.toml"
analyses = ["simulate"]
chunk_size = 4
[simulate]
duration = "0.5 s"
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["200 kg", "230 kg", "260 kg", "290 kg"]
"""
    reference = Study(write_study(tmp_path, text, "free.toml")).run(client).to_pandas()
    # 4000 steps x 4 values x 8 bytes, twice: 256 kB a variant (+ the setpoint table), 1 MB for the four
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", "600 kB")
    limited = Study(write_study(tmp_path, text, "limited.toml")).run(client).to_pandas()
    assert limited["error"].isna().all()
    pd.testing.assert_frame_equal(limited, reference)


BAD = [
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.lod.mass"
values = ["1 kg"]""", "parameters.0.path", "lod"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
range = ["100 kg", "200 kg", 0]""", "parameters.0.range", "empty range"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "normal"
mean = "270 kg"
std = "-10 kg"
samples = 10""", "parameters.0.std", "negative spread"),
    ("""constraints = ["modal.f9_hz >= 80"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "constraints.0", "unknown metric"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "uniform"
low = "300 kg"
high = "200 kg"
samples = 3""", "parameters.0.high", "negative spread"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg", "-3 kg"]""", "parameters.0.path", "-3"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
valus = ["1 kg"]""", "parameters.0.valus", "unknown key"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
range = ["100 kg", "200 kg", 1000000000000]""", "parameters.0.range", "at most"),   # refused before any allocation
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
range = ["100 kg", "200 kg", 10000]
[[parameters]]
path = "axes.X.mechanics.bodies.primary.mass"
range = ["90 kg", "95 kg", 10000]""", "parameters", "100000000 variants"),
    ("""constraints = ["modal.f1_hz >= 80 kg"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "constraints.0", "dimension mass"),
    ("""constraints = ["modal.f1_hz >="]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "constraints", "METRIC OPERATOR BOUND"),
    ("""[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = [[1, 2]]""", "parameters.0.values.0:", "valid number"),    # not pydantic's "values.0.float"
    ("""analyses = ["simulate"]
[simulate]
move = "10 mm"
max_velocity = "0 m/s"
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "simulate.max_velocity", "> 0"),                     # sicomat simulate refuses it too
    ("""analyses = ["simulate"]
[simulate]
duration = "1e9 s"
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "simulate.duration", "SICOMAT_MAX_MEMORY"),          # before any work, not in a worker
    ("""[tune]
velocity_crossover = "-5 Hz"
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "tune.velocity_crossover", "> 0"),               # was a failed row per variant
    ("""[tune]
min_gain_margin = -5
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "tune.min_gain_margin", "> 0"),                  # was accepted
    ("""[size]
inertia_ratio_limit = -1
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "size.inertia_ratio_limit", "greater than 0"),   # was a failed row per variant
    ("""seed = -3
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["1 kg"]""", "seed", "greater than or equal to 0"),
    ("""[[parameters]]
path = "axes.X.mechanics.parts.0.id"
catalogue = "motor"
where = ["peak_torque >= 1e6 N*m"]""", "parameters.0", "relative"),
]


@pytest.mark.parametrize("body, key, words", BAD, ids=[b[1] + ":" + b[2] for b in BAD])
def test_bad_study_files_are_refused_before_any_work(tmp_path, body, key, words):
    """One line naming the study file and the key, exit status 2, and nothing written (no results folder)."""
    from sicomat.cli.main import app

    if "parts.0.id" in body:   # a catalogue list: the 5M4S has no parts; refused for the filter or the path
        key, words = "parameters.0", ""
    analyses = "" if body.startswith("analyses") else 'analyses = ["modal"]\n'    # a body may give its own
    path = write_study(tmp_path, 'base = "paper_5m4s.toml"\n' + analyses + body)
    result = runner.invoke(app, ["study", str(path), "--json"])
    assert result.exit_code == 2, result.output
    line = result.output.strip()
    assert "\n" not in line and "Traceback" not in line
    assert str(path) in line and key in line and words in line
    assert not (tmp_path / "study.results").exists()


def test_the_json_summary_and_the_csv_table(tmp_path):
    """``--json``: the contract keys; ``--csv``: the table as CSV; the results beside the study file."""
    import json

    from sicomat.cli.main import app

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["modal"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["200 kg", "300 kg"]
[pareto]
maximize = ["modal.f2_hz"]
minimize = ["axes.X.mechanics.bodies.load.mass"]
""")
    result = runner.invoke(app, ["study", str(path), "--json", "--csv", "--workers", "1", "--no-figures"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    assert {"variants", "failed", "elapsed_s", "results", "pareto"} <= set(payload)
    assert payload["variants"] == 2 and payload["failed"] == 0
    assert Path(payload["results"]) == tmp_path / "study.results" / "results.csv"
    table = pd.read_csv(payload["results"])
    assert list(table["axes.X.mechanics.bodies.load.mass"]) == [200.0, 300.0]
    # a lighter load raises the load mode: the 200 kg variant dominates on both objectives
    assert table["modal.f2_hz"][0] > table["modal.f2_hz"][1]
    assert [v["variant"] for v in payload["pareto"]["variants"]] == [0]


def test_every_sizing_check_has_its_columns():
    """The study's size columns name every check ``sicomat size`` makes (read from the source with ast)."""
    import ast

    from sicomat.studies.analyses import SIZE_CHECKS

    source = (ROOT / "src" / "sicomat" / "tasks" / "size_checks.py").read_text()
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "make_check" and node.args:
            first = node.args[0]
            if isinstance(first, ast.Constant):
                names.add(first.value)
            elif isinstance(first, ast.JoinedStr):   # f"peak_{word}", f"rms_{word}"
                prefix = first.values[0].value
                names |= {prefix + "torque", prefix + "force"}
    assert names == set(SIZE_CHECKS)


def test_the_study_object_refuses_unknown_columns_and_objectives(tmp_path, client):
    from sicomat.studies import Study

    path = write_study(tmp_path, """
base = "paper_5m4s.toml"
analyses = ["modal"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
values = ["200 kg", "300 kg"]
""")
    results = Study(path).run(client)
    with pytest.raises(ModelError, match="no objectives"):
        results.pareto()
    with pytest.raises(ModelError, match="no column 'modal.f7_hz'"):
        results.pareto(maximize=["modal.f7_hz"], minimize=["modal.f1_hz"])


SMALL = """
base = "paper_5m4s.toml"
analyses = ["modal", "margins"]
constraints = ["margins.velocity.phase_margin_deg >= 30"]
[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
range = ["150 kg", "400 kg", 6]
[[parameters]]
path = "axes.X.mechanics.couplings.load.stiffness"
values = ["2e8 N/m", "5e8 N/m"]
[pareto]
maximize = ["margins.velocity.phase_margin_deg", "axes.X.mechanics.bodies.load.mass"]
"""


def test_the_pareto_front_and_the_figures_of_a_study(tmp_path, client):
    """``pareto()`` is the definition applied to the feasible rows (written out here: no other feasible row at
    least as good in both objectives and better in one); every figure is written, the Pareto plot highlighting
    exactly the front."""
    import matplotlib.image

    from sicomat.studies import Study

    results = Study(write_study(tmp_path, SMALL)).run(client, figures=True)
    table = results.to_pandas()
    feasible = table[table["constraints_ok"].astype(bool)]
    a = feasible["margins.velocity.phase_margin_deg"].to_numpy()
    b = feasible["axes.X.mechanics.bodies.load.mass"].to_numpy()
    expected = {int(v) for v, x, y in zip(feasible["variant"], a, b)
                if not any((a >= x) & (b >= y) & ((a > x) | (b > y)))}
    front = results.pareto()
    assert set(front["variant"]) == expected and 0 < len(expected) < len(feasible)
    assert len(feasible) < len(table)                     # the constraint removes some: the front is among the rest
    written = {Path(p).name for p in results.info["figures"]}
    assert written == {"scatter_matrix.png", "parallel_coordinates.png", "histograms.png", "pareto.png"}
    for name in written:
        assert matplotlib.image.imread(tmp_path / "study.results" / name).shape[0] > 300
    fig = results.plot("pareto")
    highlighted = [c for c in fig.axes[0].collections if c.get_gid() == "front"][0]
    assert len(highlighted.get_offsets()) == len(expected)
    assert fig.axes[0].get_ylabel().startswith("axes.X.mechanics.bodies.load.mass (kg)")   # the study's units
    summary = results.summary()
    assert [v["variant"] for v in summary["pareto"]["variants"]] == list(front["variant"])


@pytest.mark.parametrize("lines, key", [
    ('constraints = ["axes.X.mechanics.parts.2.id >= 3"]', "constraints.0"),
    ('[pareto]\nmaximize = ["modal.f1_hz", "axes.X.mechanics.parts.2.id"]', "pareto.maximize.1"),
    ('[pareto]\nminimize = ["modal.f1_hz", "axes.X.mechanics.parts.2.mounting"]', "pareto.minimize.1"),
])
def test_constraints_and_objectives_on_words_are_refused_before_any_work(tmp_path, lines, key):
    """Catalogue ids and words have no order: a constraint or a Pareto objective on them is one line, exit status
    2, nothing computed (before, the objective failed with a traceback once the whole study had run)."""
    from sicomat.cli.main import app

    (tmp_path / "ballscrew_catalog.toml").write_text((EXAMPLES / "ballscrew_catalog.toml").read_text())
    study = tmp_path / "study.toml"
    table = lines if lines.startswith("[") else ""
    study.write_text('base = "ballscrew_catalog.toml"\nanalyses = ["modal"]\n' + ("" if table else lines + "\n")
                     + '[[parameters]]\npath = "axes.X.mechanics.parts.2.id"\ncatalogue = "ball-screw"\n'
                     'where = ["diameter == 32 mm"]\n[[parameters]]\npath = "axes.X.mechanics.parts.2.mounting"\n'
                     'values = ["fixed-supported", "fixed-fixed"]\n' + table + "\n")
    result = runner.invoke(app, ["study", str(study), "--workers", "1"])
    line = result.output.strip()
    assert result.exit_code == 2 and "\n" not in line and key in line and "not numbers" in line, result.output
    assert not (tmp_path / "study.results").exists()


def test_a_study_from_a_dict_equals_the_same_study_from_its_file(tmp_path, client):
    """``Study.from_dict``: the study file's data without the file, ``base`` relative to ``folder``; the same plan
    and table as the file gives; a refusal names ``<study data>`` and the key, as for a file."""
    import tomllib

    from sicomat.studies import Study

    path = write_study(tmp_path, SMALL)
    data = tomllib.loads(SMALL)
    from_file = Study(path)
    from_dict = Study.from_dict(data, folder=tmp_path, out=tmp_path / "from-dict")
    assert from_dict.variants == from_file.variants == 12
    assert [from_dict.settings(v) for v in range(12)] == [from_file.settings(v) for v in range(12)]
    assert Study.from_dict(data, folder=tmp_path).out == tmp_path / "study.results"
    pd.testing.assert_frame_equal(from_dict.run(client).to_pandas(), from_file.run(client).to_pandas())
    with pytest.raises(ModelError, match=r"<study data>.*parameters\.0\.range"):
        Study.from_dict({**data, "parameters": [{"path": "axes.X.mechanics.bodies.load.mass",
                                                 "range": ["1 kg", "2 kg", 0]}]}, folder=tmp_path)


def test_the_dry_run_shows_the_plan_and_computes_nothing(tmp_path):
    """``--dry-run``: the variant count and chunks, each parameter's levels, the metrics, the constraints as the
    study will judge them (a bound with a unit converted to its column's) and variant 0's --set options; no
    worker started, nothing written."""
    import json

    from sicomat.cli.main import app

    path = write_study(tmp_path, SMALL.replace('constraints = ["margins.velocity.phase_margin_deg >= 30"]',
                                               'constraints = ["margins.velocity.phase_margin_deg >= 0.5 rad", '
                                               '"margins.stable == true"]'))
    result = runner.invoke(app, ["study", str(path), "--dry-run", "--json"])
    assert result.exit_code == 0, result.output
    plan = json.loads(result.stdout)
    assert (plan["variants"], plan["grid"], plan["samples"]) == (12, [6, 2], 1)
    assert plan["chunks"] == -(-12 // plan["chunk_size"])
    assert [(q["path"], q["way"], q["levels"]) for q in plan["parameters"]] == [
        ("axes.X.mechanics.bodies.load.mass", "range", 6), ("axes.X.mechanics.couplings.load.stiffness", "values", 2)]
    assert "margins.velocity.phase_margin_deg" in plan["metrics"] and "margins.stable" in plan["metrics"]
    first, second = plan["constraints"]
    assert first["bound"] == pytest.approx(0.5 * 180 / math.pi, rel=1e-14) and first["unit"] == "°"
    assert (second["bound"], second["unit"]) == (True, None)
    assert plan["first_variant"] == ['axes.X.mechanics.bodies.load.mass="150.0 kg"',
                                     'axes.X.mechanics.couplings.load.stiffness="2e8 N/m"']
    text = runner.invoke(app, ["study", str(path), "--dry-run"])
    assert text.exit_code == 0 and "12 variants" in text.output and "28.6479 °" in text.output
    assert not (tmp_path / "study.results").exists()


def test_outputs_follow_the_output_policy_before_any_work(tmp_path):
    """``--out`` a file, a results name taken by a folder, an output that is the base model: one line, exit 2,
    and no chunk computed."""
    from sicomat.cli.main import app

    path = write_study(tmp_path, SMALL)
    (tmp_path / "a-file").write_text("x")
    result = runner.invoke(app, ["study", str(path), "--out", str(tmp_path / "a-file"), "--workers", "1"])
    assert result.exit_code == 2 and "a-file" in result.output and "is a file" in result.output
    out = tmp_path / "out"
    (out / "results.parquet").mkdir(parents=True)
    result = runner.invoke(app, ["study", str(path), "--out", str(out), "--workers", "1"])
    assert result.exit_code == 2 and "results.parquet" in result.output and "not a regular file" in result.output
    assert not list((out / "chunks").glob("*.parquet"))
    inside = tmp_path / "inside"
    inside.mkdir()
    (inside / "paper_5m4s.toml").write_text((EXAMPLES / "paper_5m4s.toml").read_text())
    (inside / "manifest.json").symlink_to(inside / "paper_5m4s.toml")   # an output that is the base model
    (inside / "study.toml").write_text(SMALL)
    result = runner.invoke(app, ["study", str(inside / "study.toml"), "--out", str(inside), "--workers", "1"])
    assert result.exit_code == 2 and "would replace the base model" in result.output
    assert (inside / "paper_5m4s.toml").read_text() == (EXAMPLES / "paper_5m4s.toml").read_text()
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")                            # a link to a folder that is not there
    result = runner.invoke(app, ["study", str(path), "--out", str(dangling), "--workers", "1"])
    line = result.output.strip()
    assert result.exit_code == 2 and "\n" not in line and "nowhere" in line and "does not exist" in line, line
    assert not (tmp_path / "nowhere").exists()


def test_options_that_contradict_and_ctrl_c(tmp_path, monkeypatch):
    from sicomat.cli.main import app
    from sicomat.studies import Study

    path = write_study(tmp_path, SMALL)
    result = runner.invoke(app, ["study", str(path), "--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"])
    assert result.exit_code == 2 and "--workers" in result.output
    result = runner.invoke(app, ["study", str(path), "--workers", "0"])
    assert result.exit_code == 2 and "--workers" in result.output
    for address in ("nonsense", "foo://x:1", "tcp://host:notaport"):   # refused by distributed's parser, not reached
        result = runner.invoke(app, ["study", str(path), "--scheduler", address])
        line = result.output.strip()
        assert result.exit_code == 2 and "\n" not in line and "--scheduler" in line and address in line, result.output
    assert not (tmp_path / "study.results" / "results.parquet").exists()

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(Study, "run", interrupted)
    result = runner.invoke(app, ["study", str(path)])
    assert result.exit_code == 130 and "--resume" in result.output and "Traceback" not in result.output


def test_the_circle_test_after_tuning_equals_the_verbs_one_by_one(tmp_path, client):
    """``tune`` then ``circle`` on the X-Y table: X is tuned in each variant and the circle runs on the tuned
    machine, as ``tune --write`` then ``circle`` would (the same verbs: rtol 1e-12)."""
    from sicomat import load_model, build_servo_loop, tune_frequency
    from sicomat.description.units import UNITS, parse_quantity
    from sicomat.studies import Study
    from sicomat.tasks.analysis import tuned_machine
    from sicomat.tasks.circle import circle_report
    from sicomat.tuning import TuningTargets

    (tmp_path / "xy_table.toml").write_text((EXAMPLES / "xy_table.toml").read_text())
    path = tmp_path / "study.toml"
    path.write_text('base = "xy_table.toml"\nanalyses = ["tune", "circle"]\naxis = "X"\n'
                    '[[parameters]]\npath = "axes.Y.controller.Kv"\nvalues = ["30 1/s", "45 1/s"]\n'
                    '[circle]\nradius = "50 mm"\nfeed = "2000 mm/min"\n')
    table = Study(path).run(client).to_pandas()
    assert table["error"].isna().all()
    for kv, row in zip((30, 45), table.to_dict("records")):
        machine = load_model(tmp_path / "xy_table.toml", [f"axes.Y.controller.Kv={kv}"])
        tuned = tune_frequency(build_servo_loop(machine, "X"), TuningTargets(), suggest_notch=False).tuned
        machine = tuned_machine(machine, "X", {"Kp": tuned.Kp, "Kp_normalized": tuned.Kp_normalized,
                                               "Ti": tuned.Ti, "Kv": tuned.Kv})
        # the feed as the study file's "2000 mm/min" reads (15 digits, as every model-file quantity): the last
        # sample of the circle moves with the 16th digit of the feed (2e-4 of the deviation), so the same input
        feed = parse_quantity("2000 mm/min", UNITS["velocity"])
        test, payload, _ = circle_report(machine, 0.05, feed)
        assert row["tune.Kv"] == pytest.approx(tuned.Kv, rel=1e-12)
        assert row["circle.circular_deviation"] == pytest.approx(payload["circular_deviation"], rel=1e-12)
        assert row["circle.max_contour_error"] == pytest.approx(payload["max_contour_error"], rel=1e-12)
    # the Y gain changes the contour: the rows differ (the variants are not the base model twice)
    assert table["circle.max_contour_error"][0] != table["circle.max_contour_error"][1]


def failing_chunk(chunk):
    """A task that fails on the worker (outside any variant): a bug, a lost worker."""
    raise RuntimeError("the worker lost its disk")


def test_a_chunk_the_cluster_gives_up_on_is_one_clear_error(tmp_path, client, monkeypatch):
    """Not a traceback: an AnalysisError that says what failed, what is kept and how to resume."""
    from sicomat.errors import AnalysisError
    from sicomat.studies import Study, analyses

    monkeypatch.setattr(analyses, "run_chunk", failing_chunk)
    with pytest.raises(AnalysisError, match="RuntimeError: the worker lost its disk.*--resume"):
        Study(write_study(tmp_path, SMALL)).run(client)


def test_the_local_cluster_size(monkeypatch):
    """One worker per usable core, no more than the chunks to compute nor than memory holds at 512 MB each."""
    import types

    import psutil

    from sicomat.studies.engine import WORKER_MEMORY, default_workers

    monkeypatch.setattr(psutil, "virtual_memory", lambda: types.SimpleNamespace(available=10 * WORKER_MEMORY))
    assert default_workers(64, 50) == 10       # memory
    assert default_workers(8, 3) == 3          # chunks
    assert default_workers(4, 50) == 4         # cores
    monkeypatch.setattr(psutil, "virtual_memory", lambda: types.SimpleNamespace(available=WORKER_MEMORY // 2))
    assert default_workers(4, 50) == 1         # always one
