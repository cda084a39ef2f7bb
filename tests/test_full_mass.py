"""A full (non-diagonal) mass matrix through the one (M, D, K) assembler, the modal analysis and the loop.

Oracles: closed-form eigenvalues, ``scipy.linalg.eigh(K, M)``, a direct ``np.linalg.solve(M, ...)`` and
the second-order resolvent ``(K + jωD − ω²M)⁻¹``; and invariance under a change of coordinates
``q = T p``: a mechanics and its congruent ``(TᵀMT, TᵀDT, TᵀKT)`` with every actuator, sensor and link
vector mapped by ``Tᵀ`` have the same frequencies, damping ratios, participations, transfers and
simulated responses between named signals — while the congruent one has a full M.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

import sicomat
from sicomat.description import ChainSpec
from sicomat.errors import ModelError
from sicomat.mechanics import (Link, Load, MassFactor, Measurement, Mechanics, build_mechanics, modal_analysis,
                               second_order_input, second_order_state_space)
from sicomat.motion.setpoints import step_profile
from sicomat.servo.loop import SetpointTable, build_servo_loop, servo_plant, servo_program
from sicomat.simulation import simulate

EPS = np.finfo(float).eps
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _T(n: int) -> np.ndarray:
    """A well-conditioned, non-orthogonal change of coordinates (κ(T) < 4 for n ≤ 6)."""
    return np.eye(n) + 0.4 * np.triu(np.ones((n, n)), 1) - 0.2 * np.tril(np.ones((n, n)), -1)


def _congruent(mech: Mechanics, T: np.ndarray) -> Mechanics:
    """The same mechanics in the coordinates ``q = T p`` (forces and stretches mapped by Tᵀ)."""
    Tt = T.T
    return Mechanics.from_matrices(
        mech.dofs, Tt @ mech.mass @ T, Tt @ mech.damping @ T, Tt @ mech.stiffness @ T,
        actuators=[Load(a.name, Tt @ a.vector, a.kind) for a in mech.actuators],
        sensors=[Measurement(s.name, Tt @ s.vector, s.kind, s.unit, s.step) for s in mech.sensors],
        couplings=[replace(c, g=Tt @ c.g) for c in mech.couplings],
        frictions=[replace(f, g=Tt @ f.g) for f in mech.frictions])


# ------------------------------------------------------------------ the assembler against a direct solve
def test_state_space_with_full_mass_equals_direct_solve():
    rng = np.random.default_rng(11)
    n, m = 6, 2
    X = rng.standard_normal((n, n))
    M = X @ X.T + n * np.eye(n)
    Y = rng.standard_normal((n, n))
    K, D = Y @ Y.T, 0.01 * (Y @ Y.T + np.eye(n))
    F = rng.standard_normal((n, m))
    A, B = second_order_state_space(M, D, K, F)
    # both are backward-stable solves with M: they agree to about κ(M)·ε relative (first-order bound),
    # times a small factor n for the accumulated rounding
    bound = 10 * n * np.linalg.cond(M) * EPS
    np.testing.assert_array_equal(A[:n, :n], 0.0)
    np.testing.assert_array_equal(A[:n, n:], np.eye(n))
    np.testing.assert_array_equal(B[:n], 0.0)
    for block, direct in ((-A[n:, :n], np.linalg.solve(M, K)), (-A[n:, n:], np.linalg.solve(M, D)),
                          (B[n:], np.linalg.solve(M, F))):
        assert np.max(np.abs(block - direct)) <= bound * np.max(np.abs(direct))
    np.testing.assert_allclose(second_order_input(M, F)[n:], B[n:], rtol=0, atol=bound * np.max(np.abs(B)))


def test_mechanics_plant_with_full_mass_equals_the_second_order_resolvent():
    """C (jω − A)⁻¹ B of the plant against ``(K + jωD − ω²M)⁻¹ F`` computed from the matrices."""
    chain = build_mechanics(ChainSpec(type="chain", masses=[2.0, 1.0, 3.0], stiffnesses=[4e4, 1e4],
                                      dampings=[20.0, 5.0]))
    mech = _congruent(chain, _T(3))
    assert not mech.lumped
    plant = mech.state_space()
    Fu = np.column_stack([a.vector for a in mech.actuators])
    Cq = np.vstack([s.vector for s in mech.sensors])        # the chain's sensors read positions
    assert all(s.kind == "position" for s in mech.sensors)
    for w in (3.0, 70.0, 400.0):
        Z = mech.stiffness + 1j * w * mech.damping - w ** 2 * mech.mass
        oracle = Cq @ np.linalg.solve(Z, Fu)
        got = plant.C @ np.linalg.solve(1j * w * np.eye(6) - plant.A, plant.B)
        # both solve a system of condition κ; relative agreement ~ κ·ε (×100 for the two formulations)
        kappa = max(np.linalg.cond(Z), np.linalg.cond(1j * w * np.eye(6) - plant.A))
        assert np.max(np.abs(got - oracle)) <= 100 * kappa * EPS * np.max(np.abs(oracle))


# ------------------------------------------------------------------ modal analysis with a full M
def test_genuinely_coupled_two_dof_system_against_closed_form():
    """M = [[m1, μ], [μ, m2]] (a body coupled through its inertia), K grounded: det(K − λM) = 0."""
    m1, m2, mu, k1, k2 = 3.0, 2.0, 1.2, 5e4, 2e4
    M = np.array([[m1, mu], [mu, m2]])
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    a = m1 * m2 - mu ** 2
    b = -(K[0, 0] * m2 + K[1, 1] * m1 - 2 * K[0, 1] * mu)
    c = np.linalg.det(K)
    lam = np.sort(np.roots([a, b, c]).real)
    oracle_hz = np.sqrt(lam) / (2 * np.pi)
    np.testing.assert_allclose(oracle_hz, np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)) / (2 * np.pi),
                               rtol=1e-12)
    mech = Mechanics.from_matrices(["a", "b"], M, 1e-3 * K, K,
                                   actuators=[Load("motor", np.array([1.0, 0.0]), "translational")],
                                   sensors=[Measurement("scale", np.array([0.0, 1.0]), "position", "translational")])
    res = modal_analysis(mech)
    assert res.n_rigid == 0
    # SVD accuracy ε·ω_max·κ(L) on ω (docs of _undamped), κ(M) = 4.6 here: 1e-12 relative is 100× that
    np.testing.assert_allclose(res.undamped_hz, oracle_hz, rtol=1e-12)
    # light proportional damping D = βK: ζ = β ω / 2 exactly, the pole frequency equals ω
    for mode in res.modes:
        assert mode.frequency_hz == pytest.approx(mode.undamped_hz, rel=1e-10)
        assert mode.damping_ratio == pytest.approx(1e-3 * 2 * np.pi * mode.undamped_hz / 2, rel=1e-9)
    # the mode shapes solve K φ = ω² M φ (residual relative to ‖K φ‖ at the level of the SVD's accuracy)
    for mode in res.modes:
        phi = np.array([mode.shape[d] for d in res.dofs])
        w2 = (2 * np.pi * mode.undamped_hz) ** 2
        assert np.linalg.norm(K @ phi - w2 * M @ phi) <= 1e-10 * np.linalg.norm(K @ phi)


def test_congruent_chain_keeps_its_frequencies_and_its_rigid_mode():
    """Three equal masses m and springs k, free-free: ω² = (0, 1, 3)·k/m; in coordinates with a full M."""
    m, k = 2.0, 8e4
    chain = build_mechanics(ChainSpec(type="chain", masses=[m, m, m], stiffnesses=[k, k]))
    T = _T(3)
    full = _congruent(chain, T)
    assert not full.lumped and np.count_nonzero(full.mass - np.diag(np.diag(full.mass)))
    oracle_hz = np.sqrt(np.array([0.0, 1.0, 3.0]) * k / m) / (2 * np.pi)
    for mech in (full, Mechanics.from_matrices(full.dofs, full.mass, full.damping, full.stiffness)):
        res = modal_analysis(mech)
        assert res.n_rigid == 1 and res.undamped_hz[0] == 0.0
        # ω to ε·ω_max·κ(T)² (κ(T)² < 16): 1e-12 relative to the highest frequency is a wide margin
        np.testing.assert_allclose(res.undamped_hz, oracle_hz, rtol=0, atol=1e-12 * oracle_hz[-1])
        # the rigid motion is q = 1 (all bodies together), that is p = T⁻¹ 1
        rigid = np.array([res.modes[0].shape[d] for d in res.dofs])
        expected = np.linalg.solve(T, np.ones(3))
        expected = expected / expected[np.argmax(np.abs(expected))]
        np.testing.assert_allclose(rigid, expected, atol=1e-12)
    # the rigid mass the actuator sees is the total mass, whatever the coordinates (kinetic energy)
    tool = T[2]                                               # q3 = T[2] · p
    _, m_rigid = full.rigid_motion(full.actuators[0].vector, tool)
    assert m_rigid == pytest.approx(3 * m, rel=1e-13)


def test_modal_analysis_of_the_5m4s_in_full_mass_coordinates():
    """Everything the modal analysis reports between named signals is invariant under q = T p."""
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))
    lumped = loop.mechanics
    full = _congruent(lumped, _T(lumped.n))
    a, b = modal_analysis(lumped), modal_analysis(full)
    assert a.n_rigid == b.n_rigid
    # frequencies: SVD accuracy ε·ω_max·κ(T)² (κ(T)² ≈ 14) ≈ 1e-11 Hz on a 1 kHz top mode; damping
    # ratios and participations come from eigenvectors of well-separated modes: 1e-9 relative
    np.testing.assert_allclose(b.undamped_hz, a.undamped_hz, rtol=0, atol=1e-9 * a.undamped_hz.max())
    np.testing.assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=1e-9)
    np.testing.assert_allclose(b.damping_ratios, a.damping_ratios, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose([m.participation for m in b.modes], [m.participation for m in a.modes],
                               rtol=1e-8, atol=1e-12)
    assert b.f_meca_hz == pytest.approx(a.f_meca_hz, rel=1e-9)


# ------------------------------------------------------------------ the servo loop with a full M
def _full_loop():
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))
    T = _T(loop.mechanics.n)
    return loop, replace(loop, mechanics=_congruent(loop.mechanics, T), tool=T.T @ loop.tool), T


def test_servo_plant_with_full_mass_has_the_same_transfers():
    loop, full, _ = _full_loop()
    pa, pb = servo_plant(loop, disturbance=loop.tool), servo_plant(full, disturbance=full.tool)
    named = [i for i, o in enumerate(pa.outputs) if o.startswith(("sensor.", "tool.", "actuator.", "drive."))]
    nx = pa.n_states
    for w in (2 * np.pi * 5, 2 * np.pi * 80, 2 * np.pi * 700):
        ga = pa.C[named] @ np.linalg.solve(1j * w * np.eye(nx) - pa.A, pa.B)
        gb = pb.C[named] @ np.linalg.solve(1j * w * np.eye(nx) - pb.A, pb.B)
        # two backward-stable solves of condition κ (κ(T)² more for the full one): κ·ε·κ(T)²·100
        kappa = np.linalg.cond(1j * w * np.eye(nx) - pb.A)
        scale = np.max(np.abs(ga), axis=0, keepdims=True)
        assert np.all(np.abs(gb - ga) <= 100 * 16 * kappa * EPS * scale)


def test_friction_inputs_of_the_program_solve_with_the_full_mass():
    loop, full, _ = _full_loop()
    table = SetpointTable(np.zeros(3), np.zeros(3), np.zeros(3))
    mech = full.mechanics
    links = [f for f in mech.frictions if f.coulomb > 0 or f.static > 0]
    assert links
    F = servo_program(full, table).continuous.F
    n = mech.n
    direct = np.linalg.solve(mech.mass, np.column_stack([link.g for link in links]))
    np.testing.assert_array_equal(F[:n], 0.0)
    # κ(M)·ε relative (M = TᵀM₀T, κ(M) ≈ 14·κ(M₀))
    assert np.max(np.abs(F[n: 2 * n] - direct)) <= 100 * np.linalg.cond(mech.mass) * EPS * np.max(np.abs(direct))


def test_linear_simulation_with_full_mass_equals_the_lumped_one():
    loop, full, _ = _full_loop()
    a = simulate(loop, step_profile(1e-4), 0.03, nonlinear=False)
    b = simulate(full, step_profile(1e-4), 0.03, nonlinear=False)
    for name in ("tool.position", "following_error", "current.command"):
        x, y = np.asarray(a[name]), np.asarray(b[name])
        # a stable recursion of N = 240 steps accumulates at most N per-step roundings, each
        # κ(T)²·ε relative to the signal's scale (κ(T)² ≈ 14): N·14·ε ≈ 7e-13; 1e-10 leaves room
        assert np.max(np.abs(x - y)) <= 1e-10 * np.max(np.abs(x))


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize("M, words", [
    ([[1.0, 2.0], [2.0, 1.0]], "not positive definite"),
    ([[1.0, 0.5], [0.4, 1.0]], "not symmetric"),
    ([[1.0, 0.0], [0.0, 0.0]], "not positive definite"),
    ([[1.0, 0.0], [0.0, -2.0]], "not positive definite"),
    ([[1.0, np.nan], [np.nan, 1.0]], "non-finite"),
    ([[1.0, 0.0, 0.0]], "square"),
])
def test_mass_matrix_that_is_not_spd_gives_a_located_error(M, words):
    with pytest.raises(ModelError, match=words) as err:
        MassFactor(M)
    assert err.value.path == "mass" and str(err.value).startswith("mass: ")
    with pytest.raises(ModelError, match=words):
        second_order_state_space(M, np.eye(2), np.eye(2))


def test_from_matrices_checks_its_input():
    eye = np.eye(2)
    with pytest.raises(ModelError, match="not positive definite") as err:
        Mechanics.from_matrices(["a", "b"], [[1.0, 2.0], [2.0, 1.0]], 0 * eye, eye)
    assert err.value.path == "mass"
    with pytest.raises(ModelError, match=r"expected an \(2, 2\) matrix") as err:
        Mechanics.from_matrices(["a", "b"], eye, np.eye(3), eye)
    assert err.value.path == "damping"
    with pytest.raises(ModelError, match="negative eigenvalue") as err:
        Mechanics.from_matrices(["a", "b"], eye, 0 * eye, [[1.0, 0.0], [0.0, -1.0]])
    assert err.value.path == "stiffness"
    with pytest.raises(ModelError, match="couplings do not make the stiffness") as err:
        Mechanics.from_matrices(["a", "b"], eye, 0 * eye, [[1.0, -1.0], [-1.0, 1.0]],
                                couplings=[Link("s", np.array([1.0, 0.0]), "translational", stiffness=1.0)])
    assert err.value.path == "couplings"


def test_from_matrices_with_a_diagonal_mass_equals_build_mechanics():
    """The constructor path from outside gives the same plant and modes as the model-file path."""
    chain = build_mechanics(ChainSpec(type="chain", masses=[1.0, 2.0, 3.0], stiffnesses=[1e4, 3e4],
                                      dampings=[1.0, 2.0]))
    again = Mechanics.from_matrices(chain.dofs, chain.mass, chain.damping, chain.stiffness,
                                    actuators=chain.actuators, sensors=chain.sensors, couplings=chain.couplings)
    assert again.lumped
    np.testing.assert_array_equal(again.state_space().A, chain.state_space().A)
    np.testing.assert_array_equal(again.state_space().B, chain.state_space().B)
    np.testing.assert_array_equal(modal_analysis(again).undamped_hz, modal_analysis(chain).undamped_hz)


def test_physical_regrouping_refuses_a_full_mass():
    """Regrouping bodies moves their lumped masses; a full M has none to move: say so, don't guess."""
    from sicomat.reduction import physical

    spec = ChainSpec(type="chain", masses=[1.0, 2.0, 3.0], stiffnesses=[1e9, 1e3])
    full = _congruent(build_mechanics(spec), _T(3))
    psi = np.ones(3)
    with pytest.raises(ModelError, match="physical regrouping is defined for lumped bodies"):
        physical._greedy_keep(spec.to_lumped(), full, psi, bodies_wanted=2, omega_stop=None, tool=None)
    T = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    with pytest.raises(ModelError, match="physical regrouping is defined for lumped bodies"):
        physical._regrouped_spec(spec.to_lumped(), full, ["m1", "m3"], [0, 2], T, psi)
