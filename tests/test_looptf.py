"""Loop frequency responses against python-control built independently, and the lifted position loop."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
import pytest

import sicomat
from sicomat.servo.loop import build_servo_loop, servo_plant
from sicomat.frequency.loops import LoopAnalysis, default_omega

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def paper_loop():
    return build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))


@pytest.fixture(scope="module")
def chain_loop():
    """A 2-mass axis with a moderate stiffness spread, where python-control's dense FRF is accurate
    (on the 5M4S, 1e12 N/m beside 8 g makes its z-domain solves noisy near z = 1)."""
    return build_servo_loop(sicomat.machine_from_dict({"axes": {"X": {
        "mechanics": {"type": "chain", "masses": [10.0, 30.0], "stiffnesses": [2e6], "dampings": [500.0]},
        "drive": {"force_constant": 50.0, "time_constant": 2e-4},
        "controller": {"position_sensor": "last", "velocity_sensor": "last", "Kv": 12.0, "Kp_normalized": 50.0,
                       "Ti": 0.02, "position_period": 2e-4, "velocity_period": 2e-4, "velocity_delay": 1,
                       "position_delay": 1}}}}))


def _at(sys, omega):
    return np.asarray(sys.frequency_response(omega).complex).ravel()


def _control_velocity_open(loop, omega):
    """L_v = C(z) z^-d / Kt · c2d(plant) · (1 - z^-1)/T / g_v, each factor a python-control object
    (the plant kept as a state space: a transfer-function product of it is ill-conditioned)."""
    ctrl = loop.controller
    T = ctrl.velocity_period
    plant = servo_plant(loop)
    row = plant.outputs.index(f"sensor.{ctrl.velocity_sensor}")
    disc = control.c2d(control.ss(plant.A, plant.B[:, :1], plant.C[row:row + 1], 0), T, "zoh")
    z = control.tf([1, 0], [1], T)
    pi = loop.Kp + loop.Kp * T / loop.Ti / (z - 1)
    diff = (1 - 1 / z) / T
    delay = 1 / z ** ctrl.velocity_delay
    return _at(pi, omega) * _at(delay, omega) * _at(disc, omega) * _at(diff, omega) / loop.drive.kt \
        / loop.velocity_gain


def test_velocity_open_loop_equals_python_control_product(chain_loop):
    omega = default_omega(chain_loop, "velocity-open", 400)
    ours = LoopAnalysis.of(chain_loop).response("velocity-open", omega).response
    peer = _control_velocity_open(chain_loop, omega)
    # agreement relative to the peak: the rigid mode's double pole at z = 1 limits both evaluations
    # accuracy.transfer_accuracy: each side's value is within n·κ(zI − Φ)·eps of the ZOH plant's; near z = 1 the
    # rigid double pole makes κ ~ 1/(ωT)² ≈ 1e6 at the lowest frequency, i.e. ~1e-10 of the peak: 1e-9
    np.testing.assert_allclose(ours, peer, rtol=0, atol=1e-9 * np.max(np.abs(peer)))


def test_velocity_closed_loop_is_l_over_one_plus_l(paper_loop):
    an = LoopAnalysis.of(paper_loop)
    omega = default_omega(paper_loop, "velocity-closed", 300)
    L = an.response("velocity-open", omega).response
    T = an.response("velocity-closed", omega).response
    # the closed loop from its own realisation against L/(1 + L): where |1 + L| is small (near the crossover, |1
    # + L| >= the modulus margin ~0.5) the division amplifies L's rounding by 1/|1 + L| <= 2, and the
    # realisations differ by κ·eps ≈ 1e-10 (above): 1e-9
    np.testing.assert_allclose(T, L / (1 + L), rtol=1e-9)


def test_position_closed_loop_single_rate_matches_state_space_peer(chain_loop):
    """With Tp = Tv the position loop is an ordinary sampled loop: build it with python-control."""
    loop = chain_loop
    ctrl = loop.controller
    T = ctrl.velocity_period
    z = control.tf([1, 0], [1], T)
    plant = servo_plant(loop)
    row_v = plant.outputs.index(f"sensor.{ctrl.velocity_sensor}")
    row_p = plant.outputs.index(f"sensor.{ctrl.position_sensor}")
    cont = control.ss(plant.A, plant.B[:, :1], plant.C[[row_p, row_v]], 0)
    disc = control.c2d(cont, T, "zoh")
    pos, vel = disc[0, 0], disc[1, 0]
    pi = loop.Kp + loop.Kp * T / loop.Ti / (z - 1)
    act = pi / z ** ctrl.velocity_delay / loop.drive.kt
    omega = default_omega(loop, "position-closed", 300)
    zz = np.exp(1j * omega * T)
    A_ = _at(act, omega)
    P_ = _at(pos, omega) / loop.position_gain
    V_ = _at(vel, omega) * (1 - 1 / zz) / T / loop.velocity_gain
    g = A_ * P_ / (1 + A_ * V_)
    L = loop.Kv * zz ** -ctrl.position_delay * g
    expected = L / (1 + L)
    ours = LoopAnalysis.of(loop).response("position-closed", omega).response
    # the lifted multi-rate loop against a product of python-control factors: the same κ·eps per factor (above)
    # through three products and two closed-loop divisions: 1e-8 of the peak
    np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-8 * np.max(np.abs(expected)))


def test_lifted_position_loop_has_its_own_nyquist(paper_loop):
    frf = LoopAnalysis.of(paper_loop).response("position-open")
    assert frf.sample_period == paper_loop.controller.position_period
    assert frf.omega[-1] < np.pi / paper_loop.controller.position_period
    assert frf.open_loop


def test_compliance_tends_to_the_open_mechanics_above_the_bandwidth(paper_loop):
    """Far above the loop bandwidth the controller no longer acts: the closed-loop compliance at the
    tool equals the mechanics' own compliance there (checked against the plain mechanics FRF)."""
    an = LoopAnalysis.of(paper_loop)
    omega = np.array([2 * np.pi * 3000.0])
    closed = an.response("compliance", omega).response
    mech = paper_loop.mechanics.state_space(forces_on=["load"], dof_outputs=True)
    sub = mech.select(inputs=["load.force"], outputs=["load.x"])
    open_ = np.asarray(sub.to_control().frequency_response(omega).complex).ravel()
    # a physical approximation: at 3 kHz, 40 times the loop's bandwidth, the controller's residual action on the
    # compliance is O(ω_bw/ω) ≈ 2.5 %: 5 %
    np.testing.assert_allclose(closed, open_, rtol=0.05)
    low = an.response("compliance", np.array([2 * np.pi * 0.5])).response
    # integral action: the static compliance of the closed loop is far below the mechanics' own
    assert abs(low[0]) < 1e-3 * abs(np.asarray(sub.to_control().frequency_response([2 * np.pi * 0.5]).complex).ravel()[0]) \
        or abs(low[0]) < 1e-8
