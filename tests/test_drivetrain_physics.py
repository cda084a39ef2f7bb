"""The drive-train physics rules (issue 12, ``sicomat.catalogue``) against hand calculations.

Every expected number is worked out in the comment beside it from the formula in ``docs/components.md``
(not by calling the code): the literals are rounded to 10 significant digits, so ``REL = 1e-9`` covers the
rounding of the literal (5e-11) and the few float operations of the code (≲ 1e-15). Data: a 32×10
ball screw with root diameter 28 mm, E = 2.06e11 Pa, G = 7.9e10 Pa, ρ = 7850 kg/m³ (the THK values).
"""

from __future__ import annotations

import itertools
import math

import pytest

from sicomat.description import drivetrain as dt
from sicomat.description import motor_checks as mc
from sicomat.errors import ModelError

REL = 1e-9
D_ROOT = 0.028          # m
EA = 126_844_944.98     # E·π·d_r²/4 = 2.06e11 · π · 0.028² / 4 = 2.06e11 · 6.157521601e-4 N
K_NUT = 1.0e9           # N/m
K_BEARING = 1.5e9       # N/m
LEAD = 0.01 / (2 * math.pi)   # 10 mm/rev as m/rad


# --------------------------------------------------------------------------- shaft axial stiffness
@pytest.mark.parametrize("mounting", ["fixed-supported", "fixed-free"])
@pytest.mark.parametrize(("x", "expected"), [
    (0.25, 507_379_779.9),    # EA / 0.25
    (0.5, 253_689_889.96),    # EA / 0.5
    (1.0, 126_844_944.98),    # EA / 1.0 (nut at the far end: the softest)
])
def test_shaft_axial_stiffness_fixed_supported_and_free(mounting: str, x: float, expected: float) -> None:
    assert dt.shaft_axial_stiffness(D_ROOT, 1.0, x, mounting) == pytest.approx(expected, rel=REL)


@pytest.mark.parametrize(("x", "expected"), [
    (0.1, 1_409_388_277.6),   # EA·L/(a·b) = EA·1/(0.1·0.9)
    (0.25, 676_506_373.23),   # EA/(0.25·0.75)
    (0.5, 507_379_779.9),     # EA/(0.5·0.5) = 4·EA/L, the minimum
    (0.75, 676_506_373.23),   # symmetric to 0.25
])
def test_shaft_axial_stiffness_fixed_fixed(x: float, expected: float) -> None:
    assert dt.shaft_axial_stiffness(D_ROOT, 1.0, x, "fixed-fixed") == pytest.approx(expected, rel=REL)


def test_fixed_fixed_minimum_is_at_mid_stroke() -> None:
    # d/da [L/(a(L−a))] = 0 at a = L/2; on a grid of 101 points the smallest value sits at index 50.
    xs = [i / 100 for i in range(1, 100)]
    ks = [dt.screw_axial_stiffness(D_ROOT, 1.0, x, "fixed-fixed", nut_stiffness=K_NUT,
                                   bearing_stiffness=K_BEARING) for x in xs]
    assert xs[ks.index(min(ks))] == pytest.approx(0.5)


def test_shaft_is_rigid_at_the_fixed_bearing() -> None:
    assert math.isinf(dt.shaft_axial_stiffness(D_ROOT, 1.0, 0.0, "fixed-supported"))
    assert math.isinf(dt.shaft_axial_stiffness(D_ROOT, 1.0, 0.0, "fixed-fixed"))
    assert math.isinf(dt.shaft_axial_stiffness(D_ROOT, 1.0, 1.0, "fixed-fixed"))


# --------------------------------------------------------------------------- series with nut and bearings
def test_series_fixed_supported() -> None:
    # 1/k = 0.5/EA + 1/1e9 + 1/1.5e9 = 3.941817e-9 + 1e-9 + 0.6666667e-9 → 178 301 202.5 N/m
    k = dt.screw_axial_stiffness(D_ROOT, 1.0, 0.5, "fixed-supported", nut_stiffness=K_NUT,
                                 bearing_stiffness=K_BEARING)
    assert k == pytest.approx(178_301_202.54, rel=REL)


def test_series_limit_nut_at_the_fixed_end_is_nut_plus_bearing() -> None:
    # shaft infinitely stiff: 1/k = 1/1e9 + 1/1.5e9 → k = 6e8 exactly
    k = dt.screw_axial_stiffness(D_ROOT, 1.0, 0.0, "fixed-supported", nut_stiffness=K_NUT,
                                 bearing_stiffness=K_BEARING)
    assert k == pytest.approx(6.0e8, rel=1e-14)


@pytest.mark.parametrize(("x", "expected"), [
    # path_i = 1/(seg_i/EA + 1/k_b); k = 1/(1/k_nut + 1/(path_1 + path_2))
    (0.25, 346_885_660.24),   # paths 379 135 865.3 (a = 0.25) + 151 989 604.0 (b = 0.75)
    (0.5, 302_641_128.02),    # paths 216 990 949.8 each
    (0.0, 617_876_480.59),    # path 1 = k_b (segment of length 0), path 2 = 1/(1/EA + 1/k_b)
])
def test_series_fixed_fixed_two_bearings(x: float, expected: float) -> None:
    k = dt.screw_axial_stiffness(D_ROOT, 1.0, x, "fixed-fixed", nut_stiffness=K_NUT, bearing_stiffness=K_BEARING)
    assert k == pytest.approx(expected, rel=REL)


def test_fixed_fixed_with_rigid_bearings_reduces_to_the_textbook_form() -> None:
    # bearings 1e30 (rigid to 1e-21): 1/k = 1/k_nut + (0.25·0.75)/(EA·1) → 403 521 504.0 N/m
    # (1/1e9 + 1/676 506 373.23 = 1e-9 + 1.478182e-9 = 2.478182e-9)
    k = dt.screw_axial_stiffness(D_ROOT, 1.0, 0.25, "fixed-fixed", nut_stiffness=K_NUT, bearing_stiffness=1e30)
    assert k == pytest.approx(403_521_504.02, rel=REL)


def test_fixed_fixed_rigid_shaft_has_both_bearings_in_parallel() -> None:
    # E = 1e30 (shaft rigid to 1e-21): both fixed bearings carry the nut, 1/k = 1/k_nut + 1/(2·k_b)
    # = 1e-9 + 1/3e9 → k = 7.5e8 (THK's one-bearing form would give 1/(1e-9 + 1/1.5e9) = 6e8)
    k = dt.screw_axial_stiffness(D_ROOT, 1.0, 0.3, "fixed-fixed", nut_stiffness=K_NUT, bearing_stiffness=K_BEARING,
                                 youngs_modulus=1e30)
    assert k == pytest.approx(7.5e8, rel=1e-12)


# --------------------------------------------------------------------------- torsion, inertia
@pytest.mark.parametrize(("length", "expected"), [
    (0.25, 19_068.612894),    # G·π·d_r⁴/(32·l): 7.9e10 · 6.034371169e-8 / 0.25
    (0.5, 9_534.3064470),
    (1.0, 4_767.1532235),
])
def test_torsional_stiffness(length: float, expected: float) -> None:
    assert dt.screw_torsional_stiffness(D_ROOT, length) == pytest.approx(expected, rel=REL)


def test_torsion_reflected_through_the_lead() -> None:
    # k = k_t (2π/p)² = 9534.306447 · (2π/0.01)² = 9534.306447 · 394 784.176 = 3 763 993 314.8 N/m
    k = dt.torsional_to_translational(9_534.306447, LEAD)
    assert k == pytest.approx(3_763_993_314.8, rel=REL)
    assert dt.translational_to_torsional(k, LEAD) == pytest.approx(9_534.306447, rel=1e-14)


def test_torsion_is_rigid_at_the_motor_end() -> None:
    assert math.isinf(dt.screw_torsional_stiffness(D_ROOT, 0.0))


def test_screw_inertia_nominal_diameter() -> None:
    # π·ρ·L·d⁴/32 = π · 7850 · 1.2 · 0.032⁴ / 32 = 9.697297300e-4 kg·m²
    assert dt.screw_inertia(0.032, 1.2) == pytest.approx(9.697297300e-4, rel=REL)


def test_table_inertia_reflected_through_the_lead() -> None:
    # m (p/2π)² = 300 · (0.01/2π)² = 300 · 2.533029591e-6 = 7.599088773e-4 kg·m²
    assert dt.reflected_inertia(300.0, LEAD) == pytest.approx(7.599088773e-4, rel=REL)


# --------------------------------------------------------------------------- speed limits
@pytest.mark.parametrize(("mounting", "omega"), [
    # (λ/l)²·(d_r/4)·√(E/ρ), l = 1.5 m: √(2.06e11/7850) = 5122.7 m/s
    ("fixed-free", 56.035489664),       # λ = 1.8751
    ("fixed-supported", 245.72402935),  # λ = 3.9266
    ("fixed-fixed", 356.56325459),      # λ = 4.7300
])
def test_critical_speed_hand_value(mounting: str, omega: float) -> None:
    assert dt.critical_speed(D_ROOT, 1.5, mounting) == pytest.approx(omega, rel=REL)


@pytest.mark.parametrize(("mounting", "fc"), [("fixed-free", 3.4), ("fixed-supported", 15.1), ("fixed-fixed", 21.9)])
def test_critical_speed_against_a_vendor_chart_formula(mounting: str, fc: float) -> None:
    # An independent oracle: n = fc·d_r/l²·1e7 min⁻¹ (d_r, l in mm), factors including the 0.8 safety
    # (engineersedge.com, "Critical Speed Ball Screw and Lead Screws Formulas"): 28 mm, 1500 mm.
    # fc is printed to 2–3 digits (3.4 is ±1.5 %), so 2 % is the tolerance.
    n_vendor = fc * 28.0 / 1500.0**2 * 1e7
    n_ours = 0.8 * dt.critical_speed(D_ROOT, 1.5, mounting) * 60 / (2 * math.pi)
    assert n_ours == pytest.approx(n_vendor, rel=0.02)


def test_dn_limit() -> None:
    # 70 000 / 32 mm = 2187.5 min⁻¹ = 2187.5 · 2π/60 = 229.0744643 rad/s
    assert dt.dn_speed_limit(0.032, 70_000.0) == pytest.approx(229.0744643, rel=REL)


# --------------------------------------------------------------------------- belts
C_SPEC = 2.5e5   # N


@pytest.mark.parametrize(("x", "expected"), [
    (0.2, 1_388_888.8889),    # c (1/0.2 + 1/1.8)
    (0.5, 666_666.66667),     # c (1/0.5 + 1/1.5)
    (1.0, 500_000.0),         # c (1/1 + 1/1) = 2c/C at the idler
])
def test_linear_belt_axis(x: float, expected: float) -> None:
    spans = dt.linear_belt_spans(x, 1.0)
    assert dt.belt_axis_stiffness(C_SPEC, spans) == pytest.approx(expected, rel=REL)


def test_linear_belt_softest_at_the_idler() -> None:
    xs = [i / 100 for i in range(1, 101)]
    ks = [dt.belt_axis_stiffness(C_SPEC, dt.linear_belt_spans(x, 1.0)) for x in xs]
    assert xs[ks.index(min(ks))] == 1.0
    assert all(a > b for a, b in itertools.pairwise(ks))   # monotonic towards the idler


@pytest.mark.parametrize(("x", "expected"), [(0.25, 1_333_333.3333), (0.5, 1_000_000.0)])
def test_omega_belt_axis(x: float, expected: float) -> None:
    # c·L/(x(L − x)): 2.5e5/(0.25·0.75) and 4c/L
    assert dt.belt_axis_stiffness(C_SPEC, dt.omega_belt_spans(x, 1.0)) == pytest.approx(expected, rel=REL)


def test_omega_belt_softest_at_mid_stroke() -> None:
    xs = [i / 100 for i in range(1, 100)]
    ks = [dt.belt_axis_stiffness(C_SPEC, dt.omega_belt_spans(x, 1.0)) for x in xs]
    assert xs[ks.index(min(ks))] == pytest.approx(0.5)


def test_pulley_and_rotating_mass() -> None:
    # π·2700·0.03·(0.04⁴ − 0.01⁴)/2 = 3.244479813e-4 kg·m²
    assert dt.pulley_inertia(0.04, 0.03, density=2700.0, bore_radius=0.01) == pytest.approx(3.244479813e-4, rel=REL)
    # 2e-4/0.02² + 1e-4/0.015² + 0.5 = 0.5 + 0.4444444444 + 0.5
    assert dt.rotating_equivalent_mass([2e-4, 1e-4], [0.02, 0.015], belt_mass=0.5) == pytest.approx(
        1.4444444444, rel=REL)


# --------------------------------------------------------------------------- gearbox, rack and pinion
def test_gearbox_referred_to_the_input() -> None:
    assert dt.gearbox_stiffness_at_input(1.0e4, 5.0) == pytest.approx(400.0, rel=1e-15)   # 1e4/25
    assert dt.inertia_at_input(1.0e-3, 5.0) == pytest.approx(4.0e-5, rel=1e-15)           # 1e-3/25


def test_rack_and_pinion() -> None:
    assert dt.pinion_pitch_radius(0.003, 20) == pytest.approx(0.03, rel=1e-15)            # 3 mm · 20 / 2
    # helical 30°: 0.06/(2 cos 30°) = 0.06/√3 = 0.03464101615
    assert dt.pinion_pitch_radius(0.003, 20, helix_angle=math.pi / 6) == pytest.approx(0.03464101615, rel=REL)
    assert dt.reflected_inertia(200.0, 0.03) == pytest.approx(0.18, rel=1e-14)             # 200 · 0.03²


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("call", [
    lambda: dt.shaft_axial_stiffness(D_ROOT, 1.0, 1.2, "fixed-supported"),   # nut beyond the length
    lambda: dt.shaft_axial_stiffness(D_ROOT, 1.0, -0.1, "fixed-fixed"),
    lambda: dt.shaft_axial_stiffness(D_ROOT, 1.0, 0.5, "clamped"),           # unknown mounting
    lambda: dt.shaft_axial_stiffness(-0.02, 1.0, 0.5, "fixed-free"),
    lambda: dt.critical_speed(D_ROOT, 1.0, "floating"),
    lambda: dt.linear_belt_spans(1.5, 1.0),
    lambda: dt.series_stiffness(1e6, 0.0),
    lambda: dt.gearbox_stiffness_at_input(1e4, 0.0),
])
def test_bad_input_is_a_model_error(call) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ModelError):
        call()


# --------------------------------------------------------------------------- motor conventions
def test_unit_conversions_of_the_motor_conventions() -> None:
    assert mc.torque_constant_rms(1.0, "peak") == pytest.approx(1.414213562, rel=REL)   # √2
    assert mc.torque_constant_rms(1.0, "rms") == 1.0
    assert mc.back_emf_line_rms(1.0, "phase-peak") == pytest.approx(1.224744871, rel=REL)  # √3/√2
    assert mc.back_emf_line_rms(1.0, "phase-rms") == pytest.approx(1.732050808, rel=REL)   # √3
    assert mc.back_emf_line_rms(1.0, "line-to-line-peak") == pytest.approx(0.7071067812, rel=REL)  # 1/√2
    assert mc.phase_resistance(2.0, "line-to-line") == 1.0
    # 100 V/1000 min⁻¹ = 100·60/(2π·1000) = 0.9549296586 V·s/rad
    assert mc.per_krpm_to_per_rad_s(100.0) == pytest.approx(0.9549296586, rel=REL)
    assert mc.expected_torque_constant(0.9549296586) == pytest.approx(1.653986686, rel=REL)   # √3 ×
    # 3·R·J/kT² = 3 · 1 Ω · 1e-3 kg·m² / 1.65² = 1.101928375e-3 s
    assert mc.mechanical_time_constant(1.0, 1.0e-3, 1.65) == pytest.approx(1.101928375e-3, rel=REL)
    with pytest.raises(ModelError):
        mc.torque_constant_rms(1.0, "average")


def test_consistent_synthetic_datasheet_has_no_warning_and_a_convention_slip_has_one() -> None:
    # A datasheet stating kE = 100 V/krpm line rms, kT = 1.1695 N·m/A per A PEAK (= 1.6539 rms).
    ke = mc.per_krpm_to_per_rad_s(100.0)
    kt = mc.torque_constant_rms(1.1695, "peak")
    assert mc.datasheet_warnings(torque_constant=kt, back_emf_constant=ke) == []
    slip = mc.datasheet_warnings(torque_constant=1.1695, back_emf_constant=ke)   # peak read as rms
    assert [w.name for w in slip] == ["kT_kE"]
    assert slip[0].ratio == pytest.approx(1.1695 / 1.653986686, rel=1e-9)       # 0.7071: the √2
    assert slip[0].tolerance == mc.DATASHEET_TOLERANCE


def test_published_table_motor() -> None:
    # A brushless servo motor's data as published (encyclopedia2.thefreedictionary.com, "torque constant",
    # its Table: 310 V DC, 4600 rpm, 2.2 N·m, stall current 4.52 A, Ke 51 V/krpm, Kt 0.49 N·m/A,
    # ph/ph resistance 3.07 Ω, J = 1.8 kg·cm²; the table does not say rms or peak).
    ke = mc.per_krpm_to_per_rad_s(51.0)          # 0.4870141259 V·s/rad
    r_ph = mc.phase_resistance(3.07, "line-to-line")     # 1.535 Ω
    warnings = mc.datasheet_warnings(torque_constant=0.49, back_emf_constant=ke, stall_current=4.52,
                                     stall_torque=2.2, phase_resistance=r_ph, rotor_inertia=1.8e-4)
    # I0·kT = 4.52·0.49 = 2.2148 against M0 = 2.2: ratio 0.9933, inside ±10 % → no "M0" warning.
    # √3·kE = 0.8435 against kT = 0.49: ratio 0.5809, outside: this table's kE is not line-to-line rms
    # (kT ≈ kE in SI, ratio 1.006, is the block-commutated BLDC convention), and the check says so.
    assert [w.name for w in warnings] == ["kT_kE"]
    assert warnings[0].ratio == pytest.approx(0.5808899925, rel=1e-9)


def test_mechanical_time_constant_and_stall_checks_fire() -> None:
    # T_mech stated 2 ms against 3·1·1e-3/1.65² = 1.102 ms: ratio 1.815; M0 12 against 5·1.65 = 8.25: 1.4545
    warnings = mc.datasheet_warnings(torque_constant=1.65, phase_resistance=1.0, rotor_inertia=1e-3,
                                     mechanical_time_constant=2e-3, stall_current=5.0, stall_torque=12.0)
    assert {w.name: w.ratio for w in warnings} == pytest.approx({"T_mech": 1.815, "M0": 1.454545455}, rel=1e-9)
    with pytest.raises(ModelError):
        mc.datasheet_warnings(torque_constant=1.65, back_emf_constant=0.0)
