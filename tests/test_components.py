"""The drive-chain builder (issue 12, §3, §6): a ``components`` axis against hand calculations, catalogue ids and
overrides, the drive from the motor, ``check --lumped`` / ``--write-lumped`` / ``--write``, Save Model, bad input.

Every expected number is computed here from the formula written beside it (docs/components.md), never copied
from the code's output. Unless said otherwise the comparisons use ``rel = 1e-13``: each side is a dozen or so
floating-point operations on the same inputs in a different order, each rounding by at most 1.1e-16, so the two
agree to ~2e-15; 1e-13 leaves a factor 50.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from sicomat.catalogue.store import ENV, load_catalogue
from sicomat.cli.main import app
from sicomat.description.components import ComponentsSpec, motor_constants
from sicomat.description.motor_checks import datasheet_warnings
from sicomat.errors import ModelError
from sicomat.io.modelfile import load_model, machine_from_dict
from sicomat.mechanics.lumped import build_mechanics

runner = CliRunner()
REL = 1e-13

# a ball-screw axis, SI: motor, bellows coupling, 32 x 10 screw, table (steel defaults of the screw)
JM, JC, KC = 1.6e-3, 2.0e-4, 7.6e4                 # kg*m^2, kg*m^2, N*m/rad
P, D, DR, L = 0.010, 0.032, 0.027, 1.0             # lead per rev, nominal and root diameter, length (m)
KN, KB = 5.0e8, 6.0e8                              # nut, one support bearing (N/m)
M = 400.0                                          # kg
RHO, E, G = 7850.0, 2.06e11, 7.9e10
LEAD = P / (2 * math.pi)                           # m/rad
A = math.pi * DR ** 2 / 4
JS = math.pi * RHO * L * D ** 4 / 32               # screw inertia, nominal diameter, whole length


@pytest.fixture(autouse=True)
def _no_user_catalogue(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)


def screw_parts(mounting: str = "fixed-supported") -> list[dict]:
    return [{"kind": "motor", "rotor_inertia": JM},
            {"kind": "coupling", "inertia": JC, "torsional_stiffness": KC},
            {"kind": "ball-screw", "lead": P, "diameter": D, "root_diameter": DR, "length": L, "mounting": mounting,
             "nut_stiffness": KN, "bearing_stiffness": KB},
            {"kind": "table", "mass": M}]


def components(parts: list[dict], position: float | None = None, detail: str = "full", **extra) -> ComponentsSpec:
    data = {"type": "components", "parts": parts, "detail": detail, **extra}
    if position is not None:
        data["position"] = position
    return ComponentsSpec.model_validate(data)


def by_name(items):
    return {item.name: item for item in items}


def series(*ks: float) -> float:
    return 1.0 / sum(1.0 / k for k in ks)


def axial_by_hand(mounting: str, x: float, kb: float = KB) -> float:
    if mounting == "fixed-supported":        # shaft A·E/x, nut and bearing in series
        return series(A * E / x, KN, kb)
    a, b = x, L - x                          # fixed-fixed: two paths (segment + its bearing) in parallel, nut in series
    return series(KN, series(A * E / a, kb) + series(A * E / b, kb))


# --------------------------------------------------------------------------- ball screw against the hand
@pytest.mark.parametrize("mounting", ["fixed-supported", "fixed-fixed"])
@pytest.mark.parametrize("x", [0.1, 0.5, 0.85])
def test_screw_springs_and_inertias_by_hand(mounting, x):
    chain = components(screw_parts(mounting), position=x).chain
    springs, bodies = by_name(chain.springs), by_name(chain.bodies)
    assert list(springs) == ["coupling", "screw_torsion", "screw_axial"]
    assert springs["screw_axial"].stiffness == pytest.approx(axial_by_hand(mounting, x), rel=REL)
    assert springs["screw_axial"].ratio == pytest.approx(LEAD, rel=REL)          # through the lead p/2π
    assert springs["screw_torsion"].stiffness == pytest.approx(G * math.pi * DR ** 4 / (32 * x), rel=REL)
    assert springs["coupling"].stiffness == KC
    # the coupling's inertia half on each side; the screw's J = π·ρ·L·d⁴/32: half the segment motor end → nut
    # on the motor side of the torsion spring (J·(x/L)/2), the rest at the nut
    near = JS * (x / L) / 2
    assert bodies["motor"].value == pytest.approx(JM + JC / 2, rel=REL)
    assert bodies["screw"].value == pytest.approx(JC / 2 + near, rel=REL)
    assert bodies["screw_nut"].value == pytest.approx(JS - near, rel=REL)
    assert bodies["table"].value == M and bodies["table"].kind == "translational"


def test_fixed_fixed_with_rigid_bearings_is_AEL_over_ab_and_the_nut():
    # kb → ∞ (1e30): each path's bearing compliance 1e-30 against a/(A·E) ~ 1e-9: relative change 1e-21 ≪ REL
    for x in (0.2, 0.5):
        parts = screw_parts("fixed-fixed")
        parts[2]["bearing_stiffness"] = 1e30
        k = by_name(components(parts, position=x).chain.springs)["screw_axial"].stiffness
        assert k == pytest.approx(series(A * E * L / (x * (L - x)), KN), rel=REL)


def test_rigid_detail_is_one_body_with_the_referred_inertias():
    x = 0.4
    spec = components(screw_parts(), position=x, detail="rigid")
    (body,) = spec.chain.bodies
    assert spec.chain.springs == []
    # one translating body: m + Σ J / lead² (J_eq = m·(p/2π)² seen from the motor)
    assert body.kind == "translational"
    assert body.value == pytest.approx(M + (JM + JC + JS) / LEAD ** 2, rel=REL)
    assert spec.chain.actuator["ratio"] == pytest.approx(1 / LEAD, rel=REL)
    # the rigid inertia the motor sees per unit table acceleration: T = (ΣJ + m·lead²)·θ̈, ẍ = lead·θ̈
    expected = (JM + JC + JS + M * LEAD ** 2) / LEAD
    for detail in ("rigid", "full"):
        mech = build_mechanics(components(screw_parts(), position=x, detail=detail).to_lumped())
        tool = np.array([1.0 if d.name == "table" else 0.0 for d in mech.dofs])
        _, m_rigid = mech.rigid_motion(np.asarray(mech.actuators[0].vector), tool)
        # a linear solve on M (condition ~ M·lead²/J ≈ 1e-3..1e3 in these units): 1e-11
        assert m_rigid == pytest.approx(expected, rel=1e-11), detail



def gearbox_parts(i: float = 5.0, jg: float = 2e-4, kg: float = 3e4) -> list[dict]:
    return [screw_parts()[0], screw_parts()[1], {"kind": "gearbox", "ratio": i, "input_inertia": jg,
                                                 "torsional_stiffness": kg}, *screw_parts()[2:]]


def test_motor_coupling_gearbox_screw_chain_by_hand():
    # every spring joins the bodies before and after it (a coupling then a gearbox used to leave the gearbox
    # spring's first body unnamed: a chain of motor, coupling, gearbox and screw did not load)
    i, jg, kg, x = 5.0, 2e-4, 3e4, 0.5
    chain = components(gearbox_parts(i, jg, kg), position=x).chain
    names = [b.name for b in chain.bodies]
    assert all(names) and len(set(names)) == len(names)
    for k, spring in enumerate(chain.springs):
        assert spring.between == (names[k], names[k + 1]), spring.name
    springs = by_name(chain.springs)
    assert list(springs) == ["coupling", "gearbox", "screw_torsion", "screw_axial"]
    # the gearbox's stiffness stays at its output, its stretch θ_in/i − θ_out
    assert springs["gearbox"].ratio == pytest.approx(1 / i, rel=REL) and springs["gearbox"].stiffness == kg
    near = JS * (x / L) / 2
    values = [b.value for b in chain.bodies]
    assert values == pytest.approx([JM + JC / 2, JC / 2 + jg, near, JS - near, M], rel=REL)
    # rigid: the motor-side inertias seen at the table through (lead/i)², the screw's through lead²
    (body,) = components(gearbox_parts(i, jg, kg), position=x, detail="rigid").chain.bodies
    assert body.value == pytest.approx(M + (JM + JC + jg) * i ** 2 / LEAD ** 2 + JS / LEAD ** 2, rel=REL)


def test_a_motor_shaft_spring_comes_first():
    parts = screw_parts()
    parts[0]["shaft_torsional_stiffness"] = 2e4
    chain = components(parts, position=0.5).chain
    assert [s.name for s in chain.springs] == ["motor_shaft", "coupling", "screw_torsion", "screw_axial"]
    shaft, coupling = chain.springs[:2]
    assert shaft.stiffness == 2e4 and shaft.between[0] == "motor" and coupling.between[0] == shaft.between[1]
    assert [b.value for b in chain.bodies[:2]] == pytest.approx([JM, JC / 2], rel=REL)

# --------------------------------------------------------------------------- belts
RB, JP, CSPEC, MU = 0.0382, 2.528e-4, 5.5e5, 0.16     # pulley radius, pulley inertia, c_spec (N), kg/m


def belt_parts(arrangement: str, length: float, motor_mass: float | None = None) -> list[dict]:
    motor = {"kind": "motor", "rotor_inertia": JM, **({"mass": motor_mass} if motor_mass else {})}
    return [motor, {"kind": "belt", "drive_pulley_radius": RB, "drive_pulley_inertia": JP, "idler_pulley_radius": RB,
                    "idler_pulley_inertia": JP, "specific_stiffness": CSPEC, "mass_per_length": MU,
                    "arrangement": arrangement, "length": length},
            {"kind": "table", "mass": 50.0}]


@pytest.mark.parametrize("x", [0.2, 1.0, 1.8])
def test_end_driven_belt_against_the_span_formula(x):
    C = 2.0
    chain = components(belt_parts("end-driven", C), position=x).chain
    (spring,) = chain.springs
    assert spring.stiffness == pytest.approx(CSPEC * (1 / x + 1 / (2 * C - x)), rel=REL)   # spans x, 2C − x
    assert spring.ratio == RB
    motor, table = chain.bodies
    assert motor.value == pytest.approx(JM + JP, rel=REL)
    # the carriage, the idler J/r² and the closed belt 2C + π(r + r_i) move with the table
    assert table.value == pytest.approx(50.0 + JP / RB ** 2 + MU * (2 * C + 2 * math.pi * RB), rel=REL)


@pytest.mark.parametrize("x", [0.3, 0.75, 1.2])
def test_omega_belt_against_the_span_formula(x):
    length = 1.5
    chain = components(belt_parts("omega", length, motor_mass=3.0), position=x).chain
    (spring,) = chain.springs
    assert spring.stiffness == pytest.approx(CSPEC * length / (x * (length - x)), rel=REL)
    assert chain.bodies[-1].value == pytest.approx(50.0 + 3.0, rel=REL)   # the motor rides on the carriage


# --------------------------------------------------------------------------- the same model written by hand
def test_chain_equals_the_hand_written_lumped_model(tmp_path):
    x, zeta = 0.4, 0.05
    kc, kt, ka = KC, G * math.pi * DR ** 4 / (32 * x), axial_by_hand("fixed-supported", x)
    near = JS * (x / L) / 2
    j = [JM + JC / 2, JC / 2 + near, JS - near]          # rotational bodies
    referred = [*j, M * LEAD ** 2]                       # motor coordinate
    total = sum(referred)

    # damping (docs/drive-chains.md): c = 2ζ·k/ω, ω the mode with the largest share of the spring's strain
    # energy, found here by scipy's generalized eigensolver on the hand-built M and K (stretch vectors g)
    import scipy.linalg

    g = np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, 0.0], [0.0, 0.0, LEAD, -1.0]])
    k_hand = np.array([kc, kt, ka])
    w2, shapes = scipy.linalg.eigh(g.T @ np.diag(k_hand) @ g, np.diag([*j, M]))
    flexible = w2 > 1e-6 * w2.max()
    strain = k_hand[:, None] * (g @ shapes[:, flexible]) ** 2              # spring × flexible mode
    omega = np.sqrt(w2[flexible])[np.argmax(strain / strain.sum(axis=0), axis=1)]
    dc, dt_, da = (float(c) for c in 2 * zeta * k_hand / omega)
    hand = f"""
[axes.X.mechanics]
type = "lumped"
bodies.motor = {{inertia = {j[0]!r}}}
bodies.screw = {{inertia = {j[1]!r}}}
bodies.screw_nut = {{inertia = {j[2]!r}}}
bodies.table = {{mass = {M!r}}}
couplings.coupling = {{between = ["motor", "screw"], stiffness = {kc!r}, damping = {dc!r}}}
couplings.screw_torsion = {{between = ["screw", "screw_nut"], stiffness = {kt!r}, damping = {dt_!r}}}
couplings.screw_axial = {{between = ["screw_nut", "table"], ratios = [{LEAD!r}, 1], stiffness = {ka!r}, damping = {da!r}}}
actuators.motor = {{body = "motor"}}
sensors.encoder = {{body = "motor"}}
"""
    (tmp_path / "hand.toml").write_text(hand)
    built = build_mechanics(components(screw_parts(), position=x, damping_ratio=zeta).to_lumped())
    written = build_mechanics(load_model(tmp_path / "hand.toml").axes["X"].mechanics)
    assert built.dof_names == written.dof_names == ("motor", "screw", "screw_nut", "table")
    for name in ("mass", "stiffness", "damping"):
        # entries are sums and products of inputs that agree to REL: 1e-12 relative to the largest entry
        a, b = getattr(built, name), getattr(written, name)
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max(), err_msg=name)
    # modes: inputs agreeing to 1e-12, a backward-stable SVD; frequencies 1e2..3e3 Hz, each to
    # ~eps·(f_max/f)² relative ≈ 1e-13 from the decomposition: 1e-10 is ample
    fa, fb = built.modes().undamped_hz, written.modes().undamped_hz
    np.testing.assert_allclose(fa[1:], fb[1:], rtol=1e-10)


# --------------------------------------------------------------------------- detail 2-mass and auto
def test_two_mass_is_the_series_of_every_compliance_and_keeps_the_inertia():
    x = 0.6
    spec = components(screw_parts(), position=x, detail="2-mass")
    (spring,) = spec.chain.springs
    motor, table = spec.chain.bodies
    kt, ka = G * math.pi * DR ** 4 / (32 * x), axial_by_hand("fixed-supported", x)
    # the spring in the table's coordinate (N/m): 1/k = lead²/k_c + lead²/k_t + 1/k_axial (docs/components.md)
    cc, ct, ca = LEAD ** 2 / KC, LEAD ** 2 / kt, 1 / ka
    assert spring.stiffness == pytest.approx(1 / (cc + ct + ca), rel=REL)
    assert spring.ratio == pytest.approx(LEAD, rel=REL)
    # the bodies between go to each end in the static deflection shape: the share c/total at the load
    near = JS * (x / L) / 2
    s1, s2 = cc / (cc + ct + ca), (cc + ct) / (cc + ct + ca)
    j_motor = JM + JC / 2 + (1 - s1) * (JC / 2 + near) + (1 - s2) * (JS - near)
    m_table = M + (s1 * (JC / 2 + near) + s2 * (JS - near)) / LEAD ** 2
    assert motor.value == pytest.approx(j_motor, rel=REL)
    assert table.value == pytest.approx(m_table, rel=REL)
    # energy: the two ends together carry the whole referred inertia
    assert motor.value + table.value * LEAD ** 2 == pytest.approx(JM + JC + JS + M * LEAD ** 2, rel=REL)


def own_frequencies_by_hand(x: float) -> dict[str, float]:
    """Each spring's own frequency, the chain split at it and each side rigid (motor coordinate)."""
    near = JS * (x / L) / 2
    referred = [JM + JC / 2, JC / 2 + near, JS - near, M * LEAD ** 2]
    k_ref = {"coupling": KC, "screw_torsion": G * math.pi * DR ** 4 / (32 * x),
             "screw_axial": axial_by_hand("fixed-supported", x) * LEAD ** 2}
    out = {}
    for k, name in enumerate(k_ref):
        ja, jb = sum(referred[:k + 1]), sum(referred[k + 1:])
        out[name] = math.sqrt(k_ref[name] * (1 / ja + 1 / jb)) / (2 * math.pi)
    return out


@pytest.mark.parametrize("bandwidth", [100.0, 30.0])
def test_auto_drops_the_springs_above_the_multiple_of_the_bandwidth(bandwidth):
    x = 0.5
    hand = own_frequencies_by_hand(x)
    full = by_name(components(screw_parts(), position=x).chain.springs)
    for name, f in hand.items():
        assert full[name].frequency_hz == pytest.approx(f, rel=1e-12), name   # a sqrt on top: 1e-12
    limit = 10.0 * bandwidth
    kept = {name for name, f in hand.items() if f < limit}
    assert kept and kept != set(hand)              # the bandwidths are chosen so that some go, some stay
    spec = components(screw_parts(), position=x, detail="auto", bandwidth=bandwidth, bandwidth_multiple=10.0)
    assert {s.name for s in spec.chain.springs} == kept
    for name in set(hand) - kept:
        assert any(note.startswith(f"{name} made rigid") for note in spec.chain.notes), spec.chain.notes


# --------------------------------------------------------------------------- the drive from the motor
def test_drive_takes_the_motor_constants_and_a_file_key_wins():
    kt_peak, r_ll, l_ll, i_peak, u_dc = 1.2, 1.1, 12e-3, 30.0, 560.0
    ke_ll = kt_peak * math.sqrt(2) / math.sqrt(3)          # consistent: kT_rms = √3·kE_ll,rms
    motor = {"kind": "motor", "rotor_inertia": JM, "torque_constant": kt_peak, "torque_constant_basis": "peak",
             "back_emf_constant": ke_ll, "back_emf_basis": "line-to-line-rms", "resistance": r_ll,
             "resistance_basis": "line-to-line", "inductance": l_ll, "inductance_basis": "line-to-line",
             "peak_current": i_peak, "dc_bus": u_dc, "pole_pairs": 4}
    mech = {"type": "components", "parts": [motor, *screw_parts()[1:]]}
    drive = machine_from_dict({"axes": {"X": {"mechanics": mech, "drive": {"bandwidth": 1500}}}}).axes["X"].drive
    assert drive.force_constant == pytest.approx(kt_peak * math.sqrt(2), rel=REL)      # kT per A rms
    assert drive.back_emf_constant == pytest.approx(ke_ll / math.sqrt(3), rel=REL)     # per phase, rms
    assert drive.force_constant == pytest.approx(3 * drive.back_emf_constant, rel=REL)  # T·ω = 3·E·I
    assert drive.resistance == pytest.approx(r_ll / 2, rel=REL) and drive.inductance == pytest.approx(l_ll / 2, rel=REL)
    assert drive.peak_current == pytest.approx(i_peak / math.sqrt(2), rel=REL)         # A rms
    assert drive.supply_voltage == pytest.approx(u_dc / math.sqrt(6), rel=REL)         # U_dc/√2 line, /√3 phase
    assert drive.pole_pairs == 4
    mine = machine_from_dict({"axes": {"X": {"mechanics": mech, "drive": {"bandwidth": 1500, "force_constant": 2.0,
                                                                          "supply_voltage": "300 V"}}}})
    assert mine.axes["X"].drive.force_constant == 2.0 and mine.axes["X"].drive.supply_voltage == 300.0
    assert mine.axes["X"].drive.resistance == pytest.approx(r_ll / 2, rel=REL)


# --------------------------------------------------------------------------- catalogue ids and overrides
CAT_MODEL = """# a ball-screw axis from catalogue parts
[axes.X.mechanics]
type = "components"
position = "0.3 m"
detail = "full"

[[axes.X.mechanics.parts]]
kind = "motor"
id = "servo-motor-400v-11nm"

[[axes.X.mechanics.parts]]
kind = "coupling"
id = "bellows-coupling-60nm"

[[axes.X.mechanics.parts]]
kind = "ball-screw"
id = "ball-screw-32x10-l1000"
mounting = "fixed-supported"   # the installation's

[[axes.X.mechanics.parts]]
kind = "guide"
id = "profile-rail-ball-35"

[[axes.X.mechanics.parts]]
kind = "table"
id = "table-400kg"

[[axes.X.mechanics.parts]]
kind = "encoder"
id = "encoder-absolute-20bit"

[axes.X.drive]
type = "first-order"
bandwidth = "1500 Hz"   # the current loop

[axes.X.controller]
type = "P-PI"
position_sensor = "encoder"
velocity_sensor = "encoder"
Kv = "30 1/s"
Kp_normalized = "100 1/s"
Ti = "8 ms"
"""


@pytest.fixture
def cat_model(tmp_path) -> Path:
    path = tmp_path / "axis.toml"
    path.write_text(CAT_MODEL)
    return path


def entry(id: str):
    return load_catalogue().get(id).parameters


def test_the_files_values_win_over_the_entry(cat_model):
    text = CAT_MODEL.replace('id = "table-400kg"', 'id = "table-400kg"\nmass = "420 kg"')
    text = text.replace('mounting = "fixed-supported"', 'mounting = "fixed-supported"\nlead = "20 mm"')
    cat_model.write_text(text)
    spec = load_model(cat_model).axes["X"].mechanics
    screw, shipped = spec.part("ball-screw"), entry("ball-screw-32x10-l1000")
    assert screw.lead == 0.020 and shipped.lead == 0.010
    assert screw.mounting == "fixed-supported" != shipped.mounting
    assert (screw.root_diameter, screw.nut_stiffness) == (shipped.root_diameter, shipped.nut_stiffness)
    assert spec.part("table").mass == 420.0
    assert by_name(spec.chain.springs)["screw_axial"].ratio == pytest.approx(0.020 / (2 * math.pi), rel=REL)


def test_set_overrides_a_part_value_and_swaps_an_entry(cat_model):
    lead = load_model(cat_model, ["axes.X.mechanics.parts.2.lead=20 mm"]).axes["X"].mechanics.part("ball-screw").lead
    assert lead == 0.020
    swapped = load_model(cat_model, ["axes.X.mechanics.parts.4.id=table-150kg"]).axes["X"].mechanics.part("table")
    assert swapped.mass == entry("table-150kg").mass == 150.0 and swapped.id == "table-150kg"
    # a value set on the swapped part applies on top of the new entry, whatever the order of the settings
    for order in (1, -1):
        settings = ["axes.X.mechanics.parts.4.id=table-150kg", "axes.X.mechanics.parts.4.mass=200 kg"][::order]
        assert load_model(cat_model, settings).axes["X"].mechanics.part("table").mass == 200.0
    moved = load_model(cat_model, ["axes.X.mechanics.position=0.9"]).axes["X"].mechanics
    assert moved.chain.position == 0.9


def user_table(folder: Path, id: str, mass: str) -> None:
    (folder / "table").mkdir(parents=True, exist_ok=True)
    (folder / "table" / f"{id}.toml").write_text(
        f'kind = "table"\n[parameters]\nmass = "{mass}"\n[provenance]\nsource = "typical"\nrange = "+-1 %"\n')


def test_user_entries_shadow_shipped_ones_in_a_model(cat_model, tmp_path, monkeypatch):
    mine = tmp_path / "mine"
    user_table(mine, "table-400kg", "123 kg")
    assert load_model(cat_model).axes["X"].mechanics.part("table").mass == 400.0
    assert load_model(cat_model, catalogue=load_catalogue([mine])).axes["X"].mechanics.part("table").mass == 123.0
    monkeypatch.setenv(ENV, str(mine))
    assert load_model(cat_model).axes["X"].mechanics.part("table").mass == 123.0


# one part around each entry so that every kind sits where the chain wants it (inline SI values)
_MOTOR = {"kind": "motor", "rotor_inertia": JM}
_SCREW = screw_parts()[2]
_TABLE = {"kind": "table", "mass": M}


def _chain_around(kind: str, ident: str) -> list[dict]:
    part = {"kind": kind, "id": ident}
    if kind == "belt":
        part["length"] = 1.0                     # the installation's (the entries have none)
    return {"motor": [part, _SCREW, _TABLE], "linear-motor": [part, _TABLE],
            "coupling": [_MOTOR, part, _SCREW, _TABLE], "gearbox": [_MOTOR, part, _SCREW, _TABLE],
            "ball-screw": [_MOTOR, part, _TABLE], "belt": [_MOTOR, part, _TABLE], "rack-pinion": [_MOTOR, part, _TABLE],
            "guide": [_MOTOR, _SCREW, part, _TABLE], "table": [_MOTOR, _SCREW, part],
            "encoder": [_MOTOR, _SCREW, _TABLE, part],
            "scale": [_MOTOR, _SCREW, _TABLE, part]}[kind]


def test_every_shipped_entry_builds_a_full_chain_and_passes_the_datasheet_checks():
    catalogue = load_catalogue()
    for item in catalogue:
        data = {"axes": {"X": {"mechanics": {"type": "components", "parts": _chain_around(item.kind, item.id)}}}}
        spec = machine_from_dict(data, source=item.id).axes["X"].mechanics      # raises on any refusal
        assert all(s.stiffness > 0 and math.isfinite(s.stiffness) for s in spec.chain.springs), item.id
        assert all(b.value > 0 for b in spec.chain.bodies), item.id
        if item.kind == "motor" and spec.parts[0].torque_constant is not None:   # the checks need kT
            assert datasheet_warnings(**motor_constants(spec.parts[0])) == [], item.id


# --------------------------------------------------------------------------- check --lumped
def run(*args: str):
    return runner.invoke(app, list(args))


def test_check_lumped_json_adds_the_drive_chain(cat_model):
    plain = json.loads(run("check", str(cat_model), "--json").stdout)
    result = run("check", str(cat_model), "--lumped", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    chain = payload["axes"]["X"].pop("drive_chain")
    assert payload == plain                                          # check's keys unchanged
    assert {"derived", "position", "stroke", "detail", "bodies", "springs", "frictions", "sensors", "actuator",
            "notes", "drive_from_motor", "drive", "drive_overrides"} <= set(chain)
    assert chain["derived"] is True and chain["position"] == 0.3 and chain["stroke"] == 1.0
    assert [s["name"] for s in chain["springs"]] == ["coupling", "screw_torsion", "screw_axial"]
    assert all(s["rule"] and s["frequency_hz"] > 0 for s in chain["springs"])
    motor = entry("servo-motor-400v-11nm")
    assert chain["drive_from_motor"]["force_constant"] == motor.torque_constant        # per A rms already
    assert chain["drive"]["force_constant"] == motor.torque_constant and chain["drive_overrides"] == []
    text = run("check", str(cat_model), "--lumped").stdout
    assert "drive chain" in text and "screw_axial" in text and "force_constant" in text


def test_check_lumped_on_an_already_lumped_axis_says_so():
    example = Path(__file__).resolve().parents[1] / "examples" / "paper_5m4s.toml"
    result = run("check", str(example), "--lumped", "--json")
    assert result.exit_code == 0, result.output
    chain = json.loads(result.stdout)["axes"]["X"]["drive_chain"]
    assert chain["derived"] is False and "already lumped" in chain["note"]
    assert "already lumped" in run("check", str(example), "--lumped").stdout


def test_check_lumped_axis_option_names_an_unknown_axis(cat_model):
    result = run("check", str(cat_model), "--lumped", "--axis", "Q")
    assert result.exit_code == 2 and "Q" in result.output and len(result.output.strip().splitlines()) == 1


# --------------------------------------------------------------------------- --write-lumped
def modal(path: Path, *settings: str) -> list[float]:
    result = run("modal", str(path), "--json", *[w for s in settings for w in ("--set", s)])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)["undamped_hz"]


def margins(path: Path) -> dict:
    result = run("margins", str(path), "--json")
    assert result.exit_code in (0, 3), result.output
    return json.loads(result.stdout)


def test_write_lumped_gives_identical_modes_and_margins(cat_model, tmp_path):
    out = tmp_path / "lumped.toml"
    result = run("check", str(cat_model), "--write-lumped", str(out), "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["written_lumped"] == str(out)
    written = load_model(out)
    assert written.axes["X"].mechanics.type == "lumped"
    # the drive's constants that came from the motor are written out (the lumped file has no motor)
    drive_table = tomllib.loads(out.read_text())["axes"]["X"]["drive"]
    assert drive_table["force_constant"] == entry("servo-motor-400v-11nm").torque_constant
    # the other blocks keep their text (comments, units)
    assert 'bandwidth = "1500 Hz"   # the current loop' in out.read_text()
    assert "check --write-lumped" in out.read_text().splitlines()[0]
    # the same matrices (every number a float written by repr, read back exactly), so the same modes; 1e-12
    # leaves room for nothing but a changed summation order
    np.testing.assert_allclose(modal(out), modal(cat_model), rtol=1e-12)
    a, b = margins(out), margins(cat_model)
    for loop in ("velocity", "position"):
        for key in ("gain_margin_db", "phase_margin_deg", "gain_crossover", "modulus_margin"):
            assert a[loop][key] == pytest.approx(b[loop][key], rel=1e-12), (loop, key)


def test_reduce_write_of_a_drive_chain_keeps_the_text_and_writes_the_motor_constants(cat_model, tmp_path):
    out = tmp_path / "reduced.toml"
    result = run("reduce", str(cat_model), "--method", "physical", "--keep", "motor,table", "--write", str(out))
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert "plain SI numbers" not in text and 'bandwidth = "1500 Hz"' in text
    assert load_model(out).axes["X"].drive.force_constant == entry("servo-motor-400v-11nm").torque_constant


# --------------------------------------------------------------------------- Save Model (§6)
def test_check_write_saves_the_overrides(cat_model, tmp_path):
    out = tmp_path / "saved.toml"
    settings = ["axes.X.mechanics.position=0.8", "axes.X.controller.Kv=40 1/s"]
    result = run("check", str(cat_model), *[w for s in settings for w in ("--set", s)], "--write", str(out))
    assert result.exit_code == 0, result.output
    assert cat_model.read_text() == CAT_MODEL                      # the input untouched
    text = out.read_text()
    assert text.startswith("# Written by `sicomat check --write`") and "--set axes.X.mechanics.position=0.8" in text
    assert "# was" in text and '# the current loop' in text       # the original's text, changed values marked
    saved = load_model(out)
    assert saved.axes["X"].mechanics.position == 0.8 and saved.axes["X"].controller.Kv == 40.0
    np.testing.assert_allclose(modal(out), modal(cat_model, *settings), rtol=1e-12)


def test_check_write_never_replaces_the_model(cat_model):
    result = run("check", str(cat_model), "--write", str(cat_model))
    assert result.exit_code == 2 and cat_model.read_text() == CAT_MODEL


def shadow_catalogue(folder: Path) -> None:
    """User entries that shadow the model's: a heavier table, and a motor with another rotor and, new, a
    shaft stiffness (an optional value the shipped entry does not have)."""
    user_table(folder, "table-400kg", "800 kg")
    motor = (load_catalogue().get("servo-motor-400v-11nm").source)
    text = Path(motor).read_text().replace('rotor_inertia = "16 kg*cm^2"',
                                           'rotor_inertia = "30 kg*cm^2"\nshaft_torsional_stiffness = "2e4 N*m/rad"')
    assert text != Path(motor).read_text()
    (folder / "motor").mkdir(parents=True, exist_ok=True)
    (folder / "motor" / "servo-motor-400v-11nm.toml").write_text(text)


def test_a_saved_model_loads_unchanged_after_its_entries_change(cat_model, tmp_path, monkeypatch):
    tuned = tmp_path / "tuned.toml"
    result = run("tune", str(cat_model), "--write", str(tuned))
    assert result.exit_code == 0, result.output
    text = tuned.read_text()
    assert 'id = "table-400kg"' in text and "recorded = true" in text and "mass = 400.0" in text   # ids and values
    assert "force_constant" not in text          # the drive stays implied by the (recorded) motor
    before, original = modal(tuned), modal(cat_model)
    np.testing.assert_allclose(before, original, rtol=1e-12)
    mine = tmp_path / "mine"
    shadow_catalogue(mine)
    monkeypatch.setenv(ENV, str(mine))
    # the saved model: the same numbers (plain floats read back exactly), the same modes
    assert modal(tuned) == before
    assert load_model(tuned).axes["X"].mechanics.part("table").mass == 400.0
    # the original (ids only) follows the new entries: a heavier table, a stiff shaft spring more
    moved = modal(cat_model)
    assert len(moved) == len(original) + 1 and moved[1] < original[1]
    # re-reading an entry is asked for by naming it again
    again = load_model(tuned, ["axes.X.mechanics.parts.4.id=table-400kg"]).axes["X"].mechanics.part("table")
    assert again.mass == 800.0


def test_a_saved_model_loads_when_its_user_entry_is_gone(cat_model, tmp_path, monkeypatch):
    mine = tmp_path / "mine"
    user_table(mine, "my-table", "250 kg")
    monkeypatch.setenv(ENV, str(mine))
    cat_model.write_text(CAT_MODEL.replace('id = "table-400kg"', 'id = "my-table"'))
    out = tmp_path / "saved.toml"
    assert run("check", str(cat_model), "--write", str(out)).exit_code == 0
    saved = modal(out)
    monkeypatch.delenv(ENV)
    assert modal(out) == saved
    gone = run("check", str(cat_model))
    assert gone.exit_code == 2 and "unknown catalogue id" in gone.output


def test_save_model_in_python_records_the_catalogue_values(cat_model, tmp_path):
    from sicomat.io.modelfile import save_model, with_overrides

    machine = with_overrides(load_model(cat_model), {"axes.X.mechanics.position": 0.7})
    out = save_model(machine, tmp_path / "plain.toml")             # no based_on: plain SI numbers
    data = tomllib.loads(out.read_text())
    table = data["axes"]["X"]["mechanics"]["parts"][4]
    assert table == {"kind": "table", "id": "table-400kg", "recorded": True, "mass": 400.0}
    assert load_model(out).axes["X"].mechanics.chain.position == 0.7


# --------------------------------------------------------------------------- bad input
BAD = [
    ("unknown id", ('id = "table-400kg"', 'id = "table-400kgg"'), "axes.X.mechanics.parts.4.id",
     "closest: table-400kg", "'table-400kgg'"),
    ("motor after the screw", ('kind = "guide"\nid = "profile-rail-ball-35"', 'kind = "motor"\nrotor_inertia = 1e-3'),
     "axes.X.mechanics.parts.3.kind", "parts go from the motor to the load", "'motor'"),
    ("coupling without stiffness at full", ('kind = "coupling"\nid = "bellows-coupling-60nm"',
                                            'kind = "coupling"\ninertia = "1e-4 kg*m^2"'),
     "axes.X.mechanics.parts.1.torsional_stiffness", "detail 'full' needs the coupling's torsional_stiffness", ""),
    ("position outside the stroke", ('position = "0.3 m"', 'position = "1.3 m"'), "axes.X.mechanics.position",
     "outside the stroke [0, 1] m", "1.3"),
    ("kT against kE off by 20 %", ('id = "servo-motor-400v-11nm"',
                                   'id = "servo-motor-400v-11nm"\nback_emf_constant = "1.2470 V*s/rad"'),
     "axes.X.mechanics.parts.0.back_emf_constant", "inconsistent datasheet values", "1.247"),
    ("auto without bandwidth", ('detail = "full"', 'detail = "auto"'), "axes.X.mechanics.bandwidth",
     "give 'bandwidth'", ""),
    ("unknown part kind", ('kind = "guide"', 'kind = "guides"'), "axes.X.mechanics.parts.3.kind",
     "unknown part kind; expected one of motor, linear-motor", "'guides'"),
    ("unknown part kind inline", ('kind = "guide"\nid = "profile-rail-ball-35"', 'kind = "guides"\nfriction_coefficient = 0.1'),
     "axes.X.mechanics.parts.3.kind", "unknown part kind", "'guides'"),
    ("misspelt part key", ('mounting = "fixed-supported"', 'mountng = "fixed-supported"'),
     "axes.X.mechanics.parts.2.mountng", "closest ball-screw parameters: mounting", "'fixed-supported'"),
]


def assert_one_line(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output, result.output
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert "more problem" not in lines[0]             # the drive keys the motor would give are not reported


@pytest.mark.parametrize("case, edit, path, message, value", BAD, ids=[b[0] for b in BAD])
def test_bad_drive_chain_is_one_line_and_nothing_is_written(cat_model, tmp_path, case, edit, path, message, value):
    assert edit[0] in CAT_MODEL
    cat_model.write_text(CAT_MODEL.replace(*edit))
    outputs = [tmp_path / "a.toml", tmp_path / "b.toml"]
    for args in (["--lumped"], ["--write-lumped", str(outputs[0]), "--write", str(outputs[1])]):
        result = run("check", str(cat_model), *args)
        assert_one_line(result, f"error: {cat_model}: {path}: ", message, f"(got {value}" if value else "")
    assert not any(p.exists() for p in outputs)
    assert run("modal", str(cat_model)).exit_code == 2


def test_bad_position_by_set_names_the_override(cat_model):
    result = run("check", str(cat_model), "--set", "axes.X.mechanics.position=1.3")
    assert_one_line(result, "--set axes.X.mechanics.position=1.3", "outside the stroke", "(got 1.3)")


def test_a_duplicate_id_in_a_user_catalogue_used_by_a_model(cat_model, tmp_path, monkeypatch):
    for sub in ("a", "b"):
        user_table(tmp_path / "dup" / sub, "twin", "10 kg")
    monkeypatch.setenv(ENV, str(tmp_path / "dup"))
    out = tmp_path / "out.toml"
    result = run("check", str(cat_model), "--write", str(out))
    assert_one_line(result, "duplicate catalogue id", "(got 'twin')", str(cat_model), "parts.0.id")
    assert not out.exists()


def test_unknown_id_by_set_names_the_override(cat_model):
    result = run("check", str(cat_model), "--set", "axes.X.mechanics.parts.4.id=table-40kg")
    assert_one_line(result, "--set axes.X.mechanics.parts.4.id=table-40kg", "unknown catalogue id", "closest")



@pytest.mark.parametrize("detail, extra", [("full", {}), ("2-mass", {}), ("rigid", {}),
                                           ("auto", {"bandwidth": 30.0})])
def test_write_lumped_gives_the_same_matrices_at_every_detail(tmp_path, detail, extra):
    from sicomat.tasks.lumped import write_lumped

    mech = {"type": "components", "parts": screw_parts("fixed-fixed"), "position": 0.35, "detail": detail, **extra}
    machine = machine_from_dict({"axes": {"X": {"mechanics": mech}}})
    out = write_lumped(machine, tmp_path / "lumped.toml")
    a = build_mechanics(machine.axes["X"].mechanics)
    b = build_mechanics(load_model(out).axes["X"].mechanics)
    assert load_model(out).axes["X"].mechanics.type == "lumped" and a.dof_names == b.dof_names
    # every number is a float written by repr and read back exactly, assembled by the same code: bit for bit
    for name in ("mass", "stiffness", "damping"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
