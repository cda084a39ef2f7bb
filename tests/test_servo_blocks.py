"""Conformance of every registered drive and controller kind (sicomat.servo.blocks), and the P-TF
controller against python-control.

Every kind in the registries runs through the same checks: the simulated response of its linearised
loop equals the loop's linear model (the one the stability verdict and the frequency responses use),
that model's transfer equals the frequency response of ``LoopAnalysis``, the description round-trips
through the model file, bad parameters give located errors.
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import control
import numpy as np
import pytest
from typer.testing import CliRunner

from sicomat import dump_model, load_model, machine_from_dict
from sicomat.cli.main import app
from sicomat.errors import ModelError
from sicomat.frequency.loops import LoopAnalysis
from sicomat.motion.setpoints import step_profile
from sicomat.servo.blocks import CONTROLLERS, DRIVES, controller_kind, linear_law
from sicomat.servo.loop import build_servo_loop
from sicomat.servo.stability import loop_verdict, position_closed_loop
from sicomat.simulation import simulate

M1, M2, K, C = 10.0, 30.0, 2.0e6, 500.0   # motor-side mass, table, transmission
KT, TAU = 50.0, 2.0e-4
KP, TI, KV = 2000.0, 0.02, 12.0            # Kp in N·s/m
H = 2.0e-4                                 # velocity period
NP = 4                                     # position period = NP·H
B_LAG = 0.3                                # pole of the P-TF law's first-order lag, in z


def _tf_coefficients():
    """The P-TF law used here: the P-PI law ``(1 − a z⁻¹)/(1 − z⁻¹)`` (a = 1 − T/Ti) times a unit-gain lag
    ``(1 − b)/(1 − b z⁻¹)``: a velocity law a P-PI cannot express."""
    a = 1.0 - H / TI
    return [(1 - B_LAG), -(1 - B_LAG) * a], [1.0, -(1.0 + B_LAG), B_LAG]


CONTROLLER_PARAMETERS = {
    "P-PI": {"Kp": KP, "Ti": TI},
    "P-IP": {"Kp": KP, "Ti": TI},
    "P-TF": {"Kp": KP, "numerator": _tf_coefficients()[0], "denominator": _tf_coefficients()[1]},
}
DRIVE_PARAMETERS = {"first-order": {"force_constant": KT, "time_constant": TAU}}
KINDS = list(itertools.product(CONTROLLERS.types(), DRIVES.types()))


def test_every_registered_kind_has_conformance_parameters():
    # a kind registered without parameters here would skip the suite: fail instead
    assert set(CONTROLLERS.types()) == set(CONTROLLER_PARAMETERS)
    assert set(DRIVES.types()) == set(DRIVE_PARAMETERS)


def _data(controller_type, drive_type, **controller):
    return {"axes": {"X": {
        "mechanics": {"type": "chain", "masses": [M1, M2], "stiffnesses": [K], "dampings": [C]},
        "drive": {"type": drive_type, **DRIVE_PARAMETERS[drive_type]},
        "controller": {"type": controller_type, "position_sensor": "last", "velocity_sensor": "last",
                       "Kv": KV, "position_period": NP * H, "velocity_period": H, "velocity_delay": 1,
                       "position_delay": 1, "current_filters": [{"type": "low-pass", "frequency": 800.0}],
                       **CONTROLLER_PARAMETERS[controller_type], **controller}}}}


def _loop(controller_type, drive_type, **controller):
    return build_servo_loop(machine_from_dict(_data(controller_type, drive_type, **controller)))


@pytest.mark.parametrize("domain", ["discrete", "continuous"])
@pytest.mark.parametrize("controller_type, drive_type", KINDS)
def test_simulated_linear_loop_equals_the_linear_model(controller_type, drive_type, domain):
    analog = {"velocity_loop": "continuous", "velocity_delay": 0} if domain == "continuous" else {}
    try:
        loop = _loop(controller_type, drive_type, **analog)
    except ModelError as exc:       # a kind without a continuous law must say so, located
        assert domain == "continuous" and "axes.X.controller.velocity_loop" in str(exc)
        with pytest.raises(ModelError):
            spec = machine_from_dict(_data(controller_type, drive_type)).axes["X"].controller
            controller_kind(controller_type).continuous_law(spec, KP, TI)
        return
    an = LoopAnalysis.of(loop)
    assert loop_verdict(loop, an=an).stable
    step = 1e-3
    series = simulate(loop, step_profile(step), 0.08, nonlinear=False)
    A, B, Cc, period = position_closed_loop(an, loop.Kp, loop.Ti, loop.Kv)
    assert period == pytest.approx(NP * H)
    x = np.zeros(A.shape[0])
    expected = []
    for _ in range(len(series.time[::NP])):
        expected.append(Cc @ x)
        x = A @ x + B * step
    measured = (series["setpoint.fine"] - series["following_error"])[::NP]
    # the kernel (its program from servo_program) against the lifted model (from LoopModel; an analog velocity
    # loop: the ZOH at Tp of its continuous closed loop): two realisations of the same sampled loop, both
    # discretised by expm (a few eps per step); 100 position samples of a
    # stable loop whose realisations have condition numbers ~1e4 (the differencing 1/T, the masses): rounding
    # ~1e4·100·eps ≈ 2e-10 relative to the 1e-3 m step, i.e. 2e-13 m; 1e-12 m allows it
    np.testing.assert_allclose(measured, expected, rtol=0, atol=1e-12)
    assert np.ptp(measured) > 0.5 * step          # the loop moved


@pytest.mark.parametrize("controller_type, drive_type", KINDS)
def test_frequency_responses_equal_the_linear_model(controller_type, drive_type):
    loop = _loop(controller_type, drive_type)
    an = LoopAnalysis.of(loop)
    eps = np.finfo(float).eps
    # the closed velocity loop: LoopAnalysis (its factors: law, actuation, plant, measurement at z) against the
    # closed state space of LoopModel at z = e^{jωT} (one LU solve per point)
    omega = np.geomspace(2 * np.pi, 0.9 * np.pi / H, 300)
    frf = an.response("velocity-closed", omega).response
    A, B, Cc = an.velocity_closed_loop(loop.Kp, loop.Ti)
    z = np.exp(1j * omega * H)
    resolvent = z[:, None, None] * np.eye(A.shape[0]) - A
    ss = np.array([Cc[1] @ np.linalg.solve(R, B[:, 0]) for R in resolvent])
    # the LU solve's relative error is ~ n·eps·κ(zI − A); the factors' product a few eps each (the plant's own
    # evaluation is an LU of the same conditioning): 100·eps·κ bounds both
    kappa = np.array([np.linalg.cond(R) for R in resolvent])
    assert np.all(np.abs(frf - ss) <= 100 * eps * kappa * np.maximum(np.abs(ss), 1e-3))
    # the closed position loop (setpoint → measured position) against the one the verdict takes the poles of
    omega_p = np.geomspace(2 * np.pi, 0.9 * np.pi / (NP * H), 200)
    frf = an.response("position-closed", omega_p).response
    Ap, Bp, Cp, _ = position_closed_loop(an, loop.Kp, loop.Ti, loop.Kv)
    z = np.exp(1j * omega_p * NP * H)
    resolvent = z[:, None, None] * np.eye(Ap.shape[0]) - Ap
    ss = np.array([Cp @ np.linalg.solve(R, Bp) for R in resolvent])
    kappa = np.array([np.linalg.cond(R) for R in resolvent])
    assert np.all(np.abs(frf - ss) <= 100 * eps * kappa * np.maximum(np.abs(ss), 1e-3))


@pytest.mark.parametrize("controller_type, drive_type", KINDS)
def test_kind_round_trips_through_the_model_file(controller_type, drive_type, tmp_path):
    machine = machine_from_dict(_data(controller_type, drive_type))
    path = tmp_path / "model.toml"
    path.write_text(dump_model(machine))
    again = load_model(path)
    assert again == machine
    assert again.axes["X"].controller.type == controller_type
    assert again.axes["X"].drive.type == drive_type


@pytest.mark.parametrize("controller_type, drive_type", KINDS)
def test_kind_rejects_an_unknown_key_and_a_bad_value_with_its_location(controller_type, drive_type):
    with pytest.raises(ModelError, match=r"axes\.X\.controller\.colour"):
        machine_from_dict(_data(controller_type, drive_type, colour=1))
    with pytest.raises(ModelError, match=r"axes\.X\.controller\.Kv"):
        machine_from_dict(_data(controller_type, drive_type, Kv=-1.0))
    bad = _data(controller_type, drive_type)
    bad["axes"]["X"]["drive"]["force_constant"] = -1.0
    with pytest.raises(ModelError, match=r"axes\.X\.drive\.force_constant"):
        machine_from_dict(bad)


def test_stability_verdict_does_not_read_the_frequency_package():
    import subprocess
    import sys

    code = ("import sys, sicomat\n"
            "from sicomat.servo.loop import build_servo_loop\n"
            "from sicomat.servo.stability import loop_verdict\n"
            "assert loop_verdict(build_servo_loop(sicomat.load_model('examples/paper_2m1s.toml'))).stable\n"
            "print(sorted(m for m in sys.modules if m.startswith('sicomat.frequency')))\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root, env=env)
    assert out.stdout.strip() == "[]"


def test_unknown_types_name_the_known_ones():
    with pytest.raises(ModelError, match=r"axes\.X\.controller\.type.*P-PI.*P-TF"):
        machine_from_dict(_data("P-PI", "first-order", type="P-ID"))
    with pytest.raises(ModelError, match="known types: P-PI, P-IP, P-TF"):
        controller_kind("P-ID", path="axes.X.controller.type")
    with pytest.raises(ModelError, match="known types: first-order"):
        DRIVES.lookup("pi-current", path="axes.X.drive.type")


@pytest.mark.parametrize("change, where", [
    ({"Ti": TI}, r"controller\.Ti"),                                # a P-TF law has no Ti
    ({"denominator": [0.0, 1.0]}, r"controller\.denominator\.0"),   # not causal
    ({"numerator": [0.0, 0.0]}, r"controller\.numerator"),
    ({"numerator": []}, r"controller\.numerator"),
    ({"anti_windup": "clamping"}, r"controller\.anti_windup"),
    ({"velocity_loop": "continuous", "velocity_delay": 0}, r"controller\.velocity_loop"),
])
def test_transfer_function_controller_rejects_bad_parameters(change, where):
    with pytest.raises(ModelError, match=where):
        machine_from_dict(_data("P-TF", "first-order", **change))


def test_pi_controllers_reject_transfer_function_keys_and_need_ti():
    with pytest.raises(ModelError, match=r"controller\.numerator.*P-TF"):
        machine_from_dict(_data("P-PI", "first-order", numerator=[1.0]))
    data = _data("P-IP", "first-order")
    del data["axes"]["X"]["controller"]["Ti"]
    with pytest.raises(ModelError, match=r"controller\.Ti"):
        machine_from_dict(data)


def test_tf_law_with_pi_coefficients_is_the_pi_law():
    # N = 1 − a z⁻¹, D = 1 − z⁻¹ is Kp(1 + (T/Ti)/(z − 1)): the P-PI law in another realisation (tf2ss). The
    # rounding of a = 1 − T/Ti (eps) and of the two realisations is amplified by 1/(z − 1) near z = 1
    # (|z − 1| ≥ ωT ≥ 2π·2e-4: ×800) and, for the lifted position loop, by its condition (~1e3, A^Np): relative to
    # the loop's scale (the peak of |H|), not to a rolled-off point: 1e-12·max|H|
    a = 1.0 - H / TI
    pi = _loop("P-PI", "first-order")
    tf = _loop("P-TF", "first-order", numerator=[1.0, -a], denominator=[1.0, -1.0])
    omega = np.geomspace(2 * np.pi, 0.9 * np.pi / H, 200)
    for which in ("velocity-open", "velocity-closed", "position-closed", "compliance"):
        want = LoopAnalysis.of(pi).response(which, omega).response
        got = LoopAnalysis.of(tf).response(which, omega).response
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)), err_msg=which)


def test_tf_controller_against_python_control():
    """The P-TF velocity loop built by hand with python-control: c2d of the plant (mechanics + current lag),
    the law as a discrete tf, the differencing, delay, Tustin current filter, ``feedback``."""
    loop = _loop("P-TF", "first-order")
    num, den = _tf_coefficients()
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                  [-K / M1, K / M1, -C / M1, C / M1], [K / M2, -K / M2, C / M2, -C / M2]])
    mech = control.ss(A, np.array([[0], [0], [1 / M1], [0]]), np.array([[0, 1, 0, 0]]), 0)
    plant = control.c2d(control.series(control.tf([KT], [TAU, 1]), mech), H, "zoh")   # current ref → x2
    pad = max(len(num), len(den))
    law = control.ss(KP * control.tf(np.pad(num, (0, pad - len(num))), np.pad(den, (0, pad - len(den))), H))
    w = 2 * np.pi * 800.0
    lowpass = control.ss(control.c2d(control.tf([w * w], [1, 2 * 0.707 * w, w * w]), H, "tustin",
                                      prewarp_frequency=w))
    delay = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], H)           # one sample of computation delay
    differencing = control.ss([[0.0]], [[1.0]], [[-1.0 / H]], [[1.0 / H]], H)   # velocity from the position
    # state-space interconnections throughout (a tf product would expand polynomials of degree ~10)
    open_loop = differencing * plant * delay * lowpass * (1 / KT) * law
    closed = control.feedback(open_loop, 1)
    omega = np.geomspace(2 * np.pi, 0.9 * np.pi / H, 300)
    z = np.exp(1j * omega * H)
    an = LoopAnalysis.of(loop)
    L_want, T_want = (np.asarray(sys(z)).ravel() for sys in (open_loop, closed))
    L_got = an.response("velocity-open", omega).response
    T_got = an.response("velocity-closed", omega).response
    # both evaluate state spaces of ~10 states after a c2d by expm; sicomat's plant goes through its modal form,
    # accurate relative to the largest modal term (the free rigid body: a double pole at z = 1), i.e. to the
    # scale of the response, not at a point where the terms cancel (the ZOH plant's near-zero at 2.25 kHz, 1e-11
    # of its peak). So |ΔL| ≤ 1e-9·max|L| (the modal form's ~1e-13 amplified by the ~1e3 condition of the
    # rigid block, with a margin), and the closed loop T = L/(1 + L) carries it as ΔL/(1 + L)²
    scale = 1e-9 * np.max(np.abs(L_want))
    assert np.all(np.abs(L_got - L_want) <= scale)
    assert np.all(np.abs(T_got - T_want) <= 2 * scale / np.abs(1 + L_want) ** 2)


def test_linear_law_error_form_equal_for_pi_and_ip():
    pi, ip = _loop("P-PI", "first-order"), _loop("P-IP", "first-order")
    a, b = linear_law(pi, KP, TI, error_form=True), linear_law(ip, KP, TI, error_form=True)
    for m in "ABCD":
        np.testing.assert_array_equal(getattr(a, m), getattr(b, m))   # the same numbers, exactly


# --------------------------------------------------------------------------- the CLI with the new type
EXAMPLE = str(Path(__file__).resolve().parents[1] / "examples" / "rigid_1m_tf.toml")


@pytest.mark.parametrize("command", [["bode", "--loop", "velocity-open", "--points", "50"], ["margins"], ["step"],
                                     ["simulate", "--duration", "0.1"]])
def test_cli_commands_run_a_tf_controller(command, tmp_path):
    args = [command[0], EXAMPLE, *command[1:], "--json"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output


def test_cli_tune_says_why_a_tf_controller_is_not_tuned():
    for method in ("frequency", "time"):
        result = CliRunner().invoke(app, ["tune", EXAMPLE, "--method", method])
        assert result.exit_code == 2
        assert "axes.X.controller.type" in result.output and "nothing to tune" in result.output
        assert "Traceback" not in result.output
