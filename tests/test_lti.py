"""The one frequency-response evaluator (sicomat.lti.response) and the one rigid/flexible split
(sicomat.lti.spectral): against closed forms, python-control and an exact rational oracle, every
strategy on the same system within the documented accuracy contract."""

from __future__ import annotations

from pathlib import Path

import control
import numpy as np
import pytest

import sicomat
from sicomat.frequency.loops import LoopAnalysis, default_omega
from sicomat.lti.response import DIRECT_MAX_STATES, Evaluator, transfer_at, zoh_matrices
from sicomat.lti.spectral import split_state_space
from sicomat.servo.loop import build_servo_loop

from accuracy import EPS, diagonal_accuracy, exact_transfer, transfer_accuracy

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def chain(n: int, m: float = 1.0, k: float = 1e4, c: float = 2.0, grounded: bool = False):
    """An n-mass chain (springs k, dampers c between neighbours; a spring k and damper c to the frame
    on the first mass when grounded): force on the first mass, position of the last."""
    K = np.zeros((n, n))
    for i in range(n - 1):
        K[i:i + 2, i:i + 2] += np.array([[1, -1], [-1, 1]]) * k
    if grounded:
        K[0, 0] += k
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K / m, -(c / k) * K / m]])
    B = np.zeros((2 * n, 1))
    B[n, 0] = 1.0 / m
    C = np.zeros((1, 2 * n))
    C[0, n - 1] = 1.0
    return A, B, C


def _balanced(A, B, C):
    import scipy.linalg

    s = scipy.linalg.matrix_balance(A, permute=False, separate=True)[1][0]
    return (A * s[None, :]) / s[:, None], B / s[:, None], C * s[None, :]


# ------------------------------------------------------------------------------ closed forms
def test_rigid_body_closed_form():
    """1/(m s²): the direct and the split strategies (diagonal is impossible: a Jordan block at 0)."""
    m = 2.5
    A, B, C = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1 / m]]), np.array([[1.0, 0.0]])
    w = np.logspace(-1, 4, 50)
    exact = -1.0 / (m * w ** 2)
    for method in ("direct", "split"):
        H = transfer_at(A, B, C, points=1j * w, method=method)[0, 0]
        # two roundings per operation of a 2×2 solve and of the closed form: 10 eps is generous
        assert np.max(np.abs(H - exact) / np.abs(exact)) <= 10 * EPS, method
    assert Evaluator(A, B, C).method == "direct"


def test_two_mass_free_chain_closed_form_every_strategy():
    """Force on mass 1 to the position of mass 2 of a free 2-mass chain with a spring k and a damper c:
    ``(c s + k) / (s² (m₁ m₂ s² + (m₁ + m₂)(c s + k)))`` (one rigid-body mode, one flexible mode)."""
    m1, m2, k, c = 3.0, 5.0, 2e6, 40.0
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-k / m1, k / m1, -c / m1, c / m1], [k / m2, -k / m2, c / m2, -c / m2]])
    B = np.array([[0.0], [0.0], [1 / m1], [0.0]])
    C = np.array([[0.0, 1.0, 0.0, 0.0]])
    w = np.logspace(0, 5, 80)
    s = 1j * w
    exact = (c * s + k) / (s ** 2 * (m1 * m2 * s ** 2 + (m1 + m2) * (c * s + k)))
    for method in ("direct", "split"):
        H = transfer_at(A, B, C, points=s, method=method)[0, 0]
        # the state-space contract (its bound is for the LU on the balanced matrix) plus a few eps for
        # the rounding of the closed form; the split's Sylvester decoupling adds eps·‖T‖/sep, with
        # sep ≈ |λ_flex| ≈ ‖T‖ here, i.e. a few eps more: factor 10 over the first-order LU bound
        bound = 10 * transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), s) + 10 * EPS
        assert np.all(np.abs(H - exact) / np.abs(exact) <= bound), method


def test_sampled_double_integrator_closed_form():
    """The exact ZOH of 1/(m s²) at z = e^{jωT}: ``T² (z + 1) / (2 m (z − 1)²)``."""
    m, T = 4.0, 1e-3
    A, B, C = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1 / m]]), np.array([[1.0, 0.0]])
    Phi, Gamma = zoh_matrices(A, B, T)
    w = np.logspace(0, np.log10(0.99 * np.pi / T), 60)
    z = np.exp(1j * w * T)
    exact = T ** 2 * (z + 1) / (2 * m * (z - 1) ** 2)
    H = transfer_at(Phi, Gamma, C, points=z)[0, 0]
    # Φ, Γ are exact to a few eps (expm of a nilpotent matrix: its series terminates); the 2×2 solve
    # near the double pole at z = 1 amplifies them by κ(zI − Φ) ≈ 1/|z − 1|² relative to |H| ∝ 1/|z − 1|²:
    # the LU contract, plus 10 eps for the closed form's own rounding
    bound = 10 * transfer_accuracy(Phi, Gamma, C, np.zeros((1, 1)), z) + 10 * EPS
    assert np.all(np.abs(H - exact) / np.abs(exact) <= bound)


# ------------------------------------------------------------------------------ python-control
def test_direct_against_python_control_continuous_and_sampled():
    A, B, C = chain(6, grounded=True)
    w = np.logspace(-1, 3, 200)
    ours = transfer_at(A, B, C, points=1j * w)[0, 0]
    peer = np.asarray(control.ss(A, B, C, 0).frequency_response(w).complex).ravel()
    # both are LU solves per point (python-control's without slycot): each within the LU contract, ours
    # on the balanced matrix, the peer's on the raw one
    bound = transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), 1j * w) \
        + transfer_accuracy(A, B, C, np.zeros((1, 1)), 1j * w)
    assert np.all(np.abs(ours - peer) / np.abs(peer) <= bound)
    T = 1e-3
    Phi, Gamma = zoh_matrices(A, B, T)
    w = w[w < np.pi / T]
    z = np.exp(1j * w * T)
    ours = transfer_at(Phi, Gamma, C, points=z)[0, 0]
    peer = np.asarray(control.ss(Phi, Gamma, C, 0, T).frequency_response(w).complex).ravel()
    bound = transfer_accuracy(*_balanced(Phi, Gamma, C), np.zeros((1, 1)), z) \
        + transfer_accuracy(Phi, Gamma, C, np.zeros((1, 1)), z)
    assert np.all(np.abs(ours - peer) / np.abs(peer) <= bound)


# ------------------------------------------------------------------------------ strategies agree
def test_direct_and_diagonal_agree_within_the_contract():
    """A grounded 40-mass chain (80 states > DIRECT_MAX_STATES: "auto" is diagonal)."""
    A, B, C = chain(40, grounded=True)
    assert A.shape[0] > DIRECT_MAX_STATES
    w = np.logspace(0, 3, 120)
    s = 1j * w
    diag = Evaluator(A, B, C)
    assert diag.method == "diagonal"
    Hd = diag(s)[0, 0]
    Hl = transfer_at(A, B, C, points=s, method="direct")[0, 0]
    # the difference of two results is within the sum of their contracts (module docstring)
    bound = diagonal_accuracy(A, B, C, s) + transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), s)
    rel = np.abs(Hd - Hl) / np.abs(Hl)
    assert np.all(rel <= bound)


def test_free_chain_rigid_modes_split_and_direct_agree():
    """A free 40-mass chain (a double pole at 0): every strategy, at points away from 0."""
    A, B, C = chain(40)
    s = 1j * np.logspace(0, 3, 60)
    Hl = transfer_at(A, B, C, points=s, method="direct")[0, 0]
    Hs = transfer_at(A, B, C, points=s, method="split")[0, 0]
    split = split_state_space(A, B, C, np.zeros((1, 1)))
    assert split.rigid.n == 2 and np.all(split.rigid.poles() == 0)
    # the split's rigid part is exact (nilpotent 2×2, a few eps); its flexible part is diagonalised,
    # within the diagonal contract of that block; the direct result within its LU contract
    f = split.flexible
    bound = diagonal_accuracy(f.A, f.B, f.C, s) * np.abs(transfer_at(f.A, f.B, f.C, points=s, method="direct")[0, 0]) \
        / np.abs(Hl) + transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), s) + 10 * EPS
    assert np.all(np.abs(Hs - Hl) / np.abs(Hl) <= bound)


def test_near_defective_matrix_falls_back_to_the_split():
    """Two poles 1e-13 apart (κ₂(V) ≈ 1e13): "auto" leaves the diagonal form for the split, whose
    flexible block goes to triangular solves on its Schur form; it agrees with the direct solves."""
    rng = np.random.default_rng(7)
    A0, B0, C0 = chain(34, grounded=True)
    J = np.array([[-5.0, 1.0], [0.0, -5.0 - 1e-13]])
    A = np.block([[A0, np.zeros((68, 2))], [np.zeros((2, 68)), J]])
    B = np.vstack([B0, [[1.0], [1.0]]])
    C = np.hstack([C0, rng.standard_normal((1, 2))])
    ev = Evaluator(A, B, C)
    assert ev.method == "split" and ev._split._schur is not None
    s = 1j * np.logspace(0, 3, 50)
    Hl = transfer_at(A, B, C, points=s, method="direct")[0, 0]
    Hs = ev(s)[0, 0]
    # both are backward-stable solves (LU; triangular on a unitary Schur form, n eps ‖T‖ each) of the
    # same balanced pencil, the Sylvester decoupling of the rigid-free split adds eps·‖T‖/sep with
    # sep ≥ min distance between the blocks' poles (~1e-2 here relative to ‖T‖ ≈ 2e4): 2 LU bounds·1e2
    bound = 2e2 * transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), s)
    assert np.all(np.abs(Hs - Hl) / np.abs(Hl) <= bound)


def test_exactly_defective_matrix():
    """A Jordan block ``[[−1, 1], [0, −1]]`` inside 70 states: the eigenvector matrix is singular; the
    split path gives ``1/(s + 1)²`` from the block exactly (to a few eps), plus the rest."""
    A0, B0, C0 = chain(35, grounded=True)
    A = np.block([[A0, np.zeros((70, 2))], [np.zeros((2, 70)), np.array([[-1.0, 1.0], [0.0, -1.0]])]])
    B = np.vstack([0 * B0, [[0.0], [1.0]]])
    C = np.hstack([0 * C0, [[1.0, 0.0]]])
    s = 1j * np.logspace(-1, 2, 40)
    ev = Evaluator(A, B, C)
    assert ev.method == "split"
    # the block decoupled from the rest (B, C see only it): the Sylvester coupling is zero, the
    # triangular solve on the Schur form of a 2×2 is exact to a few eps relative: 10 eps
    assert np.max(np.abs(ev(s)[0, 0] * (s + 1) ** 2 - 1)) <= 10 * EPS * 10


# ------------------------------------------------------------------------------ the CLI's loops
@pytest.mark.parametrize("example", ["ballscrew_analog.toml", "ballscrew_3m2s.toml"])
def test_plant_response_against_exact_oracle(example):
    """`bode --loop plant`: the mechanics (a rigid-body mode, stiff spring) at s = jω. The old diagonal
    form lost digits where the response rolls off (3e-4 relative on ballscrew_analog, 5e-7 on the
    3m2s); the direct strategy meets its LU contract against an exact rational solve."""
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / example))
    ctrl = loop.controller
    plant = loop.mechanics.state_space().select(inputs=[loop.actuator], outputs=[ctrl.position_sensor])
    w = default_omega(loop, "plant")
    w = w[np.linspace(0, w.size - 1, 25).round().astype(int)]
    frf = LoopAnalysis.of(loop).response("plant", w)
    A, B, C = (np.asarray(m, dtype=float) for m in (plant.A, plant.B, plant.C))
    exact = exact_transfer(A, B, C, 1j * w)
    # the oracle is exact to eps; ours within the LU contract on the balanced matrix
    bound = transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), 1j * w) + EPS
    assert np.all(np.abs(frf.response - exact) / np.abs(exact) <= bound)


def test_sampled_plant_against_exact_oracle():
    """The 5M4S's ZOH plant at z = e^{jωTv} (velocity-open's plant factor)."""
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))
    an = LoopAnalysis.of(loop)
    w = default_omega(loop, "velocity-open")
    w = w[np.linspace(0, w.size - 1, 25).round().astype(int)]
    z = np.exp(1j * w * loop.controller.velocity_period)
    A, B, C = an.Phi, an.Gamma[:, :1], an.c_vel[None, :]
    exact = exact_transfer(A, B, C, z)
    H = transfer_at(A, B, C, points=z)[0, 0]
    bound = transfer_accuracy(*_balanced(A, B, C), np.zeros((1, 1)), z) + EPS
    assert np.all(np.abs(H - exact) / np.abs(exact) <= bound)


def test_static_gain_and_unknown_method():
    ev = Evaluator(np.zeros((0, 0)), None, None, [[2.0]])
    assert ev([1j, 2j]).tolist() == [[[2.0, 2.0]]]
    with pytest.raises(ValueError, match="unknown method"):
        Evaluator([[0.0]], [[1.0]], [[1.0]], method="fast")


@pytest.mark.parametrize("example", ["paper_5m4s.toml", "ballscrew_3m2s.toml"])
def test_sampled_plant_diagonal_path_against_exact_oracle(example):
    """A small discrete system (``discrete=True``, as the sampled loops ask) takes the diagonal form:
    against an exact rational solve it meets the diagonal contract (``tests/accuracy.diagonal_accuracy``:
    residues to ``n·eps·κ₂(V)``, poles to their eigenvalue accuracy; factor 10 for the second-order terms
    the first-order bound leaves out), and in absolute terms stays below 1e-9 relative on the whole
    Nyquist band (the module docstring's argument: ``|z − λ|`` bounded away from 0, no unbounded
    roll-off; an accuracy far inside what margins and Bode plots read)."""
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / example))
    an = LoopAnalysis.of(loop)
    w = default_omega(loop, "velocity-open")
    w = w[np.linspace(0, w.size - 1, 25).round().astype(int)]
    z = np.exp(1j * w * loop.controller.velocity_period)
    A, B, C = an.Phi, an.Gamma[:, :1], an.c_vel[None, :]
    ev = Evaluator(A, B, C, discrete=True)
    assert ev.method == "diagonal"
    H = ev(z)[0, 0]
    exact = exact_transfer(A, B, C, z)
    err = np.abs(H - exact) / np.abs(exact)
    assert np.all(err <= 10 * diagonal_accuracy(A, B, C, z) + EPS)
    assert err.max() <= 1e-9


def test_small_discrete_system_with_parallel_eigenvectors_takes_the_direct_path():
    """The diagonal form of a small discrete system needs a usable eigenbasis: a Jordan block at z = 1
    (a sampled double integrator) goes to LU, which meets its own contract against the closed form."""
    T = 1e-3
    Phi, Gamma = zoh_matrices(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), T)
    ev = Evaluator(Phi, Gamma, [[1.0, 0.0]], discrete=True)
    assert ev.method == "direct"
    z = np.exp(1j * np.linspace(0.1, 3.0, 20))
    exact = T ** 2 * (z + 1) / (2 * (z - 1) ** 2)          # ZOH of 1/s²
    # a 2×2 LU and a closed form of a few operations near a double pole at 1: κ(zI − Φ) ≤ 4/|z − 1|²
    bound = 100 * EPS * 4 / np.abs(z - 1) ** 2
    assert np.all(np.abs(ev(z)[0, 0] - exact) / np.abs(exact) <= bound)
