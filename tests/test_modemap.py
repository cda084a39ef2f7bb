"""The mode map over the stroke (`sicomat modemap`, `sicomat.mode_map`) and `tune --all-positions`
(issue 12, §4): against the drive-train formulas written out here by hand, the shapes the field knows
(a fixed–supported screw is softest at the far end, a fixed–fixed one at mid-stroke, an end-driven belt
at the idler, an omega belt at mid-stroke), the JSON contract and bad input."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

import sicomat
from sicomat.cli.main import app
from sicomat.errors import AnalysisError, ModelError
from sicomat.io.modelfile import load_model

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
runner = CliRunner()

# the screw axis of ComponentsSpec's example: values in SI, as the hand formulas below use them
J_MOTOR, K_COUPLING, J_COUPLING = 23e-4, 18000.0, 1.2e-4          # kg·m², N·m/rad, kg·m²
P, D, D_R, L = 0.010, 0.040, 0.034, 1.2                           # lead per rev, diameters, length (m)
K_NUT = K_BEARING = 1.0e9                                          # N/m
M_TABLE = 350.0                                                    # kg
E, G = 2.06e11, 7.9e10                                             # steel defaults (docs/components.md)

SERVO = """
[axes.X.drive]
type = "first-order"
force_constant = "1.5 N*m/A"
bandwidth = "1500 Hz"
peak_current = "24 A"

[axes.X.controller]
type = "P-PI"
position_sensor = "encoder"
velocity_sensor = "encoder"
Kv = "30 1/s"
Kp_normalized = "100 1/s"
Ti = "8 ms"
position_period = "1 ms"
velocity_period = "125 us"
"""


def screw_model(tmp_path: Path, *, mounting: str = "fixed-supported", detail: str = "full", density: float = 7850.0,
                coupling_inertia: float = J_COUPLING, shear_modulus: float = G, name: str = "screw.toml") -> Path:
    text = f"""
[axes.X.mechanics]
type = "components"
detail = "{detail}"
[[axes.X.mechanics.parts]]
kind = "motor"
rotor_inertia = {J_MOTOR!r}
[[axes.X.mechanics.parts]]
kind = "coupling"
inertia = {coupling_inertia!r}
torsional_stiffness = {K_COUPLING!r}
[[axes.X.mechanics.parts]]
kind = "ball-screw"
lead = "{P * 1e3!r} mm"
diameter = {D!r}
root_diameter = {D_R!r}
length = {L!r}
mounting = "{mounting}"
nut_stiffness = {K_NUT!r}
bearing_stiffness = {K_BEARING!r}
density = {density!r}
shear_modulus = {shear_modulus!r}
[[axes.X.mechanics.parts]]
kind = "table"
mass = {M_TABLE!r}
[[axes.X.mechanics.parts]]
kind = "encoder"
resolution = 1048576
""" + SERVO
    path = tmp_path / name
    path.write_text(text)
    return path


# the belt: AT10 25 mm values (catalogue entry belt-at10-25mm), written inline
R_PULLEY, J_PULLEY, C_SPEC, MPL = 0.0382, 2.528e-4, 5.5e5, 0.16
J_BELT_MOTOR, M_CARRIAGE, M_BELT_MOTOR, C_BELT = 7e-4, 25.0, 6.0, 1.5


def belt_model(tmp_path: Path, arrangement: str, detail: str = "full") -> Path:
    text = f"""
[axes.X.mechanics]
type = "components"
detail = "{detail}"
[[axes.X.mechanics.parts]]
kind = "motor"
rotor_inertia = {J_BELT_MOTOR!r}
mass = {M_BELT_MOTOR!r}
[[axes.X.mechanics.parts]]
kind = "belt"
drive_pulley_radius = {R_PULLEY!r}
drive_pulley_inertia = {J_PULLEY!r}
idler_pulley_radius = {R_PULLEY!r}
idler_pulley_inertia = {J_PULLEY!r}
specific_stiffness = {C_SPEC!r}
mass_per_length = {MPL!r}
arrangement = "{arrangement}"
length = {C_BELT!r}
[[axes.X.mechanics.parts]]
kind = "table"
mass = {M_CARRIAGE!r}
""" + SERVO
    path = tmp_path / f"belt-{arrangement}-{detail}.toml"
    path.write_text(text)
    return path


def first_modes(path: Path, points: int = 21, **kw) -> sicomat.ModeMap:
    return sicomat.mode_map(load_model(path), points=points, **kw)


# --------------------------------------------------------------------------- hand formulas
LEAD = P / (2 * math.pi)                                           # m/rad
AREA = math.pi * D_R ** 2 / 4                                      # root diameter (THK, NSK)
POLAR = math.pi * D_R ** 4 / 32


def axial_compliance(x: float, mounting: str) -> float:
    """m/N: shaft A·E/x (fixed–supported) with nut and bearing in series; fixed–fixed: two paths, each a
    shaft segment in series with its own fixed bearing, in parallel, then the nut in series."""
    if mounting == "fixed-supported":
        return x / (AREA * E) + 1 / K_NUT + 1 / K_BEARING
    k1 = 1 / (x / (AREA * E) + 1 / K_BEARING)
    k2 = 1 / ((L - x) / (AREA * E) + 1 / K_BEARING)
    return 1 / K_NUT + 1 / (k1 + k2)


def torsion_compliance(x: float, shear_modulus: float = G) -> float:
    """rad/(N·m): G·π·d_r⁴/(32·x) over the shaft from the motor-side end to the nut, as its compliance."""
    return x / (shear_modulus * POLAR)


def two_mass_stiffness(x: float, mounting: str) -> float:
    """N/m at the table: coupling and torsion reflected through the lead (k/lead²), the axial chain, in series."""
    return 1 / (LEAD ** 2 / K_COUPLING + LEAD ** 2 * torsion_compliance(x) + axial_compliance(x, mounting))


# --------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("mounting", ["fixed-supported", "fixed-fixed"])
def test_two_mass_first_mode_is_the_closed_form_at_every_position(tmp_path, mounting):
    # The screw's and the coupling's inertia made negligible (density 1e-6 kg/m³: J_screw = 3e-13 kg·m²,
    # 1.3e-10 of the rotor's; coupling 0), so the two masses are the rotor (J_m/lead² at the table) and the
    # table whatever the 2-mass lumping does with the bodies between: f1 = √(k(x)·(1/m1 + 1/m2))/2π.
    # Error terms: the neglected inertia shifts f1 by < 1e-10 relative; the symmetric 2×2 eigenproblem
    # and the SVD of the modal analysis are good to a few eps; rtol 1e-8.
    result = first_modes(screw_model(tmp_path, mounting=mounting, detail="2-mass", density=1e-6,
                                     coupling_inertia=0.0), points=7)
    m1, m2 = J_MOTOR / LEAD ** 2, M_TABLE
    expected = [math.sqrt(two_mass_stiffness(x, mounting) * (1 / m1 + 1 / m2)) / (2 * math.pi)
                for x in np.linspace(0.0, L, 7)]
    assert result.frequencies_hz.shape == (7, 1)
    assert_allclose(result.position, np.linspace(0.0, L, 7), rtol=0, atol=1e-15)
    assert_allclose(result.frequencies_hz[:, 0], expected, rtol=1e-8)


@pytest.mark.parametrize("arrangement", ["end-driven", "omega"])
def test_belt_first_mode_is_the_span_formula(tmp_path, arrangement):
    # One spring, the belt's spans in parallel at the carriage, c/x + c/(2C − x) (end-driven) or
    # c/x + c/(C − x) (omega), between the motor with the drive pulley (J_m + J_p, through the radius) and
    # the carriage: end-driven with the idler J_i/r_i² and the whole belt's mass (2C + π(r + r_i))·m';
    # omega with the motor's mass riding on it. Exact formulas: rtol 1e-10 covers the eigen-solver's eps.
    result = first_modes(belt_model(tmp_path, arrangement))
    x = result.position[1:-1] if arrangement == "omega" else result.position[1:]
    if arrangement == "end-driven":
        k = C_SPEC / x + C_SPEC / (2 * C_BELT - x)
        m2 = M_CARRIAGE + J_PULLEY / R_PULLEY ** 2 + (2 * C_BELT + 2 * math.pi * R_PULLEY) * MPL
    else:
        k = C_SPEC / x + C_SPEC / (C_BELT - x)
        m2 = M_CARRIAGE + M_BELT_MOTOR
    m1 = (J_BELT_MOTOR + J_PULLEY) / R_PULLEY ** 2
    expected = np.sqrt(k * (1 / m1 + 1 / m2)) / (2 * np.pi)
    got = result.frequencies_hz[1:-1, 0] if arrangement == "omega" else result.frequencies_hz[1:, 0]
    assert_allclose(got, expected, rtol=1e-10)


# --------------------------------------------------------------------------- the shapes over the stroke
def test_fixed_supported_screw_is_softest_at_the_far_end(tmp_path):
    # every compliance between the motor and the table grows with x (torsion ∝ x, shaft x/(A·E)): f1 falls
    result = first_modes(screw_model(tmp_path))
    f1 = result.frequencies_hz[:, 0]
    assert np.all(np.diff(f1) < 0)
    assert result.worst_position == L
    assert result.lowest_first_mode_hz == f1[-1]


def test_fixed_fixed_screw_is_softest_near_mid_stroke(tmp_path):
    points = 21
    step = L / (points - 1)
    # The axial chain alone is symmetric about L/2 (its compliance is largest there); the torsion from the
    # motor-side end is the model's asymmetry and grows with x. Total compliance near mid-stroke, u = x − L/2:
    # C(u) = C0 − u²/(A²E²S) + c_t'·u (S = L/(AE) + 2/k_b, c_t' = lead²·32/(Gπd_r⁴)), largest at
    # u* = c_t'·A²E²·S/2: the softest position lies beyond mid-stroke by about u* (mass shares aside), never
    # on the motor side; plus one grid step of the map's resolution.
    s = L / (AREA * E) + 2 / K_BEARING
    u_star = LEAD ** 2 / (G * POLAR) * (AREA * E) ** 2 * s / 2
    result = first_modes(screw_model(tmp_path, mounting="fixed-fixed"), points)
    f1 = result.frequencies_hz[:, 0]
    assert L / 2 - 1e-12 <= result.worst_position <= L / 2 + u_star + step
    assert f1[0] > result.lowest_first_mode_hz and f1[-1] > result.lowest_first_mode_hz

    # without that asymmetry (torsion 1e16/7.9e10 stiffer) the map is symmetric about mid-stroke: f1 shifts by
    # at most half the torsion's share of the compliance at each of x and L − x (first-order perturbation),
    # so |f1(x) − f1(L − x)|/f1 ≤ max share = lead²·c_t(L)/(smallest total compliance)
    stiff = 1e16
    rigid = first_modes(screw_model(tmp_path, mounting="fixed-fixed", shear_modulus=stiff, name="stiff.toml"), points)
    f1 = rigid.frequencies_hz[:, 0]
    smallest = min(LEAD ** 2 / K_COUPLING + axial_compliance(x, "fixed-fixed") for x in rigid.position)
    share = LEAD ** 2 * torsion_compliance(L, stiff) / smallest
    assert np.max(np.abs(f1 - f1[::-1]) / f1) <= share
    assert rigid.worst_position == pytest.approx(L / 2, abs=1e-12)


def test_end_driven_belt_is_softest_at_the_idler(tmp_path):
    result = first_modes(belt_model(tmp_path, "end-driven"))
    f1 = result.frequencies_hz[:, 0]
    # x = 0: the span to the carriage has zero length, the belt is rigid there: no flexible mode (null)
    assert np.isnan(f1[0]) and result.to_dict()["frequencies_hz"][0] == [None]
    assert np.all(np.diff(f1[1:]) < 0)
    assert result.worst_position == C_BELT
    assert any("position 0 m" in note for note in result.notes)


def test_omega_belt_is_softest_at_mid_stroke(tmp_path):
    result = first_modes(belt_model(tmp_path, "omega"))
    f1 = result.frequencies_hz[:, 0]
    assert np.isnan(f1[0]) and np.isnan(f1[-1])         # both clamps: a span of zero length, rigid
    # k = cL/(x(L − x)) is symmetric about L/2; the positions are, to rounding: rtol 1e-10
    assert_allclose(f1[1:-1], f1[1:-1][::-1], rtol=1e-10)
    assert result.worst_position == pytest.approx(C_BELT / 2, abs=1e-12)


def test_two_mass_belt_with_a_rigid_end(tmp_path):
    # detail '2-mass' refuses a chain without compliance; at the drive end the one span has zero length:
    # the map reports that end without a mode instead of failing
    result = first_modes(belt_model(tmp_path, "end-driven", detail="2-mass"), points=5)
    assert np.isnan(result.frequencies_hz[0, 0]) and np.all(np.isfinite(result.frequencies_hz[1:, 0]))


def test_an_end_with_a_body_less_pads_with_null(tmp_path):
    # at x = 0 the screw's torsion is infinite (l = 0): the chain loses a body and its mode; the others are
    # the limit of the positions next to it (the mode that went to infinity is the highest)
    result = first_modes(screw_model(tmp_path), points=21)
    payload = result.to_dict()
    assert result.modes == 3
    assert payload["frequencies_hz"][0][2] is None and None not in payload["frequencies_hz"][1]
    assert any(note.startswith("position 0 m: 2 of 3 flexible modes") for note in result.notes)
    two = first_modes(screw_model(tmp_path), points=21, modes=2)      # two columns: nothing missing
    assert two.frequencies_hz.shape == (21, 2) and not two.notes
    assert_allclose(two.frequencies_hz, result.frequencies_hz[:, :2], rtol=0)
    near = first_modes(screw_model(tmp_path), points=2001).frequencies_hz[1, :2]     # x = 0.6 mm
    # continuity: 0.6 mm of 1.2 m moves f1, f2 by well under 1 %
    assert_allclose(result.frequencies_hz[0, :2], near, rtol=1e-2)


# --------------------------------------------------------------------------- bad input
def test_axes_without_a_position_to_vary(tmp_path):
    lumped = load_model(EXAMPLES / "ballscrew_3m2s.toml")
    with pytest.raises(ModelError) as info:
        sicomat.mode_map(lumped)
    assert info.value.path == "axes.X.mechanics.type" and info.value.value == "lumped"
    rigid = load_model(screw_model(tmp_path, detail="rigid"))
    with pytest.raises(ModelError) as info:
        sicomat.mode_map(rigid)
    assert info.value.path == "axes.X.mechanics.detail"
    rack = tmp_path / "rack.toml"
    rack.write_text('[axes.X.mechanics]\ntype = "components"\n'
                    '[[axes.X.mechanics.parts]]\nkind = "motor"\nrotor_inertia = 1e-3\n'
                    '[[axes.X.mechanics.parts]]\nkind = "rack-pinion"\npinion_radius = 0.03\n'
                    'pinion_inertia = 1e-4\nmesh_stiffness = 2e8\n'
                    '[[axes.X.mechanics.parts]]\nkind = "table"\nmass = 100\n')
    with pytest.raises(ModelError) as info:
        sicomat.mode_map(load_model(rack))
    assert info.value.path == "axes.X.mechanics.parts.1.kind" and info.value.value == "rack-pinion"
    with pytest.raises(ModelError) as info:
        sicomat.mode_map(load_model(screw_model(tmp_path)), points=1)
    assert info.value.path == "points"


def test_everything_merged_is_an_analysis_error(tmp_path):
    machine = sicomat.with_overrides(load_model(screw_model(tmp_path)), {"axes.X.mechanics.detail": "auto",
                                                                         "axes.X.mechanics.bandwidth": 0.01})
    with pytest.raises(AnalysisError, match="no flexible mode"):
        sicomat.mode_map(machine, points=3)


def run(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def test_cli_json_contract(tmp_path):
    result = run("modemap", screw_model(tmp_path), "--points", "5", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    contract = {"position", "frequencies_hz", "worst_position", "lowest_first_mode_hz"}
    assert set(payload) == contract | {"axis", "stroke", "modes", "notes"}
    assert payload["position"] == [0.0, 0.3, 0.6, 0.9, 1.2]
    assert len(payload["frequencies_hz"]) == 5 and all(len(row) == 3 for row in payload["frequencies_hz"])
    assert payload["worst_position"] == 1.2
    assert payload["lowest_first_mode_hz"] == payload["frequencies_hz"][-1][0]


def test_cli_table_and_plot(tmp_path):
    figure = tmp_path / "map.png"
    result = run("modemap", screw_model(tmp_path), "--points", "5", "--plot", figure)
    assert result.exit_code == 0, result.output
    assert "worst" in result.stdout and "1200" in result.stdout
    assert figure.stat().st_size > 10_000 and figure.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, needle", [
    (["--points", "1"], "--points"),
    (["--plot", "map.txt"], "--plot"),
])
def test_cli_bad_options_exit_2(tmp_path, args, needle):
    result = run("modemap", screw_model(tmp_path), *[str(tmp_path / a) if a.endswith(".txt") else a for a in args])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in result.output
    assert not (tmp_path / "map.txt").exists()


def test_cli_lumped_model_exit_2():
    result = run("modemap", EXAMPLES / "ballscrew_3m2s.toml")
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "axes.X.mechanics.type" in lines[0] and "'lumped'" in lines[0]
    assert "ballscrew_3m2s.toml" in lines[0]


# --------------------------------------------------------------------------- tune --all-positions
@pytest.fixture(scope="module")
def stroke_tuning(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tune")
    path = screw_model(folder)
    written = folder / "tuned.toml"
    result = run("tune", path, "--all-positions", "--points", "5", "--write", written, "--json")
    assert result.exit_code == 0, result.output
    return path, written, json.loads(result.stdout)


def test_tune_all_positions_payload(stroke_tuning):
    path, _, payload = stroke_tuning
    for key in ("velocity", "position", "achieved", "targets", "stable", "warnings"):   # the tune keys stay
        assert key in payload
    assert [p["position"] for p in payload["positions"]] == [0.0, 0.3, 0.6, 0.9, 1.2]
    # tuned where the first mode is lowest: the mode map's worst position (the far end of this screw)
    assert payload["tuned_position"] == first_modes(path, 5).worst_position == 1.2
    phase = [p["phase_margin_deg"] for p in payload["positions"]]
    assert payload["min_phase_margin_deg"] == min(phase)
    assert payload["worst_position"] == payload["positions"][int(np.argmin(phase))]["position"]
    assert payload["min_gain_margin_db"] == min(p["gain_margin_db"] for p in payload["positions"])


def test_tune_all_positions_margins_are_those_of_sicomat_margins(stroke_tuning):
    # The reported minimum, recomputed by `sicomat margins` with the tuned gains at that position. The same
    # grid and the same margin computation on the same loop; the gains go through JSON (repr floats
    # round-trip exactly) and Kp through Kp_normalized·m_rigid (a few ulp), which moves a margin by ~1e-14
    # relative: 1e-9 degree / dB is far inside the margins' own accuracy (the crossovers' cubic refinement).
    path, written, payload = stroke_tuning
    gains = [f"axes.X.controller.Kp_normalized={payload['velocity']['Kp_normalized']!r}",
             f"axes.X.controller.Ti={payload['velocity']['Ti']!r}", f"axes.X.controller.Kv={payload['position']['Kv']!r}"]
    for where, key in ((payload["worst_position"], "min_phase_margin_deg"),
                       (payload["min_gain_margin_position"], "min_gain_margin_db")):
        args = ["margins", path, "--json", "--set", f"axes.X.mechanics.position={where!r}"]
        for g in gains:
            args += ["--set", g]
        again = run(*args)
        assert again.exit_code == 0, again.output
        m = json.loads(again.stdout)
        if key == "min_phase_margin_deg":
            assert payload[key] == pytest.approx(m["velocity"]["phase_margin_deg"], abs=1e-9)
        else:
            assert payload[key] == pytest.approx(min(m["velocity"]["gain_margin_db"], m["position"]["gain_margin_db"]),
                                                 abs=1e-9)
    # --write keeps working: the file has the tuned gains (its own position kept), the same margins there
    from_file = run("margins", written, "--json", "--set", f"axes.X.mechanics.position={payload['worst_position']!r}")
    assert from_file.exit_code == 0, from_file.output
    assert json.loads(from_file.stdout)["velocity"]["phase_margin_deg"] == pytest.approx(
        payload["min_phase_margin_deg"], abs=1e-6)   # the written decimal gains (15 digits): ~1e-13 relative
    tuned = load_model(written).axes["X"].controller
    assert tuned.Kv == pytest.approx(payload["position"]["Kv"], rel=1e-14)
    assert tuned.Kp_normalized == pytest.approx(payload["velocity"]["Kp_normalized"], rel=1e-14)


def test_an_unmet_margin_somewhere_is_reported(tmp_path):
    path = screw_model(tmp_path)
    over = sicomat.tune_over_stroke(load_model(path), None, points=3)
    assert not over.unmet and over.stable is True
    low = replace(over.positions[1], velocity_phase_margin_deg=30.0, position_gain_margin_db=2.0, stable=False)
    worse = replace(over, positions=(over.positions[0], low, over.positions[2]))
    text = " | ".join(worse.unmet)
    assert "position 0.6 m" in text and "velocity phase margin 30.0°" in text and "gain margin 2.0 dB" in text
    assert "unstable" in text
    payload = worse.update_payload({"stable": True, "warnings": []})
    assert payload["stable"] is False and payload["targets_met_all_positions"] is False
    assert payload["worst_position"] == 0.6 and payload["min_phase_margin_deg"] == 30.0
    assert any("not met at position 0.6 m" in w for w in payload["warnings"])


@pytest.mark.parametrize("args, needle", [
    (["--points", "5"], "--all-positions"),
    (["--all-positions", "--method", "time"], "--method"),
    (["--all-positions", "--points", "1"], "--points"),
])
def test_tune_bad_options_exit_2(tmp_path, args, needle):
    result = run("tune", screw_model(tmp_path), *args)
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0]


def test_tune_all_positions_on_a_lumped_model_exit_2():
    result = run("tune", EXAMPLES / "ballscrew_3m2s.toml", "--all-positions")
    assert result.exit_code == 2 and "axes.X.mechanics.type" in result.output


def test_the_catalogue_examples_as_documented():
    # examples/ballscrew_catalog.toml (screw mounted fixed-supported by the file) is softest at the far end,
    # examples/belt_catalog.toml (end-driven) at the idler; the rack and pinion has no map (docs/components.md)
    assert first_modes(EXAMPLES / "ballscrew_catalog.toml").worst_position == 1.0
    assert first_modes(EXAMPLES / "belt_catalog.toml").worst_position == 2.0
    with pytest.raises(ModelError, match="rack and pinion"):
        first_modes(EXAMPLES / "rack_pinion.toml")
    # tuned at the far end, the ball-screw axis's margins hold everywhere: one attempt
    result = run("tune", EXAMPLES / "ballscrew_catalog.toml", "--all-positions", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["tuned_position"] == 1.0 and payload["targets_met_all_positions"] is True
    assert [a["tuned_position"] for a in payload["attempts"]] == [1.0]


SWAPPED = {"axes.X.mechanics.parts.0.id": "servo-motor-400v-11nm", "axes.X.mechanics.parts.2.id": "ball-screw-40x10-l1500",
           "axes.X.mechanics.parts.4.mass": "400 kg"}


def test_a_tuning_that_fails_elsewhere_is_tuned_again_where_it_fails():
    # The ball-screw example with an 11 N·m motor, a 40×10 screw 1.5 m (the swapped entry's fixed–fixed
    # mounting) and 400 kg (docs/components.md): softest at mid-stroke, but tuned there the loop is unstable
    # with the table near the motor end, where the coupling mode sits near the phase crossover. The second
    # attempt tunes where the margins fell shortest, and the choice is the attempt with the smaller worst
    # shortfall over the stroke.
    machine = sicomat.with_overrides(load_model(EXAMPLES / "ballscrew_catalog.toml"), SWAPPED)
    over = sicomat.tune_over_stroke(machine, None)
    first = over.attempts[0]
    assert first.tuned_position == sicomat.mode_map(machine).worst_position == 0.75
    assert first.stable is False and first.shortfall == math.inf
    assert over.attempts[1].tuned_position == first.shortest.position
    assert over.tuned_position != first.tuned_position and over.shortfall == min(a.shortfall for a in over.attempts)
    assert over.stable is True and over.shortfall < 0.1
    assert over.to_dict()["attempts"][0] == {"tuned_position": 0.75, "shortfall": None, "stable": False,
                                             "unmet": len(first.unmet), "chosen": False}
