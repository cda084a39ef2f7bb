"""The figures of a study's results table (`sicomat.plots.study`): built from a synthetic table written here (failed
variants, a text column, a bool colour, an undefined metric), read back through their artists — the points and
lines drawn are the succeeded variants, the histograms' quantiles and shares are the hand-derived ones, the
Pareto staircase runs through the front found by the definition — and their refusals of bad columns."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.colors import to_rgba
from numpy.testing import assert_allclose, assert_array_equal

from sicomat.errors import ModelError
from sicomat.plots.base import save_figure
from sicomat.plots.study import histograms, parallel_coordinates, pareto_plot, scatter_matrix
from sicomat.plots.study_table import column_label, format_value
from sicomat.studies.pareto import pareto_front
from test_study_pareto import brute_front

MASS, MOTOR, F1 = "axes.X.mechanics.bodies.load.mass", "axes.X.drive.motor", "modal.f1_hz"
PM, FE, OK = "margins.velocity.phase_margin_deg", "simulate.max_following_error_m", "constraints_ok"
METRICS = [F1, PM, FE]
FAILED = (3, 11, 27, 35)
UNDEFINED_PM = 5          # a succeeded variant whose phase margin is undefined (NaN)
N = 40


def study_table() -> pd.DataFrame:
    """40 variants of a load mass and a motor; 4 failed (metrics NaN, an error text), one phase margin undefined."""
    rng = np.random.default_rng(7)
    mass = rng.uniform(100.0, 400.0, N)
    table = pd.DataFrame({
        "variant": np.arange(N), MASS: mass, MOTOR: rng.choice(["mot-060", "mot-080", "mot-100"], N),
        F1: np.sqrt(4e8 / mass) / (2 * np.pi), PM: 30.0 + 30.0 * rng.random(N),
        FE: 1e-6 * (mass / 100.0) * (1.0 + rng.random(N)),
    })
    table[OK] = pd.Series(table[FE] < 6e-6, dtype=object)
    table["error"] = None
    for i in FAILED:
        table.loc[i, METRICS] = np.nan
        table.loc[i, OK] = None
        table.loc[i, "error"] = "AnalysisError: the velocity loop is unstable"
    table.loc[UNDEFINED_PM, PM] = np.nan
    return table


def succeeded(table):
    return table["error"].isna().to_numpy()


def points(ax) -> int:
    return sum(len(c.get_offsets()) for c in ax.collections if isinstance(c, PathCollection))


# --------------------------------------------------------------------------- scatter matrix
def test_scatter_matrix_draws_the_succeeded_variants():
    table = study_table()
    ok = succeeded(table)
    cols = [MASS, *METRICS]
    fig = scatter_matrix(table, cols, color=OK)
    k = len(cols)
    main = fig.axes[:k * k]                      # the k×k panels, then the diagonal's twin axes
    for i in range(k):
        for j in range(k):
            ax = main[i * k + j]
            if i == j:
                # the diagonal histogram (on its twin) counts every succeeded variant with a value
                twin = fig.axes[k * k + i]
                expected = int((ok & table[cols[i]].notna()).sum())
                assert sum(p.get_height() for p in twin.patches) == expected
                continue
            both = ok & table[cols[i]].notna().to_numpy() & table[cols[j]].notna().to_numpy()
            assert points(ax) == both.sum() == (35 if PM in (cols[i], cols[j]) else 36)
            # one collection per colour, each with its own variants: False red, True green
            by_label = {c.get_label(): c for c in ax.collections}
            for value, colour in ((False, "tab:red"), (True, "tab:green")):
                c = by_label[f"{OK} = {value}"]
                assert len(c.get_offsets()) == (both & (table[OK] == value).to_numpy()).sum()
                assert_allclose(c.get_facecolor()[0][:3], to_rgba(colour)[:3])
    xlabels = [main[(k - 1) * k + j].get_xlabel().replace("\n", "") for j in range(k)]
    assert xlabels == [MASS, f"{F1} (Hz)", f"{PM} (°)", f"{FE} (m)"]
    assert [main[i * k].get_ylabel().replace("\n", "") for i in range(k)] == xlabels
    title = fig.get_suptitle()
    assert "36 of 40 variants (4 failed, left out)" in title and "1 with an undefined value" in title
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    n_false = int((ok & (table[OK] == False).to_numpy()).sum())  # noqa: E712 (an object column)
    assert legend == [f"{OK} = False ({n_false})", f"{OK} = True ({36 - n_false})"]
    # the following error (micrometres) is written with its SI prefix, not as an offset "1e-6"
    fig.canvas.draw()
    assert any("µm" in t.get_text() for t in main[(k - 1) * k + k - 1].get_xticklabels())


def test_scatter_matrix_numeric_colour_has_a_colour_bar():
    table = study_table()
    fig = scatter_matrix(table, [F1, FE], color=MASS)
    ax = fig.axes[1]                              # row 0, column 1: f1 against the following error
    (c,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    ok = succeeded(table)
    assert_allclose(c.get_array(), table[MASS].to_numpy()[ok])
    assert any(a.get_ylabel().replace("\n", "") == MASS for a in fig.axes)   # the colour bar's label


# --------------------------------------------------------------------------- parallel coordinates
def test_parallel_coordinates_scales_each_axis_to_its_range():
    table = study_table()
    ok = succeeded(table)
    cols = [MASS, F1, MOTOR, PM]
    fig = parallel_coordinates(table, cols, color=OK)
    ax = fig.axes[0]
    groups = {c.get_label(): c for c in ax.collections if isinstance(c, LineCollection)}
    assert sum(len(c.get_paths()) for c in groups.values()) == ok.sum() == 36
    for value in (False, True):
        rows = ok & (table[OK] == value).to_numpy()
        (label,) = [lab for lab in groups if lab.startswith(f"{OK} = {value} ")]
        segments = np.array([path.vertices for path in groups[label].get_paths()])
        assert segments.shape == (rows.sum(), len(cols), 2)
        assert_array_equal(segments[:, :, 0], np.broadcast_to(np.arange(4.0), segments.shape[:2]))
        # the mass axis: its smallest succeeded value at 0, its largest at 1
        mass = table[MASS].to_numpy()
        lo, hi = mass[ok].min(), mass[ok].max()
        assert_allclose(segments[:, 0, 1], (mass[rows] - lo) / (hi - lo), rtol=1e-12)
        # the motor axis: its three sorted categories at 0, 1/2 and 1
        where = {"mot-060": 0.0, "mot-080": 0.5, "mot-100": 1.0}
        assert_array_equal(segments[:, 2, 1], [where[m] for m in table[MOTOR].to_numpy()[rows]])
    texts = {t.get_gid(): t.get_text() for t in ax.texts if t.get_gid()}
    assert texts["min-0"] == f"{lo:.4g}" and texts["max-0"] == f"{hi:.4g}"
    f1 = table[F1].to_numpy()[ok]
    assert texts["max-1"] == f"{f1.max():.4g} Hz"
    assert {t.get_text() for t in ax.texts} >= {"mot-060", "mot-080", "mot-100"}
    assert [t.get_text().replace("\n", "") for t in ax.get_xticklabels()] == [MASS, f"{F1} (Hz)", MOTOR, f"{PM} (°)"]
    assert "36 of 40 variants (4 failed, left out)" in ax.get_title()


def test_parallel_coordinates_leaves_an_undefined_value_as_a_gap():
    """The undefined phase margin is a NaN vertex (matplotlib breaks the line there), not a line to 0."""
    table = study_table()
    fig = parallel_coordinates(table, [MASS, PM, F1])
    (c,) = [c for c in fig.axes[0].collections if isinstance(c, LineCollection)]
    ok = succeeded(table)
    position = int(np.flatnonzero(np.flatnonzero(ok) == UNDEFINED_PM)[0])
    heights = c.get_paths()[position].vertices[:, 1]
    assert np.isfinite(heights[0]) and np.isnan(heights[1]) and np.isfinite(heights[2])
    # what is drawn: the path cut at the NaN, so the line stops at the mass axis and restarts at f1
    assert len(c.get_segments()[position]) == 2


def test_nullable_bool_and_text_columns_read_as_categories():
    """pandas' nullable "boolean" and "string" columns (pd.NA for the failed variants) work like object columns."""
    table = study_table()
    table[OK] = table[OK].astype("boolean")
    table[MOTOR] = table[MOTOR].astype("string")
    table.loc[list(FAILED), MOTOR] = pd.NA
    ok = succeeded(table)
    fig = parallel_coordinates(table, [MOTOR, F1], color=OK)
    groups = {c.get_label(): c for c in fig.axes[0].collections if isinstance(c, LineCollection)}
    n_true = int((ok & (table[OK] == True).fillna(False).to_numpy()).sum())  # noqa: E712
    assert sorted(groups) == [f"{OK} = False ({36 - n_true})", f"{OK} = True ({n_true})"]
    heights = np.concatenate([[p.vertices[0, 1] for p in c.get_paths()] for c in groups.values()])
    assert set(heights) == {0.0, 0.5, 1.0}


# --------------------------------------------------------------------------- histograms
def tolerance_table() -> pd.DataFrame:
    """101 succeeded values 0, 1, ..., 100 and 3 failed variants; a gain margin whose 10 largest are infinite."""
    values = np.r_[np.arange(101.0), np.nan, np.nan, np.nan]
    gain = values.copy()
    gain[91:101] = np.inf
    return pd.DataFrame({"variant": np.arange(104), PM: values, "margins.velocity.gain_margin_db": gain,
                         OK: [True] * 104, "error": [None] * 101 + ["ModelError: bad variant"] * 3})


def test_histograms_mark_the_quantiles_and_the_share_meeting_a_threshold():
    table = tolerance_table()
    gm = "margins.velocity.gain_margin_db"
    fig = histograms(table, [PM, gm], thresholds={PM: (">=", 40.0), gm: (">=", 6.0)})
    ax_pm, ax_gm = fig.axes[:2]
    lines = {line.get_gid(): line for line in ax_pm.lines}
    # numpy's linear quantile of 0, 1, ..., 100 at p is 100 p exactly (position p (n - 1) = 100 p)
    for q in (5, 50, 95):
        assert_array_equal(lines[f"quantile-{q}"].get_xdata(), [q, q])
    assert_array_equal(lines["threshold"].get_xdata(), [40.0, 40.0])
    # 40, 41, ..., 100 meet ">= 40": 61 of the 101 succeeded values
    assert ax_pm.get_title() == f"≥ 40 °: {100 * 61 / 101:.1f} % meet it (61 of 101 values)"
    assert sum(p.get_height() for p in ax_pm.patches if p.get_gid() == "bar") == 101
    # infinite gain margins meet any lower limit: 6, ..., 90 (85 values) and the 10 infinite ones
    assert ax_gm.get_title() == f"≥ 6 dB: {100 * 95 / 101:.1f} % meet it (95 of 101 values (10 infinite))"
    gids = {line.get_gid() for line in ax_gm.lines}
    # sorted: 0..90 then 10 infinities; the 95 % quantile is at position 95, an infinity: no line, named
    assert {"quantile-5", "quantile-50"} <= gids and "quantile-95" not in gids
    assert "95 %: inf" in [t.get_text() for t in ax_gm.get_legend().get_texts()]
    assert "101 of 104 variants (3 failed, left out)" in fig.get_suptitle()


def test_histograms_count_undefined_values():
    fig = histograms(study_table(), [PM])
    assert fig.axes[0].get_title() == "35 values, 1 undefined"


# --------------------------------------------------------------------------- Pareto plot
def test_pareto_plot_staircase_is_the_front():
    table = study_table()
    ok = succeeded(table)
    for senses in (("max", "max"), ("min", "max"), ("min", "min"), ("max", "min")):
        front = pareto_front(table[[PM, F1]].to_numpy(float), senses)
        fig = pareto_plot(table, PM, F1, senses=senses, front=front)
        ax = fig.axes[0]
        expected = brute_front(table[[PM, F1]].to_numpy(float), senses)
        stair = next(line for line in ax.lines if line.get_gid() == "staircase")
        drawn = {(float(a), float(b)) for a, b in zip(stair.get_xdata(), stair.get_ydata())}
        assert drawn == {(table[PM][i], table[F1][i]) for i in expected}
        assert np.all(np.diff(stair.get_xdata()) >= 0)             # joined along x
        # x "min": a step runs along x first, then in y; x "max": the other way round (the dominated region's edge)
        assert stair.get_drawstyle() == ("steps-post" if senses[0] == "min" else "steps-pre")
        marked = {c.get_gid(): c for c in ax.collections}
        assert len(marked["front"].get_offsets()) == len(expected)
        assert len(marked["variants"].get_offsets()) == (ok & table[PM].notna().to_numpy()).sum() == 35
        labels = sorted(int(t.get_text()) for t in ax.texts if t.get_gid() == "variant-label")
        assert labels == sorted(table["variant"][i] for i in expected)
        assert f"{len(expected)} non-dominated of 36 of 40 variants (4 failed, left out)" in ax.get_title()


def test_pareto_plot_labels_at_most_fifteen():
    # 30 variants on the line x + y = 30, both minimised: all non-dominated
    x = np.arange(30.0)
    table = pd.DataFrame({"variant": np.arange(100, 130), "cost_s": x, "error_m": 30.0 - x, "error": None})
    front = pareto_front(table[["cost_s", "error_m"]].to_numpy(float), ("min", "min"))
    assert len(front) == 30
    fig = pareto_plot(table, "cost_s", "error_m", senses=("min", "min"), front=front)
    ax = fig.axes[0]
    labels = [int(t.get_text()) for t in ax.texts if t.get_gid() == "variant-label"]
    assert len(labels) == 15 and labels[0] == 100 and labels[-1] == 129          # spread, both ends kept
    assert "numbers on 15 of 30" in [t.get_text() for t in ax.get_legend().get_texts()]
    assert ax.get_xlabel() == "cost_s (s), smaller is better"
    assert ax.get_title() == "Pareto front: 30 non-dominated of 30 variants"


# --------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("call, match", [
    (lambda t: scatter_matrix(t, [F1, "modal.f9_hz"]),
     r"plot: scatter matrix: no column 'modal.f9_hz' in the results table; the table has: variant, axes.X"),
    (lambda t: scatter_matrix(t, [F1, MOTOR]),
     r"column 'axes.X.drive.motor' holds text \(e.g. 'mot-0\d0'\), not numbers; the numeric columns are: "
     r"axes.X.mechanics.bodies.load.mass, modal.f1_hz, margins.velocity.phase_margin_deg, "
     r"simulate.max_following_error_m \(got"),
    (lambda t: histograms(t, [OK]), r"column 'constraints_ok' holds true/false values \(e.g. (True|False)\)"),
    (lambda t: scatter_matrix(t, []), r"scatter matrix: no column given"),
    (lambda t: scatter_matrix(t, [F1], color="colour"), r"no column 'colour'"),
    (lambda t: parallel_coordinates(t, [F1, "nope"]), r"parallel coordinates: no column 'nope'"),
    (lambda t: histograms(t, [PM], thresholds={F1: (">=", 1.0)}), r"not among the plotted columns"),
    (lambda t: histograms(t, [PM], thresholds={PM: ("=>", 40.0)}), r"op one of >=, >, <=, <"),
    (lambda t: histograms(t, [PM], thresholds={PM: 40.0}), r"must be \(op, number\)"),
    (lambda t: pareto_plot(t, PM, MOTOR, front=[0]), r"Pareto plot: column 'axes.X.drive.motor' holds text"),
    (lambda t: pareto_plot(t, PM, F1, senses=("max", "best"), front=[0]), r"senses must be two of 'min'/'max'"),
    (lambda t: pareto_plot(t, PM, F1, front=[0, 3]), r"front row 3 is not a succeeded variant"),
    (lambda t: pareto_plot(t, PM, F1, front=[0, 40]), r"front row 40 is not a succeeded variant"),
    (lambda t: pareto_plot(t, PM, F1, front=[0.5]), r"front must be row positions"),
])
def test_bad_columns_are_refused_by_name(call, match):
    with pytest.raises(ModelError, match=match) as info:
        call(study_table())
    assert info.value.path == "plot"


# --------------------------------------------------------------------------- labels and saving
@pytest.mark.parametrize("column, label", [
    ("tune.velocity_bandwidth_hz", "tune.velocity_bandwidth_hz (Hz)"),
    ("a.speed_m_s", "a.speed_m_s (m/s)"),
    ("a.settling_ms", "a.settling_ms (ms)"),
    ("simulate.rise_time_s", "simulate.rise_time_s (s)"),
    ("axes.X.controller.Kv", "axes.X.controller.Kv"),
])
def test_units_come_from_the_name_suffix(column, label):
    assert column_label(column, wrap=False) == label


def test_values_take_an_si_prefix_when_small_or_large():
    assert format_value(1.595e-6, "m") == "1.595 µm"
    assert format_value(12500.0, "Hz") == "12.5 kHz"
    assert format_value(201.2, "Hz") == "201.2 Hz"
    assert format_value(1e-6, "°") == "1e-06 °"            # not an SI unit: no prefix
    assert format_value(0.5, None) == "0.5"


def test_each_figure_saves_as_png(tmp_path):
    table = study_table()
    front = pareto_front(table[[PM, F1]].to_numpy(float), ("max", "max"))
    figures = {
        "scatter": scatter_matrix(table, [MASS, *METRICS], color=OK),
        "parallel": parallel_coordinates(table, [MASS, F1, MOTOR, PM, FE], color=OK),
        "histograms": histograms(table, METRICS, thresholds={PM: (">=", 40.0)}),
        "pareto": pareto_plot(table, PM, F1, senses=("max", "max"), front=front),
    }
    for name, fig in figures.items():
        path = save_figure(fig, tmp_path / f"{name}.png")
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
