"""sicomat.mechanics.statespace.mechanics_plant: the state space of the paper's eqs. (11)-(12), z = (q, qdot)."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
import pytest
from accuracy import eigenvalue_accuracy
from numpy.testing import assert_allclose, assert_array_equal
from scipy.optimize import linear_sum_assignment

from sicomat import ChainSpec, ModelError, build_mechanics, load_model, mechanics_plant, modal_analysis

EXAMPLES_DIR = Path(__file__).resolve().parents[1] / "examples"
EXAMPLES = ["paper_5m4s", "ballscrew_3m2s", "paper_2m1s", "rigid_1m"]


def _mech(name):
    return build_mechanics(load_model(EXAMPLES_DIR / f"{name}.toml").axis().mechanics)


@pytest.mark.parametrize("name", EXAMPLES)
def test_A_and_B_follow_eq_12(name):
    mech = _mech(name)
    n = mech.n
    M_inv = np.linalg.inv(mech.mass)
    F = np.column_stack([a.vector for a in mech.actuators])
    plant = mechanics_plant(mech)
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-M_inv @ mech.stiffness, -M_inv @ mech.damping]])
    B = np.vstack([np.zeros((n, F.shape[1])), M_inv @ F])
    # the same products M⁻¹K, M⁻¹D in another order: a few roundings each (1e-13; 1e-14/1e-15 for a single
    # quotient)
    assert_allclose(plant.A, A, rtol=1e-13, atol=0)
    assert_allclose(plant.B, B, rtol=1e-13, atol=0)
    assert_array_equal(plant.D, np.zeros((len(plant.outputs), len(plant.inputs))))
    # state order z = (q, qdot): positions of all bodies, then velocities
    assert plant.states == tuple(d.position for d in mech.dofs) + tuple(d.velocity for d in mech.dofs)
    assert plant.inputs == tuple(a.name for a in mech.actuators)
    assert plant.outputs == tuple(s.name for s in mech.sensors)


def test_sensor_rows_read_positions_and_velocities():
    mech = _mech("paper_5m4s")
    plant = mechanics_plant(mech)
    n = mech.n
    rel = np.zeros(n)
    rel[mech.index("scale_head")], rel[mech.index("structure")] = 1.0, -1.0
    C = dict(zip(plant.outputs, plant.C))
    assert_array_equal(C["scale"], np.concatenate([rel, np.zeros(n)]))
    assert_array_equal(C["scale_velocity"], np.concatenate([np.zeros(n), rel]))


def test_paper_2m1s_state_space_by_hand():
    # eq. (12) with M, mu, K of eqs. (5)-(9) for x = (theta_m, x_M), F = (Gamma_mot, 0)
    mech = _mech("paper_2m1s")
    plant = mechanics_plant(mech)
    (J, M), K, mu = np.diag(mech.mass), mech.stiffness, mech.damping
    expected_A = np.array([
        [0, 0, 1, 0],
        [0, 0, 0, 1],
        [-K[0, 0] / J, -K[0, 1] / J, -mu[0, 0] / J, -mu[0, 1] / J],
        [-K[1, 0] / M, -K[1, 1] / M, -mu[1, 0] / M, -mu[1, 1] / M],
    ])
    # single quotients K/J, mu/M: one or two roundings
    assert_allclose(plant.A, expected_A, rtol=1e-14)
    assert_allclose(plant.B.ravel(), [0, 0, 1 / J, 0], rtol=1e-14)
    assert plant.states == ("motor.theta", "load.x", "motor.omega", "load.v")


def test_one_mass_plant_is_a_double_integrator():
    m = 2.5
    plant = mechanics_plant(build_mechanics(ChainSpec(type="chain", masses=[m])))
    assert_array_equal(plant.A, [[0.0, 1.0], [0.0, 0.0]])
    assert_allclose(plant.B.ravel(), [0.0, 1.0 / m], rtol=1e-15)             # one quotient
    sys = plant.to_control()[0, 0]  # motor -> first
    # G(s) = 1/(m s^2): G(j w) = -1/(m w^2), and a double pole at 0
    for w in (0.1, 1.0, 30.0):
        # a 2-state solve with κ(jωI − A) <= 1/ω² + ... ≈ 1e2 at ω = 0.1: κ·eps ≈ 2e-14 (1e-12); the defective
        # double pole at 0 of [[0, 1], [0, 0]] is computed exactly here (a triangular matrix), 1e-12 slack
        assert_allclose(complex(sys(1j * w)), -1.0 / (m * w * w), rtol=1e-12)
    assert_allclose(control.poles(sys), [0.0, 0.0], atol=1e-12)


def test_external_loads_and_state_outputs():
    mech = _mech("ballscrew_3m2s")
    plant = mechanics_plant(mech, forces_on=["table", "screw"], dof_outputs=True)
    assert plant.inputs == ("motor", "table.force", "screw.torque")
    n = mech.n
    col = plant.B[:, plant.inputs.index("table.force")]
    expected = np.zeros(2 * n)
    expected[n + mech.index("table")] = 1.0 / mech.mass[mech.index("table"), mech.index("table")]
    # one quotient: exact to an ulp
    assert_allclose(col, expected, rtol=1e-15)
    assert plant.outputs[-2 * n:] == plant.states
    assert_array_equal(plant.C[-2 * n:], np.eye(2 * n))
    with pytest.raises(ModelError, match="nobody"):
        mechanics_plant(mech, forces_on=["nobody"])


@pytest.mark.parametrize("name", EXAMPLES)
def test_to_control_keeps_names_and_matrices(name):
    plant = mechanics_plant(_mech(name))
    sys = plant.to_control()
    assert isinstance(sys, control.StateSpace)
    assert tuple(sys.state_labels) == plant.states
    assert tuple(sys.input_labels) == plant.inputs
    assert tuple(sys.output_labels) == plant.outputs
    for ours, theirs in ((plant.A, sys.A), (plant.B, sys.B), (plant.C, sys.C), (plant.D, sys.D)):
        assert_array_equal(np.asarray(theirs), ours)


def _match(a, b):
    """Pair the complex numbers of ``a`` and ``b`` (same length) by least total distance."""
    cost = np.abs(np.asarray(a)[:, None] - np.asarray(b)[None, :])
    rows, cols = linear_sum_assignment(cost)
    return np.asarray(a)[rows], np.asarray(b)[cols]


@pytest.mark.parametrize("name", EXAMPLES)
def test_poles_equal_python_control(name):
    plant = mechanics_plant(_mech(name))
    ours, theirs = _match(plant.poles(), control.poles(plant.to_control()))
    # two eigen-solver calls on the same matrix (with and without eigenvectors, another LAPACK path):
    # each pole within n·eps·‖A‖·κ(λ) (accuracy.eigenvalue_accuracy); the rigid double pole is
    # defective, so its κ and its bound are large, as its computed value (~sqrt(eps·‖A‖)) is
    assert np.all(np.abs(ours - theirs) <= 2 * eigenvalue_accuracy(plant.A, theirs))


@pytest.mark.parametrize("name", ["paper_5m4s", "ballscrew_3m2s", "paper_2m1s"])
def test_modal_frequencies_and_damping_match_control_damp(name):
    mech = _mech(name)
    wn, zeta, poles = control.damp(mechanics_plant(mech).to_control(), doprint=False)
    upper = poles.imag > 0                        # one entry per oscillating pole pair
    ref = sorted(zip(wn[upper], zeta[upper], poles[upper].imag))
    flexible = sorted((m for m in modal_analysis(mech).modes if not m.rigid),
                      key=lambda m: m.frequency_hz)
    assert len(flexible) == len(ref)
    # each side's pole is within n·eps·‖A‖·κ(λ) of the true one (accuracy.eigenvalue_accuracy: ~1e-5
    # relative for the 5M4S's 80 Hz mode beside its 1e12 N/m spring); |λ|, Im λ inherit that error,
    # and ζ = -Re λ/|λ| inherits it divided by |λ| (an absolute error in ζ, not a relative one)
    A = mechanics_plant(mech).A
    for mode, (w, z, wd) in zip(flexible, ref):
        err = 2 * eigenvalue_accuracy(A, np.array([-z * w + 1j * wd]))[0]
        assert abs(2 * np.pi * mode.frequency_hz - w) <= err
        assert abs(mode.damping_ratio - z) <= err / w
        assert abs(2 * np.pi * mode.damped_frequency_hz - wd) <= err


def test_select_sub_plant():
    plant = mechanics_plant(_mech("paper_5m4s"))
    sub = plant.select(outputs=["scale_velocity"])
    assert sub.outputs == ("scale_velocity",)
    assert_array_equal(sub.C, plant.C[[1]])
    with pytest.raises(ModelError):
        plant.select(inputs=["nope"])
