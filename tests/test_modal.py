"""sicomat.mechanics.modal.modal_analysis: frequencies, damping ratios and mode shapes against closed forms."""

from __future__ import annotations

import json
import math
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.linalg
from matplotlib.figure import Figure
from numpy.testing import assert_allclose

from sicomat import ChainSpec, LumpedSpec, build_mechanics, load_model, modal_analysis
from sicomat.robotics.lowering import axis_mechanics

EXAMPLES_DIR = Path(__file__).resolve().parents[1] / "examples"
EXAMPLES = sorted(p.stem for p in EXAMPLES_DIR.glob("*.toml"))
TWO_PI = 2 * math.pi


def _modal(name):
    mech = axis_mechanics(load_model(EXAMPLES_DIR / f"{name}.toml"))   # a robot's first axis: its linearisation
    return mech, modal_analysis(mech)


# --------------------------------------------------------------------------- closed forms
def test_two_mass_free_free_chain():
    m1, m2, k = 3.0, 5.0, 1.0e6
    res = modal_analysis(build_mechanics(ChainSpec(type="chain", masses=[m1, m2], stiffnesses=[k])))
    assert [m.rigid for m in res.modes] == [True, False]
    rigid, flex = res.modes
    assert rigid.undamped_hz == 0.0 and rigid.frequency_hz == 0.0 and rigid.damping_ratio == 0.0
    assert res.undamped_hz[0] == 0.0
    f = math.sqrt(k * (m1 + m2) / (m1 * m2)) / TWO_PI
    # undamped values are singular values of diag(√k) G M^(-1/2), absolute accuracy ~eps·ω_max (modal.py), here
    # ω = ω_max: a few eps relative (1e-12). Damped ones are poles of the state matrix by dgeev, which balances
    # it: for an oscillator the balanced matrix is nearly normal with norm ~ω, so a pole is known to a few eps
    # relative too; 1e-10 leaves room for the pole-to-mode matching and the shapes' ratios (shape components are
    # O(1), normalised to an exact +1)
    assert_allclose(flex.undamped_hz, f, rtol=1e-12)
    assert_allclose(flex.frequency_hz, f, rtol=1e-10)
    assert_allclose(flex.damping_ratio, 0.0, atol=1e-12)
    # shapes: rigid translation (1, 1); flexible mode with momentum balance m1 x1 = -m2 x2
    assert_allclose([rigid.shape["m1"], rigid.shape["m2"]], [1.0, 1.0], rtol=1e-12)
    assert_allclose(flex.shape["m1"] / flex.shape["m2"], -m2 / m1, rtol=1e-10)
    assert res.n_rigid == 1


def test_two_mass_grounded_chain_quadratic_formula():
    m1, m2, k1, k2 = 2.0, 0.5, 3.0e5, 8.0e4
    res = modal_analysis(build_mechanics(ChainSpec(type="chain", masses=[m1, m2], stiffnesses=[k2],
                                                   ground_stiffness=k1)))
    # det(K - w^2 M) = m1 m2 w^4 - (m1 k2 + m2 (k1 + k2)) w^2 + k1 k2 = 0
    a, b, c = m1 * m2, -(m1 * k2 + m2 * (k1 + k2)), k1 * k2
    disc = math.sqrt(b * b - 4 * a * c)
    w2 = sorted([(-b - disc) / (2 * a), (-b + disc) / (2 * a)])
    assert res.n_rigid == 0
    # ω_max/ω_min ≈ 3: SVD accuracy eps·ω_max gives ~1e-15 relative (1e-12); poles after balancing 1e-10, as
    # above
    assert_allclose(res.undamped_hz, np.sqrt(w2) / TWO_PI, rtol=1e-12)
    assert_allclose(res.frequencies_hz, np.sqrt(w2) / TWO_PI, rtol=1e-10)


@pytest.mark.parametrize("via", ["coupling", "friction"])
def test_lightly_damped_oscillator(via):
    m, k, c = 2.0, 800.0, 4.0
    links = {"couplings": {"k": {"between": ["m", "ground"], "stiffness": k,
                                 **({"damping": c} if via == "coupling" else {})}}}
    if via == "friction":
        links["frictions"] = {"f": {"between": ["m", "ground"], "viscous": c}}
    res = modal_analysis(build_mechanics(LumpedSpec(bodies={"m": {"mass": m}}, **links)))
    (mode,) = res.modes
    wn = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    # one oscillator: the balanced 2×2 state matrix's poles to a few eps; ζ and ω_d from them in a few
    # roundings: 1e-10 (1e-12 for the undamped value)
    assert_allclose(mode.damping_ratio, zeta, rtol=1e-10)
    assert_allclose(mode.frequency_hz, wn / TWO_PI, rtol=1e-12)
    assert_allclose(mode.undamped_hz, wn / TWO_PI, rtol=1e-12)
    assert_allclose(mode.damped_frequency_hz, wn * math.sqrt(1 - zeta ** 2) / TWO_PI, rtol=1e-10)
    assert not mode.rigid


def test_overdamped_oscillator_keeps_natural_frequency():
    # roots l1, l2 of m s^2 + c s + k: sqrt(l1 l2) = wn, -(l1 + l2) / (2 wn) = zeta > 1
    m, k, c = 1.0, 100.0, 60.0
    res = modal_analysis(build_mechanics(LumpedSpec(
        bodies={"m": {"mass": m}},
        couplings={"k": {"between": ["m", "ground"], "stiffness": k, "damping": c}})))
    (mode,) = res.modes
    # overdamped: ω_n = √(l1 l2) and ζ from two real poles (κ ~ 1 after balancing): a few eps; 1e-10
    assert_allclose(mode.frequency_hz, math.sqrt(k / m) / TWO_PI, rtol=1e-10)
    assert_allclose(mode.damping_ratio, c / (2 * math.sqrt(k * m)), rtol=1e-10)
    assert mode.damped_frequency_hz == 0.0


def test_overdamped_soft_mode_beside_a_stiff_one():
    # Body a (1 kg) on a 1 N/m spring and a 1e4 N*s/m damper to the ground, body b (1 g) on a
    # 1e8 N/m spring to a. The soft mode (a and b together) is heavily overdamped: its slow real
    # pole (about -k/c = -1e-4 rad/s) is tiny next to the stiff mode's |lambda| ~ 3e5 rad/s.
    ma, mb, k, c, kb = 1.0, 1e-3, 1.0, 1e4, 1e8
    spec = LumpedSpec(bodies={"a": {"mass": ma}, "b": {"mass": mb}},
                      couplings={"g": {"between": ["a", "ground"], "stiffness": k},
                                 "k": {"between": ["b", "a"], "stiffness": kb}},
                      frictions={"c": {"between": ["a", "ground"], "viscous": c}})
    res = modal_analysis(build_mechanics(spec))
    soft, stiff = res.modes
    # undamped 2-DOF problem: m_a m_b w^4 - (m_a k_b + m_b (k + k_b)) w^2 + k k_b = 0
    a2, b2, c2 = ma * mb, -(ma * kb + mb * (k + kb)), k * kb
    disc = math.sqrt(b2 * b2 - 4 * a2 * c2)
    w2_high = (-b2 + disc) / (2 * a2)
    w2_low = c2 / (a2 * w2_high)                  # product of the roots, no cancellation
    # SVD accuracy eps·ω_max = 7e-11 rad/s absolute against ω_soft ≈ 1 rad/s: 7e-11 relative; 1e-6 for the
    # damped values: merging a and b is exact to O(ω_soft²/ω_stiff²) = 1e-11, and the slow pole (-1e-4 rad/s
    # beside 3e5 rad/s) has a normwise first-order bound of 1e-5 even after balancing, but dgeev on this graded
    # matrix reaches 2e-12 on every OpenBLAS kernel tried (Prescott to SkylakeX): the 1e-6 rests on that
    # grading. The stiff mode: eps·ω_max/ω = a few eps (1e-9)
    assert_allclose(soft.undamped_hz, math.sqrt(w2_low) / TWO_PI, rtol=1e-6)
    assert_allclose(stiff.undamped_hz, math.sqrt(w2_high) / TWO_PI, rtol=1e-9)
    # soft mode: a and b as one 1.001 kg body on k and c
    m = ma + mb
    assert_allclose(soft.frequency_hz, math.sqrt(k / m) / TWO_PI, rtol=1e-6)
    assert_allclose(soft.damping_ratio, c / (2 * math.sqrt(k * m)), rtol=1e-6)


def test_wide_spread_grounded_chain_soft_modes():
    # An undamped grounded chain (all values inside the ranges of test_mechanics' properties):
    # ground -100 N/m- 10 t -1e12 N/m- 1 g -100 N/m- 100 kg. No mode is rigid.
    masses, ks, k0 = [1e4, 1e-3, 100.0], [1e12, 100.0], 100.0
    mech = build_mechanics(ChainSpec(type="chain", masses=masses, stiffnesses=ks, ground_stiffness=k0))
    res = modal_analysis(mech)
    assert res.n_rigid == 0
    # Peer 1: python-control's poles of the undamped plant are +-j w.
    wn, _, poles = control.damp(mech.state_space().to_control(), doprint=False)
    wn_ref = np.sort(wn[poles.imag > 0])
    # Peer 2 (soft modes): the compliance of a grounded chain is exact in closed form,
    # F[i, j] = sum(1 / k_l, l <= min(i, j)) (springs in series from the ground), and the
    # largest eigenvalues of M^1/2 F M^1/2 are 1 / w^2 of the softest modes, to full precision.
    c = np.cumsum([1.0 / k0] + [1.0 / k for k in ks])
    m_half = np.sqrt(masses)
    mu = np.linalg.eigvalsh(m_half[:, None] * np.minimum.outer(c, c) * m_half[None, :])
    w_soft = np.sqrt(1.0 / mu[::-1][:2])
    # python-control's damp (eig of the unbalanced plant) against the closed-form compliance: the soft modes of
    # a chain with a 1e12/100 stiffness spread are ill-conditioned for eig (first-order bound up to 0.3
    # relative); what we check is the package (SVD: absolute eps·ω_max = 7e-9 rad/s, i.e. 7e-8 relative at 0.1
    # rad/s) against them; 1e-6 is the peers' agreement on every kernel tried (observed 2e-16)
    assert_allclose(wn_ref[:2], w_soft, rtol=1e-6)        # the two peers agree
    # The result: no flexible mode at 0 Hz, every frequency as the peers say, JSON-clean.
    assert np.all(res.undamped_hz > 0.0), res.undamped_hz
    assert_allclose(TWO_PI * res.frequencies_hz, wn_ref, rtol=1e-6)
    assert_allclose(TWO_PI * res.undamped_hz, wn_ref, rtol=1e-6)
    assert all(math.isfinite(m.participation) for m in res.modes)
    json.dumps(res.to_dict(), allow_nan=False)


def test_paper_2m1s_flexible_frequency():
    mech, res = _modal("paper_2m1s")
    # one spring on the stretch r*theta - x: w^2 = k (r^2 / J + 1 / M)
    J, M = np.diag(mech.mass)
    k = 2.5e7
    r = 0.025 / (0.060 / 0.030)   # R_pig / n_b
    # one flexible mode, the SVD's largest value: a few eps
    assert_allclose(res.undamped_hz, [0.0, math.sqrt(k * (r * r / J + 1 / M)) / TWO_PI], rtol=1e-12)


# --------------------------------------------------------------------------- mode shapes
@pytest.mark.parametrize("name", EXAMPLES)
def test_mode_shapes_normalised_and_eigenvectors(name):
    mech, res = _modal(name)
    for mode in res.modes:
        phi = np.array([mode.shape[d] for d in mech.dof_names])
        assert np.max(np.abs(phi)) == 1.0
        assert mode.shape[mode.dominant_dof] == 1.0          # the largest component is +1
        w2 = (TWO_PI * mode.undamped_hz) ** 2
        residual = mech.stiffness @ phi - w2 * mech.mass @ phi
        # K φ − ω² M φ for shapes with components <= 1: the residual of a backward-stable SVD is ~eps·‖K‖ per
        # entry, amplified by the shapes' conditioning (ω_max²/ω² for the softest mode beside the 1e12 N/m
        # spring: up to 1e6): 1e-8 of max|K|
        assert_allclose(residual, 0.0, atol=1e-8 * np.abs(mech.stiffness).max())
    assert res.shapes.shape == (mech.n, mech.n)


# --------------------------------------------------------------------------- the paper's 5M4S example
def test_paper_5m4s_first_mode_near_80_hz():
    mech, res = _modal("paper_5m4s")
    assert res.n_rigid == 1
    assert len([m for m in res.modes if m.rigid]) == 1
    first = next(m for m in res.modes if not m.rigid)
    # Fig. 8: "a first mode near f_meca = 80 Hz"
    assert 75.0 <= first.frequency_hz <= 85.0
    assert 75.0 <= first.undamped_hz <= 85.0
    assert res.f_meca_hz is not None and 75.0 <= res.f_meca_hz <= 85.0


def test_paper_5m4s_frequencies_from_independent_eigensolve():
    _, res = _modal("paper_5m4s")
    # M and K written from the paper's printed parameters (the example's naming of the triples)
    m = np.array([3667.0, 232.0, 92.305, 270.2, 0.008])  # structure, secondary, primary, load, head
    K = np.zeros((5, 5))
    K[0, 0] += 1e9
    for i, j, k in [(1, 0, 1e12), (3, 2, 3.8e8), (4, 2, 1e7)]:
        K[np.ix_([i, j], [i, j])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    w2 = np.clip(scipy.linalg.eigvalsh(K, np.diag(m)), 0.0, None)
    w2_max = w2.max()
    # atol: eigvalsh gets ω² to ~eps·ω²_max (×1e3 for the generalized problem's Cholesky and the order); rtol
    # 1e-8: the SVD's ω to eps·ω_max, squared
    assert_allclose((TWO_PI * res.undamped_hz) ** 2, np.sort(w2), rtol=1e-8,
                    atol=1e3 * np.finfo(float).eps * w2_max)


@pytest.mark.parametrize("name", EXAMPLES)
def test_undamped_hz_ascending_rigid_first(name):
    _, res = _modal(name)
    f = res.undamped_hz
    assert np.all(np.diff(f) >= 0)
    rigid = [m.rigid for m in res.modes]
    assert rigid == sorted(rigid, reverse=True)
    assert np.all(f[: res.n_rigid] == 0.0)
    assert np.all(f[res.n_rigid:] > 0.0)


def test_undamped_hz_ascending_when_damping_reorders_modes():
    # Two grounded oscillators, 1.59 Hz (a) and 3.18 Hz (b); b is tied to a heavy free mass by a
    # strong damper, which drags its damped pole pair down to ~0.32 Hz. The documented contract
    # (ModalResult.undamped_hz: "ascending") must still hold.
    spec = LumpedSpec(bodies={"a": {"mass": 1.0}, "b": {"mass": 1.0}, "f": {"mass": 100.0}},
                      couplings={"ka": {"between": ["a", "ground"], "stiffness": 100.0},
                                 "kb": {"between": ["b", "ground"], "stiffness": 400.0}},
                      frictions={"c": {"between": ["f", "b"], "viscous": 1e4}})
    res = modal_analysis(build_mechanics(spec))
    assert res.n_rigid == 1
    # ω_max/ω_min = 2: the SVD's eps·ω_max is a few eps relative
    assert_allclose(np.sort(res.undamped_hz), [0.0, 10 / TWO_PI, 20 / TWO_PI], rtol=1e-12)
    assert np.all(np.diff(res.undamped_hz) >= 0), res.undamped_hz


def test_rigid_only_model():
    _, res = _modal("rigid_1m")
    (mode,) = res.modes
    assert mode.rigid and mode.undamped_hz == 0.0 and mode.frequency_hz == 0.0
    assert res.f_meca_hz is None


# --------------------------------------------------------------------------- outputs
@pytest.mark.parametrize("name", EXAMPLES)
def test_to_dict_is_json(name):
    mech, res = _modal(name)
    data = res.to_dict()
    text = json.dumps(data, allow_nan=False)
    back = json.loads(text)
    assert back["dofs"] == list(mech.dof_names)
    assert back["undamped_hz"] == [float(f) for f in res.undamped_hz]
    assert len(back["modes"]) == mech.n
    assert back["f_meca_hz"] == res.f_meca_hz
    for mode, d in zip(res.modes, back["modes"]):
        assert d["rigid"] == mode.rigid
        assert d["shape"] == mode.shape


@pytest.mark.parametrize("name", ["paper_5m4s", "rigid_1m"])
def test_plot_returns_a_figure(name):
    _, res = _modal(name)
    fig = res.plot()
    assert isinstance(fig, Figure)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == len(res.modes)


def test_a_split_rigid_double_pole_is_not_taken_for_a_flexible_mode():
    # Found by the passivity guard (a damping ratio of -2e-8 at 1.8e-8 Hz): a free chain whose
    # rigid double pole rounding splits into +-1.1e-7 j, beside a damper that makes one mode
    # overdamped (real poles -198.7 and -1.01). Oracle: the state matrix's poles themselves,
    # paired as the modes are (complex pairs: |lambda|; the real pair: sqrt(l1 l2), zeta from their sum).
    k = 10 ** 2.5
    mech = build_mechanics(ChainSpec(type="chain", masses=[1, 1, 1, 10, 1, 1], stiffnesses=[k, 100, k, 100, 100],
                                     dampings=[0, 0, 0, 0, 100]))
    res = modal_analysis(mech)
    poles = np.linalg.eigvals(mech.state_space().A)
    poles = poles[np.abs(poles) > 1e-3]                        # the rigid pair (|lambda| ~ 1e-7) apart
    pairs = np.sort(np.abs(poles[poles.imag > 0]))
    real = np.sort(poles[np.abs(poles.imag) == 0].real)
    assert real.size == 2                                      # exactly one overdamped mode
    expected = np.sort(np.append(pairs, np.sqrt(real[0] * real[1])))
    flexible = [m for m in res.modes if not m.rigid]
    # eigenvalues of this well-scaled matrix (|A| ~ 400) are accurate to ~1e-13 relative: 1e-9 is loose
    assert_allclose(np.sort([TWO_PI * m.frequency_hz for m in flexible]), expected, rtol=1e-9)
    assert all(m.damping_ratio >= 0 for m in flexible)
    over = max(flexible, key=lambda m: m.damping_ratio)
    assert_allclose(over.damping_ratio, -(real[0] + real[1]) / (2 * np.sqrt(real[0] * real[1])), rtol=1e-9)
