"""The sizing check (`sicomat size`, issue 12 §5) against hand calculations of a rigid ball-screw axis.

The axis: a rotary motor, a coupling, a ball screw (lead p = 10 mm) and a 200 kg table on a guide with
Coulomb friction μ·m·g, lumped at detail "rigid" into one translating body, so that the motor torque of a
trapezoidal move has a closed form: ``T = J·a/lead ± F·lead`` with ``lead = p/2π`` and ``J`` the sum of the
rotor, coupling, screw (π·ρ·L·d⁴/32) and table (m·lead²) inertias at the motor shaft.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sicomat.cli.main import app
from sicomat.io.modelfile import load_model, machine_from_dict

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
runner = CliRunner()

# the axis, SI
LEAD = 0.010 / (2.0 * math.pi)                 # m/rad
J_ROTOR, J_COUPLING, MASS = 10e-4, 2e-4, 200.0
J_SCREW = math.pi * 7850.0 * 1.0 * 0.032 ** 4 / 32.0   # steel, nominal diameter 32 mm, 1 m
J_TOTAL = J_ROTOR + J_COUPLING + J_SCREW + MASS * LEAD ** 2
MU, G = 0.05, 9.80665
FRICTION = MU * MASS * G                       # N at the table
KT, KE = 1.5, 0.866                            # N·m/A rms; V·s/rad line-to-line rms (kT = √3·kE)
# the move: 100 mm, 0.3 m/s, 3 m/s² (trapezoid: t_a = 0.1 s, cruise 0.2333 s)
DISTANCE, V_MAX, A_MAX = 0.1, 0.3, 3.0
# the loop: sampled at 125 µs (position and velocity), current loop 5 kHz, velocity and acceleration
# feedforward 1
T_V = 125e-6
TAU = 1.0 / (2.0 * math.pi * 5000.0)
KP_NORMALIZED, TI, KV = 100.0, 15e-3, 25.0


def model(**motor) -> dict:
    parts = [{"kind": "motor", "rotor_inertia": J_ROTOR, "torque_constant": KT, "torque_constant_basis": "rms",
              "back_emf_constant": KE, "back_emf_basis": "line-to-line-rms", "resistance": 1.0,
              "resistance_basis": "phase", "inductance": 5e-3, "inductance_basis": "phase", "pole_pairs": 4,
              "stall_torque": 6.0, "stall_current": 4.0, "peak_torque": 18.0, "peak_current": 14.0,
              "max_speed": "3000 rpm", "dc_bus": 560.0, **motor},
             {"kind": "coupling", "inertia": J_COUPLING, "torsional_stiffness": 2e4},
             {"kind": "ball-screw", "lead": "10 mm", "diameter": 0.032, "root_diameter": 0.026, "length": 1.0,
              "mounting": "fixed-supported", "nut_stiffness": 5e8, "bearing_stiffness": 6e8},
             {"kind": "guide", "friction_coefficient": MU},
             {"kind": "table", "mass": MASS},
             {"kind": "encoder", "resolution": 1048576}]
    parts[0] = {k: v for k, v in parts[0].items() if v is not None}
    return {"name": "rigid-screw", "axes": {"X": {
        "tool": "table",
        "mechanics": {"type": "components", "detail": "rigid", "parts": parts},
        "drive": {"type": "first-order", "bandwidth": 5000.0},
        "controller": {"type": "P-PI", "position_sensor": "encoder", "Kv": KV, "Kp_normalized": KP_NORMALIZED,
                       "Ti": TI, "velocity_feedforward": 1.0, "acceleration_feedforward": 1.0,
                       "position_period": T_V, "velocity_period": T_V},
        "trajectory": {"type": "trapezoid", "distance": DISTANCE, "max_velocity": V_MAX,
                       "max_acceleration": A_MAX}}}}


def write_model(tmp_path: Path, data: dict) -> Path:
    import tomlkit

    path = tmp_path / "axis.toml"
    path.write_text(tomlkit.dumps(data))
    return path


@pytest.fixture(scope="module")
def rigid():
    from sicomat.tasks.size import size_axis

    return size_axis(machine_from_dict(model()))


@pytest.fixture(scope="module")
def allowance():
    """Largest torque (N·m) and speed (rad/s) by which the loop's feedback can move the motor away from
    the rigid closed form, from the loop's tracking error.

    With velocity and acceleration feedforward 1 the feedforward alone gives ``J·a/lead`` exactly; the
    feedback (P-PI) torque answers two disturbances: (1) the friction ``F·lead`` (not fed forward), (2) the
    delay between the setpoint and the torque, ``T_d`` = one velocity period of computation delay + the current
    loop's lag τ + half a period for the differenced velocity + half a position period of the held setpoint,
    so the axis lags the setpoint's velocity by ``a·T_d`` and the P part adds ``Kp·a·T_d``. For a
    disturbance at the plant input the feedback effort is the velocity loop's complementary sensitivity
    applied to it, so its peak is the disturbance × (1 + the velocity loop's step overshoot M); M comes from
    the linear sampled velocity loop (``velocity_step``, a frequency-domain model, not the simulator).
    The speed's deviation is the same disturbances divided by ``Kp``: the lag ``a·T_d`` and the friction's
    ``F·lead/Kp``, × (1 + M), at the motor shaft ÷ lead.
    """
    from sicomat.frequency.loops import LoopAnalysis
    from sicomat.servo.loop import build_servo_loop
    from sicomat.tuning.time import velocity_step

    loop = build_servo_loop(machine_from_dict(model()))
    overshoot = velocity_step(LoopAnalysis.of(loop), loop.Kp, loop.Ti).overshoot_percent / 100.0
    assert 0.0 <= overshoot < 1.0
    t_d = T_V + TAU + T_V / 2 + T_V / 2
    kp = KP_NORMALIZED * J_TOTAL / LEAD          # N·m per m/s of the table
    torque = (1.0 + overshoot) * (FRICTION * LEAD + kp * A_MAX * t_d)
    speed = (1.0 + overshoot) * (A_MAX * t_d + FRICTION * LEAD / kp) / LEAD
    return torque, speed


def test_peak_torque_of_the_rigid_move_against_its_closed_form(rigid, allowance):
    # acceleration: J·a/lead + F·lead (friction against the motion); deceleration is smaller by 2·F·lead
    hand = J_TOTAL * A_MAX / LEAD + FRICTION * LEAD
    peak = rigid.check("peak_torque")
    # below: the momentum balance over the acceleration phase (t_a = 0.1 s) makes the mean torque
    # J·Δω/t_a + F·lead, and the speed at its end lags by a·T_d ≈ 0.3 ms·a only (0.3 % of Δω): 1 % covers it
    assert hand * (1 - 0.01) <= peak.value <= hand + allowance[0]
    assert (peak.limit, peak.ok, peak.unit) == (18.0, True, "N·m")


def test_rms_torque_of_the_trapezoid_against_its_closed_form(rigid, allowance):
    t_a = V_MAX / A_MAX
    t_c = DISTANCE / V_MAX - t_a
    t_move = 2 * t_a + t_c
    f = FRICTION * LEAD
    acc, dec = J_TOTAL * A_MAX / LEAD + f, -J_TOTAL * A_MAX / LEAD + f
    hand = math.sqrt((acc ** 2 * t_a + f ** 2 * t_c + dec ** 2 * t_a) / t_move)   # over the move, no dwell
    rms = rigid.check("rms_torque")
    # Minkowski: |rms(T) − rms(T_hand)| ≤ rms(T − T_hand) ≤ max |T − T_hand|, the feedback's allowance
    assert abs(rms.value - hand) <= allowance[0]
    assert rms.limit == 6.0 and rms.ok is True          # stall_torque: the continuous torque
    assert rigid.move["window"] == pytest.approx([0.0, t_move], abs=1e-12)


def test_max_speed_is_the_top_speed_through_the_lead(rigid, allowance):
    speed = rigid.check("max_speed")
    assert abs(speed.value - V_MAX / LEAD) <= allowance[1]          # 188.5 rad/s = 1800 rpm
    assert speed.limit == pytest.approx(3000 * 2 * math.pi / 60, rel=1e-12) and speed.ok is True
    screw = rigid.check("screw_critical_speed")      # no gearbox: the screw turns with the motor
    assert screw.value == speed.value
    critical = (3.9266 / 1.0) ** 2 * (0.026 / 4) * math.sqrt(2.06e11 / 7850.0)   # fixed-supported, L = 1 m
    assert screw.limit == pytest.approx(0.8 * critical, rel=1e-4)    # λ to 5 digits
    assert screw.ok is True


def test_back_emf_is_the_line_peak_at_top_speed(rigid):
    emf = rigid.check("back_emf")
    assert emf.value == pytest.approx(math.sqrt(2) * KE * rigid.check("max_speed").value, rel=1e-12)
    assert emf.limit == pytest.approx(560.0, rel=1e-12)   # the drive's supply voltage × √6 = the motor's dc_bus
    voltage = rigid.check("voltage")                      # plus the resistive and inductive drops
    assert voltage.value > emf.value and voltage.ok is True


def test_inertia_ratio_against_the_hand_sum(rigid):
    ratio = rigid.check("inertia_ratio")
    assert ratio.value == pytest.approx((J_COUPLING + J_SCREW + MASS * LEAD ** 2) / J_ROTOR, rel=1e-12)
    assert ratio.limit == 10.0 and ratio.ok is True


def test_peak_current_is_the_demand_against_the_drive(rigid):
    current = rigid.check("peak_current")
    assert current.limit == 14.0 and current.ok is True
    # the demand is the torque / kT (the current loop's lag makes the applied torque lag the demand)
    assert current.value * KT >= rigid.check("peak_torque").value * (1 - 1e-9)


def test_missing_limits_are_unknown_never_passed(rigid):
    unknown = {c.name for c in rigid.checks if c.ok is None}
    assert {"coupling_torque", "coupling_speed", "screw_max_speed"} <= unknown
    for c in rigid.checks:
        if c.ok is None:
            assert c.limit is None and c.note
    assert rigid.ok is None       # nothing failed, but not everything is known


def test_a_motor_without_max_speed_leaves_the_speed_check_unknown():
    from sicomat.tasks.size import size_axis

    result = size_axis(machine_from_dict(model(max_speed=None)), move_mm=20.0)
    speed = result.check("max_speed")
    assert speed.value > 0 and speed.limit is None and speed.ok is None
    assert "max_speed" in speed.note
    assert "max_speed" in result.to_dict()["unknown"] and result.ok is None


def test_a_failing_check_comes_first_and_is_a_warning(tmp_path):
    path = write_model(tmp_path, model(peak_torque=3.0))
    result = runner.invoke(app, ["size", str(path), "--json"])
    assert result.exit_code == 0, result.output           # as tune's unmet targets: reported, status 0
    payload = json.loads(result.stdout)
    assert payload["ok"] is False and payload["failed"] == ["peak_torque"]
    assert payload["checks"][0]["name"] == "peak_torque" and payload["checks"][0]["ok"] is False
    order = [{False: 0, True: 1, None: 2}[c["ok"]] for c in payload["checks"]]
    assert order == sorted(order)
    assert any("peak_torque" in w for w in payload["warnings"])
    table = runner.invoke(app, ["size", str(path)])
    assert table.exit_code == 0 and "FAIL" in table.stdout
    assert table.stdout.index("peak_torque") < table.stdout.index("max_speed")


def test_json_keys(tmp_path):
    path = write_model(tmp_path, model())
    result = runner.invoke(app, ["size", str(path), "--move", "20", "--json", "--inertia-ratio-limit", "1"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert {"axis", "ok", "checks", "failed", "unknown", "move", "stable", "warnings"} <= set(payload)
    for check in payload["checks"]:
        assert set(check) == {"name", "value", "limit", "ok", "unit", "note"}
    ratio = next(c for c in payload["checks"] if c["name"] == "inertia_ratio")
    assert ratio["limit"] == 1.0 and ratio["ok"] is False           # 1.51 > 1
    assert payload["move"]["source"] == "move"


def test_gearbox_divides_the_screw_speed():
    from sicomat.tasks.size import size_axis

    data = model()
    parts = data["axes"]["X"]["mechanics"]["parts"]
    parts.insert(2, {"kind": "gearbox", "ratio": 2.0, "input_inertia": 1e-5, "torsional_stiffness": 1e5,
                     "efficiency": 0.9, "rated_torque": 20.0, "max_input_speed": "6000 rpm"})
    result = size_axis(machine_from_dict(data), move_mm=20.0)
    motor, screw = result.check("max_speed").value, result.check("screw_critical_speed").value
    assert screw == pytest.approx(motor / 2.0, rel=1e-12)
    assert result.check("gearbox_input_speed").value == motor
    assert result.check("gearbox_torque").value == pytest.approx(
        2.0 / 0.9 * _rms_of(result), rel=1e-12)


def _rms_of(result) -> float:
    return result.check("rms_torque").value


def test_a_lumped_axis_sizes_the_drive_only():
    from sicomat.tasks.size import size_axis

    result = size_axis(load_model(EXAMPLES / "ballscrew_3m2s.toml"), move_mm=20.0)
    assert result.check("peak_current").ok is True
    for name in ("peak_torque", "rms_torque", "max_speed"):
        assert result.check(name).ok is None and "motor part" in result.check(name).note
    assert any("components" in note for note in result.notes)


def test_an_unstable_run_is_reported_not_sized(tmp_path):
    data = model()
    data["axes"]["X"]["controller"]["Kv"] = 4000.0       # far beyond the velocity loop's bandwidth
    result = runner.invoke(app, ["size", str(write_model(tmp_path, data)), "--move", "5", "--json"])
    assert result.exit_code == 3, result.output           # as simulate: the payload, then status 3
    payload = json.loads(result.stdout)
    assert payload["stable"] is False and payload["checks"] == [] and payload["ok"] is None


@pytest.mark.parametrize("args, words", [
    (["--axis", "Q"], "unknown axis 'Q'"),
    (["--gcode", "missing.nc"], "no such G-code file"),
    (["--gcode", "x.nc", "--move", "5"], "--gcode cannot be combined with --move"),
    (["--feed", "1000"], "--feed"),
    (["--max-velocity", "1"], "give --move MM"),
    (["--inertia-ratio-limit", "0"], "--inertia-ratio-limit"),
])
def test_bad_input_is_one_line_and_status_2(tmp_path, args, words):
    path = write_model(tmp_path, model())
    result = runner.invoke(app, ["size", str(path), *args])
    assert result.exit_code == 2, result.output
    assert words in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_no_move_is_bad_input(tmp_path):
    data = model()
    del data["axes"]["X"]["trajectory"]
    result = runner.invoke(app, ["size", str(write_model(tmp_path, data))])
    assert result.exit_code == 2 and "no move to size" in result.output


def test_a_linear_motor_is_sized_in_force_and_without_inertia_ratio():
    from sicomat.tasks.size import size_axis

    data = {"axes": {"X": {
        "mechanics": {"type": "components", "parts": [
            {"kind": "linear-motor", "primary_mass": 3.0, "force_constant": 80.0, "force_constant_basis": "rms",
             "peak_force": 1250.0, "continuous_force": 500.0, "max_speed": 5.0},
            {"kind": "table", "mass": 47.0}, {"kind": "scale", "resolution": 1e-7}]},
        "drive": {"type": "first-order", "bandwidth": 2000.0},
        "controller": {"type": "P-PI", "position_sensor": "scale", "Kv": 30.0, "Kp_normalized": 200.0, "Ti": 8e-3,
                       "velocity_feedforward": 1.0, "acceleration_feedforward": 1.0}}}}
    result = size_axis(machine_from_dict(data), move_mm=50.0, max_velocity=0.5, max_acceleration=5.0)
    names = {c.name: c for c in result.checks}
    assert {"peak_force", "rms_force", "max_speed"} <= set(names) and "inertia_ratio" not in names
    assert names["peak_force"].unit == "N" and names["max_speed"].unit == "m/s"
    assert names["peak_force"].limit == 1250.0 and names["rms_force"].limit == 500.0
    # no friction: the feedforward gives 50 kg × 5 m/s² = 250 N; the feedback adds the delay's share
    # (1 + M)·Kp_n·T_d of it (the allowance fixture's reasoning), T_d = 125 µs computation + τ (2 kHz) +
    # half a velocity period + half the default 1 ms position period
    from sicomat.frequency.loops import LoopAnalysis
    from sicomat.servo.loop import build_servo_loop
    from sicomat.tuning.time import velocity_step

    loop = build_servo_loop(machine_from_dict(data))
    overshoot = velocity_step(LoopAnalysis.of(loop), loop.Kp, loop.Ti).overshoot_percent / 100.0
    t_d = 125e-6 + 1.0 / (2.0 * math.pi * 2000.0) + 62.5e-6 + 0.5e-3
    assert 250.0 * (1 - 0.01) <= names["peak_force"].value <= 250.0 * (1.0 + (1.0 + overshoot) * 200.0 * t_d)
    assert any("mass" in note for note in result.notes)


def test_size_on_a_gcode_path(tmp_path):
    result = runner.invoke(app, ["size", str(EXAMPLES / "xy_table.toml"), "--gcode", str(EXAMPLES / "contour.nc"),
                                 "--axis", "Y", "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["axis"] == "Y" and payload["move"]["source"] == "gcode"
    assert payload["move"]["file"].endswith("contour.nc")
    assert next(c for c in payload["checks"] if c["name"] == "peak_current")["ok"] is True


def test_the_inertia_ratio_does_not_depend_on_the_detail():
    # the derived bodies of a 'full' chain (motor, coupling halves, screw split at the nut, table) referred to
    # the motor shaft sum to the same J as the rigid lump: the hand sum, to rounding (1e-12)
    from sicomat.tasks.size import size_axis

    data = model()
    data["axes"]["X"]["mechanics"]["detail"] = "full"
    ratio = size_axis(machine_from_dict(data), move_mm=5.0).check("inertia_ratio")
    assert ratio.value == pytest.approx((J_COUPLING + J_SCREW + MASS * LEAD ** 2) / J_ROTOR, rel=1e-12)


def test_a_drive_that_saturates_fails_its_peak_current():
    # 3 A × 1.5 N·m/A = 4.5 N·m cannot accelerate the axis at 3 m/s² against its friction (4.90 N·m): the
    # controller asks for more current than the drive gives, and the check fails although the clipped torque
    # stays below the motor's peak torque (a far smaller drive ends the move in a limit cycle: unstable, not sized)
    from sicomat.tasks.size import size_axis

    data = model()
    data["axes"]["X"]["drive"]["peak_current"] = 3.0
    result = size_axis(machine_from_dict(data))
    assert result.verdict.stable is True
    current = result.check("peak_current")
    assert current.ok is False and current.value > 3.0 and current.limit == 3.0
    assert result.check("peak_torque").value <= 3.0 * KT * (1 + 1e-9)
    assert result.ok is False


def test_a_motor_encoder_axis_without_tool_moves_the_table():
    # a drive chain's tool defaults to its table (the load body), so a move on a motor-encoder loop is in metres
    # of the table, not radians of the motor: the same sizing as with tool = "table" written out
    from sicomat.tasks.size import size_axis

    data = model()
    written = size_axis(machine_from_dict(data), move_mm=5.0)
    del data["axes"]["X"]["tool"]
    implied = size_axis(machine_from_dict(data), move_mm=5.0)
    assert machine_from_dict(data).axes["X"].tool == "table"
    assert not any("axis coordinate" in n for n in implied.notes)
    assert [c.value for c in implied.checks] == [c.value for c in written.checks]
