"""sicomat.reduction: modal, balanced and physical reduction against closed forms and python-control."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure
from accuracy import eigenvalue_accuracy
from numpy.testing import assert_allclose

from sicomat import ChainSpec, LumpedSpec, ModelError, build_mechanics, load_model
from sicomat.io.modelfile import save_model
from sicomat.lti.plant import Plant
from sicomat.reduction import (balanced_truncation, error_metrics, frequency_grid, frequency_limited_truncation,
                               frequency_response, hankel_norm_approximation, hankel_singular_values,
                               modal_truncation, physical_reduction, reduced_machine,
                               schur_truncation, spectral_split, technological_dofs)
from sicomat.reduction.balanced import band_gramian_operator
from sicomat.tasks.reduce import reduce_command
from sicomat.cli.main import app
from typer.testing import CliRunner

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TWO_PI = 2 * math.pi


# --------------------------------------------------------------------------- models
def chain(n: int = 12, grounded: bool = True, seed: int = 0, damping: float = 20.0, viscous: float = 0.05):
    """A lightly damped chain of n masses (1–1.5 kg, springs 1–1.5 MN/m), driven on m1."""
    rng = np.random.default_rng(seed)
    return ChainSpec(type="chain", masses=list(1.0 + 0.5 * rng.random(n)),
                     stiffnesses=list(1e6 * (1.0 + 0.5 * rng.random(n - 1))),
                     dampings=[damping] * (n - 1), viscous=[viscous] * n if viscous else None,
                     ground_stiffness=1e6 if grounded else 0.0)


def plant_of(spec) -> Plant:
    return build_mechanics(spec).state_space()


def paper_5m4s():
    return load_model(EXAMPLES / "paper_5m4s.toml")


def sorted_poles(A) -> np.ndarray:
    lam = np.linalg.eigvals(A)
    return lam[np.lexsort((lam.imag, np.round(np.abs(lam), 6)))]


def frf(plant: Plant, omega) -> np.ndarray:
    """Reference response by one dense solve per frequency (independent of the package's evaluator)."""
    n = plant.n_states
    return np.array([plant.C @ np.linalg.solve(1j * w * np.eye(n) - plant.A, plant.B) + plant.D for w in omega])


def error_plant(full: Plant, reduced: Plant) -> Plant:
    """``G − G_r`` as one plant (block-diagonal realization)."""
    import scipy.linalg

    A = scipy.linalg.block_diag(full.A, reduced.A)
    names = tuple(f"x{i}" for i in range(A.shape[0]))
    return Plant(A, np.vstack([full.B, reduced.B]), np.hstack([full.C, -reduced.C]), full.D - reduced.D,
                 names, full.inputs, full.outputs)


# --------------------------------------------------------------------------- frequency machinery
def test_frequency_response_matches_dense_solves_with_rigid_mode():
    plant = plant_of(chain(6, grounded=False))
    omega = np.logspace(0, 4, 37)
    ours, ref = frequency_response(plant, omega), frf(plant, omega)
    floor = 1e-12 * np.max(np.abs(ref))  # the far end's response at 10 kHz is round-off of both
    # Not to the last digits at low frequency: K's row sums are round-off (1e-10 N/m), so the
    # assembled model has its rigid pole at about -2e-9 rad/s, which the split puts exactly at 0.
    # two dense evaluations of the same realisation, each within n·κ₂(jωI − A)·eps of H
    # (accuracy.transfer_accuracy); the rigid pole moved by 2e-9 rad/s changes H by ~2e-9/ω relative at ω >= 1
    # rad/s: 1e-6
    assert_allclose(ours, ref, rtol=1e-6, atol=floor)


def test_spectral_split_rigid_mode_counts_two_states_and_poles_exactly_zero():
    # free chain without friction to the frame: a double pole at 0 (Jordan block)
    split = spectral_split(plant_of(chain(5, grounded=False, viscous=0.0)))
    assert split.rigid.n == 2 and np.all(split.rigid.poles() == 0)
    # viscous guides: the rigid mode is a pole at 0 and the slow real pole -c/m of the whole chain
    spec = chain(5, grounded=False)
    split = spectral_split(plant_of(spec))
    poles = np.sort(split.rigid.poles().real)
    assert split.rigid.n == 2 and poles[1] == 0.0
    # an eigenvalue of |λ| = 0.04 rad/s of a matrix with ‖A‖ = 4e6: known to eps·‖A‖·κ/|λ| ≈ 2e-8·κ relative
    # (accuracy.eigenvalue_accuracy); 1e-6
    assert_allclose(poles[0], -sum(spec.viscous) / sum(spec.masses), rtol=1e-6)


def test_grid_holds_every_pole_frequency_and_half_power_points():
    lam = np.array([-0.01 + 100j, -0.01 - 100j, -3.0])
    omega = frequency_grid(lam)
    for w in (100.0, abs(lam[0]), 100.01, 99.99, 3.0):
        # the grid is built to contain these frequencies: rounding only
        assert np.any(np.isclose(omega, w, rtol=1e-12))


def test_grid_hinf_matches_exact_linf_norm():
    control = pytest.importorskip("control")
    pytest.importorskip("slycot")
    plant = plant_of(chain(40))
    res = balanced_truncation(plant, 12)
    exact, _ = control.linfnorm(plant.to_control() - res.reduced.to_control())
    # slycot's ab13dd (tolerance 1e-10) against our grid peak refined 4 rounds × 8 (reduction/error.py
    # _refine_peak): the refined peak is low by ~(Δ/4096)²·curvature, ~1e-6 for a ζ ~ 1e-3 peak on a 1 % grid;
    # 1e-4
    assert_allclose(res.hinf_error, float(exact), rtol=1e-4)


# --------------------------------------------------------------------------- modal truncation
@pytest.mark.parametrize("grounded", [True, False])
@pytest.mark.parametrize("order", [4, 8, 14])
def test_modal_truncation_keeps_lowest_frequencies_exactly(grounded, order):
    spec = chain(12, grounded=grounded)
    plant = plant_of(spec)
    res = modal_truncation(plant, order)
    assert res.order_after == order
    full = sorted_poles(plant.A)[:order]
    reduced = sorted_poles(res.reduced.A)
    # The reduction keeps eigenvalues of a reordered Schur form, the reference is eigvals of A: two
    # computations of each eigenvalue, each within n·eps·‖A‖·κ(λ) (accuracy.eigenvalue_accuracy; 5e-10
    # relative for the 120 rad/s mode, ‖A‖ = 4e6). The assembled model's rigid pole is round-off, about
    # 1e-9 rad/s, the reduced one exactly 0: within its bound (κ is large for that near-double pole).
    bound = eigenvalue_accuracy(plant.A, full)
    assert np.all(np.abs(reduced - full) <= 2 * bound)
    # and they are the lowest natural frequencies of the mechanics (|λ| / 2π, the same bound relative)
    n_kept = len(res.frequencies_hz)
    assert_allclose(res.frequencies_hz, res.frequencies_hz_full[:n_kept], rtol=0,
                    atol=2 * bound.max() / TWO_PI)
    flexible = [m.frequency_hz for m in build_mechanics(spec).modes().modes if not m.rigid]
    kept = res.frequencies_hz[res.frequencies_hz > 0.1]
    # modes() computes the eigenvalues a second time: twice the eigenvalue bound again, in Hz
    assert_allclose(kept, np.sort(flexible)[: len(kept)], rtol=0, atol=2 * bound.max() / TWO_PI)


@pytest.mark.parametrize("grounded", [True, False])
def test_modal_truncation_keeps_static_gain_of_flexible_part(grounded):
    plant = plant_of(chain(12, grounded=grounded))
    res = modal_truncation(plant, 6)
    # modal truncation with the residual static term keeps the flexible static gain up to rounding of -C A⁻¹ B:
    # κ(A)·eps with κ(A) = ω_max²/ω_min² ≈ 1e3 for this chain: ~2e-13; 1e-10 (1e-9 for the full static gain via
    # an independent solve)
    assert res.dc_gain_error <= 1e-10 * np.linalg.norm(spectral_split(plant).dc_gain(), 2)
    if grounded:  # the whole static gain, independently of the split
        dc = lambda p: p.D - p.C @ np.linalg.solve(p.A, p.B)  # noqa: E731
        assert_allclose(dc(res.reduced), dc(plant), rtol=1e-9)


def test_modal_truncation_rigid_mode_and_one_flexible_mode_make_four_states():
    m1, m2, k, c = 3.0, 5.0, 1e6, 2.0
    plant = plant_of(ChainSpec(type="chain", masses=[m1, m2, 1.0], stiffnesses=[k, 1e9], dampings=[c, 1.0]))
    res = modal_truncation(plant, 4)
    poles = np.sort_complex(np.linalg.eigvals(res.reduced.A))
    assert np.sum(poles == 0) == 2
    # the flexible mode kept is the lowest one of the full model, exactly
    flexible = np.sort_complex(sorted_poles(plant.A)[2:4])
    # a 1e9 N/m spring makes ‖A‖ = 1.4e9: the 707 rad/s mode is known to n·eps·‖A‖·κ ≈ 1e-6 relative
    # by any eigen-solver (accuracy.eigenvalue_accuracy), not to 1e-9
    kept = np.sort_complex(poles[np.abs(poles) > 0])
    assert np.all(np.abs(kept - flexible) <= 2 * eigenvalue_accuracy(plant.A, flexible))


def test_modal_truncation_never_splits_a_complex_pair():
    # the warning (not a note) is what `reduce --json` and its table show
    res = modal_truncation(plant_of(chain(8)), 5)
    assert res.order_after == 4 and any("split" in w and "4 or 6" in w for w in res.warnings)
    assert res.to_dict()["warnings"] == list(res.warnings)


def test_modal_truncation_matches_python_control_modal_form_and_modred():
    control = pytest.importorskip("control")
    pytest.importorskip("slycot")  # control.modal_form block-diagonalises with slycot's mb03rd
    plant = plant_of(chain(10))
    order = 8
    msys, _ = control.modal_form(plant.to_control())
    A = msys.A  # block-diagonal: |λ| of each state's block
    per_state = np.zeros(A.shape[0])
    i = 0
    while i < A.shape[0]:
        if i + 1 < A.shape[0] and A[i, i + 1] != 0:
            per_state[i:i + 2] = np.sqrt(abs(np.linalg.det(A[i:i + 2, i:i + 2])))
            i += 2
        else:
            per_state[i] = abs(A[i, i])
            i += 1
    elim = np.sort(np.argsort(per_state, kind="stable")[order:])
    peer = control.modred(msys, elim, method="matchdc")
    res = modal_truncation(plant, order)
    omega = np.logspace(1, 4, 80)
    peer_plant = Plant(peer.A, peer.B, peer.C, peer.D, tuple(f"x{i}" for i in range(order)), plant.inputs,
                       plant.outputs)
    # the same truncation by slycot and by our Schur form: the reduced realisations differ by eigenvector
    # rounding, κ(V)·eps ≈ 1e-12, amplified by the FRF's conditioning near resonances (1/ζ ~ 1e3): 1e-7
    assert_allclose(frf(res.reduced, omega), frf(peer_plant, omega), rtol=1e-7)


# --------------------------------------------------------------------------- balanced truncation
@pytest.mark.parametrize("a, b, c", [(1.0, 1.0, 1.0), (3.0, 2.0, 5.0), (1e3, 1e-2, 4e4)])
def test_hankel_singular_value_of_first_order_system(a, b, c):
    plant = Plant([[-a]], [[b]], [[c]], [[0.0]], ("x",), ("u",), ("y",))
    # a 1×1 Lyapunov equation solved in a few roundings: 1e-12
    assert_allclose(hankel_singular_values(plant), [abs(b * c) / (2 * a)], rtol=1e-12)


REDUCTORS = {
    "square-root": lambda p, r: balanced_truncation(p, r),
    "singular-perturbation": lambda p, r: balanced_truncation(p, r, match_dc=True),
    "schur": lambda p, r: schur_truncation(p, r),
    "hankel-norm": lambda p, r: hankel_norm_approximation(p, r),
}


@pytest.mark.parametrize("variant", list(REDUCTORS))
@pytest.mark.parametrize("grounded", [True, False])
@pytest.mark.parametrize("order", [4, 10, 16])
def test_balanced_error_under_its_bound_and_above_the_next_hsv(variant, grounded, order):
    plant = plant_of(chain(14, grounded=grounded))
    res = REDUCTORS[variant](plant, order)
    assert res.variant == variant and res.order_after == order
    rigid = spectral_split(plant, marginal=True).rigid.n
    # 1e-6: the rounding of the Hankel singular values (absolute ~eps·σ₁ times the conditioning of the Gramians'
    # square-root factors, ~1e-10 relative for the chain) and the refined peak search (see above); the lower
    # bound (Glover) gets the same slack
    sigma = res.hankel_singular_values
    assert res.hinf_error <= res.error_bound * (1 + 1e-6)
    # no model of that order does better than the next Hankel singular value (Glover)
    assert res.hinf_error >= sigma[order - rigid] * (1 - 1e-6)


def test_hankel_norm_approximation_is_optimal_in_the_hankel_norm():
    plant = plant_of(chain(10))
    for order in (4, 9):
        res = hankel_norm_approximation(plant, order)
        error_hsv = hankel_singular_values(error_plant(plant, res.reduced))
        # σ₁ of the error system vs σ_{r+1} of the full one: two Lyapunov solves on different realisations, each
        # ~eps·σ₁(full)·cond of the factors; σ_{r+1}/σ₁ >= 1e-4 here: 1e-6
        assert_allclose(error_hsv[0], res.hankel_singular_values[order], rtol=1e-6)


@pytest.mark.parametrize("grounded", [True, False])
def test_singular_perturbation_keeps_static_gain(grounded):
    plant = plant_of(chain(14, grounded=grounded))
    res = balanced_truncation(plant, 6, match_dc=True)
    # singular perturbation keeps the static gain exactly in exact arithmetic; rounding of the balanced
    # realisation's -C A⁻¹ B is ~κ(A_balanced)·eps, ~1e-12 for this chain: 1e-9
    assert res.dc_gain_error <= 1e-9 * np.linalg.norm(spectral_split(plant).dc_gain(), 2)
    assert res.metrics.dc_gain_relative_error < 1e-9


def test_balanced_truncation_keeps_rigid_mode_exactly():
    plant = plant_of(chain(10, grounded=False, viscous=0.0))
    res = balanced_truncation(plant, 6)
    assert np.all(np.linalg.eigvals(res.reduced.A[:2, :2]) == 0)
    assert res.reduced.states[:2] == ("rigid.1", "rigid.2")
    # the double integrators cancel in the error, which stays under the bound down to low frequency
    m = res.metrics
    lowest = np.min(np.abs(spectral_split(plant).flexible.poles()))
    assert m.omega[0] <= lowest / 50 and np.all(m.error_gain <= res.error_bound * (1 + 1e-6))


def test_balanced_is_invariant_to_state_renumbering():
    plant = plant_of(chain(9))
    perm = np.random.default_rng(1).permutation(plant.n_states)
    shuffled = Plant(plant.A[np.ix_(perm, perm)], plant.B[perm], plant.C[:, perm], plant.D,
                     tuple(plant.states[i] for i in perm), plant.inputs, plant.outputs)
    omega = np.logspace(1, 4, 50)
    a, b = balanced_truncation(plant, 8), balanced_truncation(shuffled, 8)
    # HSVs are invariant to a state permutation; the ten largest are >= 1e-6 σ₁ and each is accurate to
    # ~eps·σ₁·cond(factors) absolute: <= 1e-9 relative. The reduced models agree to that rounding, amplified by
    # the FRF's conditioning (1/ζ ~ 1e3): 1e-7
    assert_allclose(a.hankel_singular_values[:10], b.hankel_singular_values[:10], rtol=1e-9)
    assert_allclose(frf(a.reduced, omega), frf(b.reduced, omega), rtol=1e-7, atol=1e-14)


def test_stiff_model_paper_5m4s_balanced_keeps_rigid_part_and_static_compliance():
    mech = build_mechanics(paper_5m4s().axis().mechanics)
    plant = mech.state_space()
    res = balanced_truncation(plant, 6, match_dc=True)
    assert res.order_after == 6
    assert res.hinf_error <= res.error_bound * (1 + 1e-6)
    # the 5M4S's 1e12 N/m spring: κ(A) ≈ 1e7 in its static gain: rounding ~2e-9, 1e-8
    assert res.metrics.dc_gain_relative_error < 1e-8
    assert res.frequencies_hz[0] == 0.0


@pytest.mark.parametrize("grounded", [True, False])
def test_balanced_matches_python_control_balred(grounded):
    control = pytest.importorskip("control")
    pytest.importorskip("slycot")
    plant = plant_of(chain(12, grounded=grounded))
    order = 10
    omega = np.logspace(0.5, 4, 60)
    for match_dc, method in ((False, "truncate"), (True, "matchdc")):
        res = balanced_truncation(plant, order, match_dc=match_dc)
        try:
            peer = control.balred(plant.to_control(), order, method=method)
        except Exception as exc:  # noqa: BLE001 - the peer's own limits are not our failure
            pytest.skip(f"balred cannot reduce this model: {exc}")
        peer_plant = Plant(peer.A, peer.B, peer.C, peer.D, tuple(f"x{i}" for i in range(peer.nstates)),
                           plant.inputs, plant.outputs)
        G = frf(plant, omega)
        scale = np.max(np.abs(G))
        # slycot's balancing and ours agree to the conditioning of the balancing transformation (~√(σ₁/σ_r) ≈
        # 1e3 here) times eps and the FRF's 1/ζ: ~1e-10; 1e-5 of the largest response, as the peer's own
        # tolerance on small HSVs (tol = 0) is unknown
        assert np.max(np.abs(frf(res.reduced, omega) - frf(peer_plant, omega))) <= 1e-5 * scale


def test_hankel_singular_values_match_slycot():
    pytest.importorskip("slycot")
    from slycot import ab09ad

    plant = plant_of(chain(12))
    n, m, p = plant.n_states, 1, len(plant.outputs)
    A, B, C = (np.array(X, order="F") for X in (plant.A, plant.B, plant.C))
    *_, hsv = ab09ad("C", "B", "N", n, m, p, A, B, C, nr=6, tol=0.0)
    ours = hankel_singular_values(plant)
    # HSVs from slycot (ab09ad) and ours: absolute accuracy ~eps·σ₁·cond(factors) each; the 12th is ~1e-5 σ₁:
    # 1e-7 relative
    assert_allclose(ours[:12], hsv[:12], rtol=1e-7)


def test_schur_method_has_the_transfer_function_of_balred():
    # The Schur (balancing-free) method projects on the same subspaces as balanced truncation. Its
    # slycot version (ab09ad/ab09md with job='N') corrupts the heap in slycot 0.7.1 ("free(): invalid
    # size"), so the peer is python-control's balred (ab09ad, job='B').
    control = pytest.importorskip("control")
    pytest.importorskip("slycot")
    plant = plant_of(chain(12))
    peer = control.balred(plant.to_control(), 8)
    peer_plant = Plant(peer.A, peer.B, peer.C, peer.D, tuple(f"x{i}" for i in range(8)), plant.inputs,
                       plant.outputs)
    res = schur_truncation(plant, 8)
    omega = np.logspace(0.5, 4, 60)
    scale = np.max(np.abs(frf(plant, omega)))
    # the Schur method needs no balancing, so the realisations differ only by the Schur vectors' rounding and
    # the FRF's 1/ζ: 1e-6 of the largest response
    assert np.max(np.abs(frf(res.reduced, omega) - frf(peer_plant, omega))) <= 1e-6 * scale
    assert np.linalg.cond(res.reduced.A) < np.linalg.cond(balanced_truncation(plant, 8).reduced.A) * 10


# --------------------------------------------------------------------------- frequency-limited Gramians
def test_band_gramian_equals_integral_over_the_band():
    plant = plant_of(chain(4))
    split = spectral_split(plant, marginal=True)
    T, B = split.flexible.A, split.flexible.B
    import scipy.integrate
    import scipy.linalg

    P = scipy.linalg.solve_continuous_lyapunov(T, -B @ B.T)
    w1, w2 = TWO_PI * 10, TWO_PI * 200
    S = band_gramian_operator(T, (w1, w2))
    P_band = S @ P + P @ S.T
    w = np.linspace(w1, w2, 40001)
    F = np.linalg.solve(1j * w[:, None, None] * np.eye(T.shape[0]) - T, np.broadcast_to(B, (w.size, *B.shape)))
    integrand = np.einsum("wik,wjk->wij", F, F.conj()).real / np.pi  # (1/2π) ∫ over ±[w1, w2]
    # the trapezoid rule on 40001 points: error (Δω)²/12·max|f''| with Δω = 0.03 rad/s and the integrand's
    # resonances (width ζω ≳ 1 rad/s): <= 1e-7 relative; 1e-6. The whole axis reproduces P up to the Lyapunov
    # solve's rounding (~κ·eps, 1e-12) and the truncation at 1e12 rad/s (ω_max/1e12 ≈ 1e-9): 1e-9 of P
    assert_allclose(P_band, scipy.integrate.trapezoid(integrand, w, axis=0), rtol=1e-6, atol=1e-8 * np.abs(P_band).max())
    # the whole axis gives back the ordinary Gramian
    S_all = band_gramian_operator(T, (0.0, 1e12))
    assert_allclose(S_all @ P + P @ S_all.T, P, rtol=1e-6, atol=1e-9 * np.abs(P).max())


@pytest.mark.parametrize("band", [(0.0, 30.0), (0.0, 60.0), (20.0, 60.0)])
def test_frequency_limited_truncation_beats_balanced_in_its_band(band):
    plant = plant_of(chain(30, seed=3))
    fl = frequency_limited_truncation(plant, 8, band)
    bt = balanced_truncation(plant, 8, band_hz=band)
    assert fl.error_bound is None and fl.band_hz == band
    assert fl.band_max_error < bt.band_max_error
    assert np.all(np.linalg.eigvals(fl.reduced.A).real < 0)


# --------------------------------------------------------------------------- physical regrouping
@pytest.mark.parametrize("k", [1e7, 1e8, 1e9])
def test_two_masses_on_a_stiff_spring_regroup_to_the_rigid_mass_to_first_order_in_1_over_k(k):
    m1, m2 = 2.0, 3.0
    res = physical_reduction(ChainSpec(type="chain", masses=[m1, m2], stiffnesses=[k]), keep=["m1"])
    assert list(res.spec.bodies) == ["m1"] and res.spec.bodies["m1"].mass == m1 + m2
    assert not res.spec.couplings and res.merged_into == {"m2": "m1"}
    assert res.spec.sensors["last"].body == "m1"
    w = np.array([10.0, 100.0])
    full = frf(res.full, w)[:, 0, 0]
    red = frf(res.reduced, w)[:, 0, 0]
    # the rigid model's closed form, a few roundings; the relative error of the full model is O(ω²/ω_n²) and its
    # closed form is evaluated from the FRF's difference (cancellation eps·1/|full/red − 1| ≈ 1e-8 at k = 1e9, ω
    # = 10): 1e-6
    assert_allclose(red, -1.0 / ((m1 + m2) * w ** 2), rtol=1e-12)
    # x1/F: the relative error of the rigid model is exactly −m2² ω² / (k (m1+m2) − m1 m2 ω²)
    assert_allclose(full / red - 1, -m2 ** 2 * w ** 2 / (k * (m1 + m2) - m1 * m2 * w ** 2), rtol=1e-6)


def test_series_springs_combine_and_masses_split_by_the_lever_rule():
    m, k1, k2 = [1.0, 2.0, 3.0], 4e6, 1e6
    res = physical_reduction(ChainSpec(type="chain", masses=m, stiffnesses=[k1, k2], dampings=[10.0, 30.0]),
                             keep=["m1", "m3"])
    (coupling,) = res.spec.couplings.values()
    assert coupling.between == ("m1", "m3")
    # the regrouping's closed forms (springs in series, masses by static shares) in a few roundings each: 1e-12
    assert_allclose(coupling.stiffness, 1 / (1 / k1 + 1 / k2), rtol=1e-12)
    w = k1 / (k1 + k2)  # m2 follows m1 by k1/(k1+k2) statically
    assert_allclose(res.spec.bodies["m1"].mass, m[0] + m[1] * w, rtol=1e-12)
    assert_allclose(res.spec.bodies["m3"].mass, m[2] + m[1] * (1 - w), rtol=1e-12)
    assert_allclose(sum(b.mass for b in res.spec.bodies.values()), sum(m), rtol=1e-12)
    # the dampers in series project the same way: c = c1 w'² + c2 (1 − w')² with w' = k2/(k1+k2)
    assert_allclose(coupling.damping, 10.0 * (k2 / (k1 + k2)) ** 2 + 30.0 * (k1 / (k1 + k2)) ** 2, rtol=1e-12)


def test_static_compliance_of_a_grounded_model_is_kept_exactly():
    # the grounded chain's static compliance is kept exactly by the regrouping: rounding of two static solves,
    # κ(K) ≈ 1e2: 1e-9
    res = physical_reduction(chain(8), keep=["m1", "m4", "m8"])
    assert res.metrics.dc_gain_relative_error < 1e-9
    with_rigid = physical_reduction(chain(8, grounded=False), keep=["m1", "m4", "m8"])
    assert with_rigid.frequencies_hz[0] == 0.0  # the rigid mode is still there, with the same mass
    # masses are only redistributed: rounding of a sum
    assert_allclose(sum(b.mass for b in with_rigid.spec.bodies.values()), sum(chain(8).masses), rtol=1e-12)


def test_parallel_springs_add_before_combining_in_series():
    spec = LumpedSpec(bodies={"a": {"mass": 1.0}, "b": {"mass": 1.0}, "c": {"mass": 1.0}},
                      couplings={"k1": {"between": ["a", "b"], "stiffness": 1e6},
                                 "k2": {"between": ["a", "b"], "stiffness": 2e6},
                                 "k3": {"between": ["b", "c"], "stiffness": 6e6}},
                      actuators={"f": {"body": "a"}}, sensors={"s": {"body": "c"}})
    res = physical_reduction(spec, keep=["a", "c"])
    (coupling,) = res.spec.couplings.values()
    # closed form, a few roundings
    assert_allclose(coupling.stiffness, 1 / (1 / 3e6 + 1 / 6e6), rtol=1e-12)


def test_transmission_ratio_is_respected_on_the_ball_screw():
    machine = load_model(EXAMPLES / "ballscrew_3m2s.toml")
    spec = machine.axis().mechanics
    lead = spec.couplings["screw_nut"].ratios[0]  # m/rad
    res = physical_reduction(spec, keep=["motor", "table"])
    (coupling,) = res.spec.couplings.values()
    k_t, k_nut = spec.couplings["coupling"].stiffness, spec.couplings["screw_nut"].stiffness
    # closed forms through the ratio lead: a few roundings (1e-12); 1e-9 where the share k_t/(k_t + k_nut lead²)
    # subtracts terms 1e6 apart
    assert_allclose(coupling.ratios, (lead, 1.0), rtol=1e-12)
    assert_allclose(coupling.stiffness, 1 / (1 / k_nut + lead ** 2 / k_t), rtol=1e-9)  # N/m at the table
    # the inertia seen by the motor in a rigid motion is unchanged: J_m + J_s + m lead²
    J = {n: b.value for n, b in spec.bodies.items()}
    Jr = {n: b.value for n, b in res.spec.bodies.items()}
    assert_allclose(Jr["motor"] + Jr["table"] * lead ** 2, J["motor"] + J["screw"] + J["table"] * lead ** 2,
                    rtol=1e-12)
    # the screw rides mostly on the motor (stiff coupling), a little on the table
    share = k_t / (k_t + k_nut * lead ** 2)
    assert_allclose(Jr["motor"], J["motor"] + J["screw"] * share, rtol=1e-9)


@pytest.mark.parametrize("order, bodies", [(6, ["structure", "primary", "load"]), (4, ["structure", "primary"])])
def test_paper_5m4s_regroups_to_3m2s_and_2m1s(order, bodies):
    machine = paper_5m4s()
    res = physical_reduction(machine.axis().mechanics, order=order)
    assert list(res.spec.bodies) == bodies and res.order_after == order
    masses = {n: b.mass for n, b in res.spec.bodies.items()}
    # sums of the file's masses: rounding
    assert_allclose(masses["structure"], 3667 + 232, rtol=1e-12)  # the secondary on its 1e12 N/m spring
    moving = 92.305 + 0.008 + (0 if "load" in bodies else 270.2)
    assert_allclose(masses["primary"], moving, rtol=1e-12)
    assert res.spec.actuators["motor"].body == "primary" and res.spec.actuators["motor"].reaction == "structure"
    assert res.spec.sensors["scale"].relative_to == "structure"
    springs = sum(1 for c in res.spec.couplings.values() if c.stiffness > 0)
    assert springs == len(bodies) - 1  # 3M2S, 2M1S
    # the first flexible mode (the paper's f_meca ≈ 80 Hz) is kept to 0.01 %
    # a physical approximation, not rounding: merging the 1e12 N/m spring shifts f_meca by O(ω²/ω_merged²) ≈
    # (80/5600)² = 2e-4 at most; observed below 1e-4, the bound the docs promise (0.01 %)
    assert_allclose(res.frequencies_hz[1], res.frequencies_hz_full[1], rtol=1e-4)
    assert res.frequencies_hz[1] == pytest.approx(80.6, abs=0.1)


def test_band_rule_merges_springs_much_stiffer_than_the_band():
    res = physical_reduction(paper_5m4s().axis().mechanics, band_hz=(0.0, 200.0))
    assert res.kept == ("structure", "primary", "load")


def test_technological_rule_keeps_signal_bodies():
    spec = paper_5m4s().axis().mechanics
    assert technological_dofs(spec) == ("structure", "secondary", "primary", "scale_head")
    res = physical_reduction(spec)
    assert res.kept == technological_dofs(spec) and res.merged_into == {"load": "primary"}


def test_reduced_model_file_round_trip(tmp_path):
    machine = paper_5m4s()
    res = physical_reduction(machine.axis().mechanics, order=6)
    reduced = reduced_machine(machine, "X", res.spec, merged_into=res.merged_into)
    path = save_model(reduced, tmp_path / "reduced.toml")
    back = load_model(path)
    assert back.axis("X").mechanics == res.spec
    assert back.axis("X").controller == machine.axis("X").controller
    again = build_mechanics(back.axis("X").mechanics).state_space()
    omega = np.logspace(1, 4, 20)
    # a saved and reloaded model: floats round-trip exactly through TOML, so the same matrices up to the
    # rounding of the assembly; their FRFs agree to κ₂·eps ≈ 1e-13 at these frequencies (no resonance sharper
    # than ζ ~ 1e-2 on the grid): 1e-12
    assert_allclose(frf(again, omega), frf(res.reduced, omega), rtol=1e-12)


def test_reduced_machine_moves_a_merged_tool():
    machine = load_model(EXAMPLES / "paper_5m4s.toml").model_copy()
    data = machine.model_dump(mode="json", exclude_none=True)
    data["axes"]["X"]["tool"] = "load"
    from sicomat.description.machine import Machine

    machine = Machine.model_validate(data)
    res = physical_reduction(machine.axis().mechanics, order=4)
    reduced = reduced_machine(machine, None, res.spec, merged_into=res.merged_into)
    assert reduced.axis().tool == "primary"
    with pytest.raises(ModelError, match="tool"):
        reduced_machine(machine, None, res.spec)


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("call, match", [
    (lambda p: modal_truncation(p, 99), "larger than the model"),
    (lambda p: balanced_truncation(p, 0), "too small"),
    (lambda p: modal_truncation(p, 2.5), "whole number"),
    (lambda p: balanced_truncation(p, 4, band_hz=(50.0, 10.0)), "low < high"),
    (lambda p: frequency_limited_truncation(p, 4, (10.0, 10.0)), "low < high"),
])
def test_bad_orders_and_bands_are_model_errors(call, match):
    plant = plant_of(chain(5, grounded=False))
    with pytest.raises(ModelError, match=match) as info:
        call(plant)
    assert isinstance(info.value, ValueError)


def test_order_below_the_rigid_part_is_refused():
    with pytest.raises(ModelError, match="rigid"):
        modal_truncation(plant_of(chain(5, grounded=False)), 1)


@pytest.mark.parametrize("kwargs, match", [
    ({"keep": []}, "keep-list is empty"),
    ({"keep": ["m1", "nope"]}, "unknown body 'nope'"),
    ({"order": 3}, "even order"),
    ({"order": 12}, "larger than the model"),
    ({"keep": ["m1", "m2"], "order": 6}, "disagree"),
])
def test_physical_bad_input(kwargs, match):
    with pytest.raises(ModelError, match=match):
        physical_reduction(chain(5), **kwargs)


def test_physical_refuses_a_body_held_by_no_spring():
    spec = paper_5m4s().axis().mechanics  # primary/load/scale_head touch the rest by friction only
    with pytest.raises(ModelError, match="no spring holds"):
        physical_reduction(spec, keep=["structure", "secondary"])


BAD_REDUCE_INPUT = [
    ("modal", 500, None, None, "order"),
    ("balanced", 0, None, None, "order"),
    ("physical", None, "", None, "keep"),
    ("physical", None, "primary,ghost", None, "keep"),
    ("modal", 4, None, "200:100", "band"),
    ("modal", 4, None, "0-200", "band"),
    ("modal", 4, "primary", None, "keep"),
    ("fourier", 4, None, None, "method"),
]


@pytest.mark.parametrize("method, order, keep, band, parameter", BAD_REDUCE_INPUT)
def test_reduce_command_bad_input_names_the_parameter(method, order, keep, band, parameter):
    # the library names its parameter, never a command-line option (the CLI maps one to the other)
    with pytest.raises(ModelError) as info:
        reduce_command(paper_5m4s(), None, method, order, keep, band)
    assert info.value.source is None and info.value.path == parameter
    assert "--" not in str(info.value)


@pytest.mark.parametrize("method, order, keep, band, parameter", BAD_REDUCE_INPUT)
def test_reduce_cli_bad_input_names_the_option(method, order, keep, band, parameter):
    args = ["reduce", str(EXAMPLES / "paper_5m4s.toml"), "--method", method]
    for option, value in (("--order", order), ("--keep", keep), ("--band", band)):
        if value is not None:
            args += [option, str(value)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: --{parameter}: ")


# --------------------------------------------------------------------------- the CLI-facing call and results
@pytest.mark.parametrize("method, order, keep, band", [
    ("modal", 4, None, None), ("balanced", 6, None, None), ("balanced", 6, None, "0:500"),
    ("balanced-dc", 6, None, None), ("schur", 6, None, None), ("hankel", 6, None, None),
    ("physical", None, "structure,primary,load", "0:200"), ("physical", 4, None, None),
    ("modal", None, None, "0:200"),
])
def test_reduce_command_json_contract(method, order, keep, band):
    res = reduce_command(paper_5m4s(), "X", method, order, keep, band)
    payload = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    for key in ("method", "order_before", "order_after", "hinf_error", "dc_gain_error", "frequencies_hz"):
        assert key in payload
    assert payload["order_before"] == 10
    if order is not None:
        assert payload["order_after"] == order
    assert payload["frequencies_hz"][0] == 0.0  # the rigid-body mode is kept
    # with the default transfer (motor → scale) every method keeps f_meca first: 80.6014 Hz from the full
    # model; the balanced methods keep it through a reduced realisation that is a physical approximation
    # (a 1e-4 shift, as above): 1e-3
    assert_allclose(payload["frequencies_hz"][1], 80.6014, rtol=1e-3)
    assert payload["warnings"] == []
    for pair in payload["retained_frequencies"]:
        assert set(pair) == {"reduced_hz", "full_hz", "relative_error"}
    if method == "physical":
        assert res.machine is not None and res.spec is not None and payload["kept"]
    else:
        assert res.machine is None


# --------------------------------------------------------------------------- the transfer that is reduced
def _f_meca_of_5m4s() -> float:
    """The 80.6 Hz mode the tuning is built on, from the modal analysis of the full mechanics."""
    from sicomat.mechanics.modal import modal_analysis

    modes = modal_analysis(build_mechanics(paper_5m4s().axis().mechanics))
    assert_allclose(modes.f_meca_hz, 80.6, rtol=1e-3)
    return modes.f_meca_hz


@pytest.mark.parametrize("method, band", [
    ("modal", None), ("balanced", None), ("balanced-dc", None), ("schur", None), ("hankel", None),
    ("balanced", "0:500"),     # the frequency-limited Gramians
    ("physical", None),
])
def test_paper_5m4s_order_4_keeps_f_meca_for_every_method(method, band):
    # Default transfer motor → scale (the loop's actuator and position sensor). With both sensors in
    # raw SI units the velocity output (m/s = ω·m) weighs the 374 Hz mode 4.6 times more than the
    # 80.6 Hz one and the balanced methods kept 374 Hz. Tolerance 1 %: the methods other than modal
    # truncation do not keep poles exactly (the Hankel-norm one moves 80.6 Hz by 1e-5).
    res = reduce_command(paper_5m4s(), None, method, 4, None, band)
    assert res.order_after == 4 and res.full.inputs == ("motor",) and res.full.outputs == ("scale",)
    payload = res.to_dict()
    assert payload["inputs"] == ["motor"] and payload["outputs"] == ["scale"]
    assert any("outputs scale by default" in note for note in payload["notes"])   # parameter words, not options
    flexible = [f for f in res.frequencies_hz if f > 0]
    # which mode survives: the other candidate (374 Hz) is 4.6 times higher, so 1 % discriminates with a
    # factor 360 to spare while allowing the non-modal methods' pole shift (1e-5 for Hankel, above)
    assert len(flexible) == 1 and flexible[0] == pytest.approx(_f_meca_of_5m4s(), rel=0.01)


def test_a_chosen_transfer_is_the_one_reduced():
    machine = paper_5m4s()
    full = build_mechanics(machine.axis().mechanics).state_space()
    res = reduce_command(machine, None, "balanced", 4, None, None, outputs="scale_velocity")
    assert res.full.outputs == ("scale_velocity",) and res.reduced.outputs == ("scale_velocity",)
    omega = np.array([10.0, 500.0, 2000.0])
    # the full model reported is the chosen column, by dense solves on the original plant
    assert_allclose(frf(res.full, omega), frf(full, omega)[:, [1], :], rtol=1e-12)
    # both outputs in SI units: the velocity channel dominates and 374 Hz is kept, not 80.6 Hz
    mixed = reduce_command(machine, None, "balanced", 4, None, None, outputs=["scale", "scale_velocity"])
    assert mixed.full.outputs == ("scale", "scale_velocity")
    assert [f for f in mixed.frequencies_hz if f > 0] == [pytest.approx(374.02, rel=1e-3)]
    # the Python reductors take the names too
    direct = balanced_truncation(full, 4, inputs=["motor"], outputs=["scale"])
    assert direct.full.outputs == ("scale",)
    assert [f for f in direct.frequencies_hz if f > 0] == [pytest.approx(80.6, rel=1e-3)]
    # the same computation as the command's default transfer (same operations: equal to round-off)
    default = reduce_command(machine, None, "balanced", 4, None, None)
    assert_allclose(frf(direct.reduced, omega), frf(default.reduced, omega), rtol=1e-12)


@pytest.mark.parametrize("inputs, outputs, option, match", [
    (None, "ghost", "--outputs", "expected names among scale, scale_velocity"),
    ("primary", None, "--inputs", "expected names among motor"),
    (",", None, "--inputs", "signal names separated by commas"),
    (None, "scale,scale", "--outputs", "named twice"),
])
def test_unknown_signals_are_model_errors_listing_the_signals(inputs, outputs, option, match):
    with pytest.raises(ModelError, match=match) as info:
        reduce_command(paper_5m4s(), None, "modal", 4, None, None, inputs, outputs)
    assert info.value.source is None and info.value.path == option.removeprefix("--")
    with pytest.raises(ModelError, match="expected names among"):
        modal_truncation(plant_of(chain(4)), 4, outputs=["nope"])


def test_default_transfer_without_a_controller_takes_the_position_sensors():
    from sicomat.tasks.reduce import default_transfer

    machine = sicomat_machine({"axes": {"X": {"mechanics": {
        "type": "lumped", "bodies": {"a": {"mass": 1.0}, "b": {"mass": 2.0}},
        "couplings": {"k": {"between": ["a", "b"], "stiffness": 1e6}},
        "actuators": {"f": {"body": "a"}},
        "sensors": {"pa": {"body": "a"}, "vb": {"body": "b", "kind": "velocity"}, "pb": {"body": "b"}}}}}})
    inputs, outputs, _ = default_transfer(machine.axis())
    assert inputs == ["f"] and outputs == ["pa", "pb"]
    res = reduce_command(machine, None, "modal", 2, None, None)
    assert res.full.outputs == ("pa", "pb")


def sicomat_machine(data):
    from sicomat import machine_from_dict

    return machine_from_dict(data)


# --------------------------------------------------------------------------- `reduce MODEL` as a newcomer types it
def test_reduce_without_options_keeps_the_modes_below_twice_the_velocity_nyquist_frequency():
    from typer.testing import CliRunner

    from sicomat.cli.main import app
    from sicomat.mechanics.modal import modal_analysis

    result = CliRunner().invoke(app, ["reduce", str(EXAMPLES / "paper_5m4s.toml"), "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    machine = paper_5m4s()
    nyquist = 0.5 / machine.axis().controller.velocity_period            # 4 kHz
    modes = modal_analysis(build_mechanics(machine.axis().mechanics)).modes
    expected = 2 + 2 * sum(1 for m in modes if not m.rigid and m.frequency_hz <= 2 * nyquist)
    assert payload["order_after"] == expected == 8    # 80.6, 374 and 5627 Hz; not 10.8 kHz
    assert payload["band_hz"] == [0.0, nyquist]
    assert any("Nyquist" in note for note in payload["notes"])
    text = CliRunner().invoke(app, ["reduce", str(EXAMPLES / "paper_5m4s.toml")])
    assert text.exit_code == 0 and "transfer: motor → scale" in text.stdout


def test_an_order_inside_a_complex_pair_is_rounded_down_and_said():
    from typer.testing import CliRunner

    from sicomat.cli.main import app

    model = str(EXAMPLES / "paper_5m4s.toml")
    result = CliRunner().invoke(app, ["reduce", model, "--order", "5", "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    assert payload["order_after"] == 4
    assert len(payload["warnings"]) == 1 and "split" in payload["warnings"][0] and "4 or 6" in payload["warnings"][0]
    text = CliRunner().invoke(app, ["reduce", model, "--order", "5"])
    assert "warning" in text.stdout and "4 or 6" in text.stdout
    # balanced methods keep an odd order (a real pole that is no mode; the error bound holds) and say so
    res = reduce_command(paper_5m4s(), None, "balanced", 5, None, None)
    assert res.order_after == 5 and any("real pole" in w for w in res.warnings)


def test_modal_order_from_band_keeps_modes_up_to_twice_the_band():
    res = reduce_command(paper_5m4s(), None, "modal", None, None, "0:200")
    assert res.order_after == 6  # the rigid mode, 80.6 Hz and 374 Hz (< 2 × 200 Hz); not 5.6 kHz
    # each kept frequency is the full model's to the eigenvalue accuracy of the 5M4S (its 1e12 N/m
    # spring gives ‖A‖ = 6e9: ~1e-6 relative at 80 Hz), far from the next mode at 5.6 kHz
    plant = build_mechanics(paper_5m4s().axis().mechanics).state_space()
    lam = TWO_PI * res.frequencies_hz_full[1:3] * 1j
    assert_allclose(res.frequencies_hz[1:], res.frequencies_hz_full[1:3], rtol=0,
                    atol=2 * eigenvalue_accuracy(plant.A, lam).max() / TWO_PI)
    assert res.frequencies_hz[0] == res.frequencies_hz_full[0] == 0.0


def test_plot_is_a_bode_figure_with_full_and_reduced():
    res = modal_truncation(plant_of(chain(6)), 4, band_hz=(0.0, 100.0))
    fig = res.plot()
    assert isinstance(fig, Figure)
    mag, phase = fig.axes
    assert len(mag.lines) == 2 * len(res.full.outputs) and mag.get_xscale() == "log"


def test_error_metrics_of_identical_plants_are_zero():
    plant = plant_of(chain(6, grounded=False))
    m = error_metrics(plant, plant, band_hz=(0.0, 50.0))
    assert m.hinf_error == 0.0 and m.dc_gain_error == 0.0 and m.band_max_error == 0.0


# --------------------------------------------------------------------------- properties
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(3, 9), seed=st.integers(0, 10_000), grounded=st.booleans(), data=st.data())
def test_properties_dc_kept_and_bound_respected_on_random_chains(n, seed, grounded, data):
    plant = plant_of(chain(n, grounded=grounded, seed=seed))
    rigid = spectral_split(plant, marginal=True).rigid.n
    order = data.draw(st.integers(max(rigid, 1), plant.n_states))
    mod = modal_truncation(plant, order)
    # random chains (mass ratio <= 1.5, stiffness ratio <= 1.5, n <= 9): κ(A) of their static solve <= ~1e3:
    # rounding ~1e-13, 1e-8 (1e-7 for singular perturbation, which solves in the balanced coordinates: κ up to
    # 1e5)
    assert mod.metrics.dc_gain_relative_error is None or mod.metrics.dc_gain_relative_error < 1e-8
    bt = balanced_truncation(plant, order)
    round_off = 1e-9 * np.max(np.abs(bt.metrics.full_response))  # order == n: bound 0, error round-off
    assert bt.hinf_error <= bt.error_bound * (1 + 1e-6) + round_off
    spa = balanced_truncation(plant, order, match_dc=True)
    assert spa.metrics.dc_gain_relative_error is None or spa.metrics.dc_gain_relative_error < 1e-7
