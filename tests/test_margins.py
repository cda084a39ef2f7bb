"""Stability margins (sicomat.frequency.margins) against closed forms and python-control; Bode/Nichols smoke tests."""

from __future__ import annotations

import json
import warnings

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure
from numpy.testing import assert_allclose

from sicomat.errors import ModelError
from sicomat.plots.frequency import bode_figure, nichols_figure
from sicomat.lti.response import FrequencyResponse
from sicomat.frequency.margins import Margins, closed_loop, sensitivity, stability_margins
from sicomat.plots.base import save_figure


def loop(omega, values, **kwargs) -> FrequencyResponse:
    return FrequencyResponse(np.asarray(omega, dtype=float), np.asarray(values, dtype=complex),
                             open_loop=True, **kwargs)


def wrap180(angle_deg):
    return angle_deg - 360.0 * np.ceil((angle_deg - 180.0) / 360.0)


DENSE = np.logspace(-3, 3, 30001)


# --------------------------------------------------------------------------- textbook closed forms
@pytest.mark.parametrize("K", [0.5, 2.0, 4.0, 8.0])
def test_third_order_loop(K):
    # L = K / (s (s+1) (s+2)). At s = jω the denominator is jω(2 − ω² + 3jω) = −3ω² + jω(2 − ω²):
    # real (L on the negative real axis) at ω² = 2, where it is −6, so L = −K/6:
    #   ω_pc = √2, GM = 20 log10(6/K) dB.
    # |L|² = K² / (ω² ((2 − ω²)² + 9ω²)) = 1  ⇔  u³ + 5u² + 4u − K² = 0 with u = ω² (one positive root);
    # ∠L = −90° − atan ω − atan(ω/2), so PM = 90° − atan ω_gc − atan(ω_gc/2) (deg).
    s = 1j * DENSE
    m = stability_margins(loop(DENSE, K / (s * (s + 1) * (s + 2))))
    roots = np.roots([1.0, 5.0, 4.0, -K**2])
    # the positive root of a cubic with simple roots: its imaginary part is rounding (~eps·|u|), 1e-12 separates
    # it from the complex pair
    u = roots[(np.abs(roots.imag) < 1e-12) & (roots.real > 0)].real
    assert u.size == 1
    w_gc = float(np.sqrt(u[0]))
    pm = 90.0 - np.degrees(np.arctan(w_gc) + np.arctan(w_gc / 2))
    # tolerance origin for the DENSE grid (Δ = 6 ln10/30000 = 4.6e-4 in ln ω): crossovers and values come from
    # local cubics, error ~Δ⁴/24·|y''''| ≈ 2e-15·|y''''| for these smooth loops; 1e-9 leaves six orders for the
    # derivatives, 1e-8 where a value divides by a crossover (delay margin)
    assert_allclose(m.phase_crossover_rad_s, np.sqrt(2.0), rtol=1e-9)
    assert_allclose(m.gain_margin_db, 20 * np.log10(6.0 / K), rtol=1e-9, atol=1e-9)
    assert_allclose(m.gain_crossover_rad_s, w_gc, rtol=1e-9)
    assert_allclose(m.phase_margin_deg, pm, rtol=1e-9, atol=1e-8)
    assert_allclose(m.delay_margin_s, np.radians(pm % 360.0) / w_gc, rtol=1e-8)     # divides by a crossover
    assert m.gain_crossovers.size == 1 and m.phase_crossovers.size == 1
    assert m.stable_hint is (K < 6.0)            # Routh: s³ + 3s² + 2s + K stable for K < 6
    assert np.isnan(m.delay_margin_samples)


@pytest.mark.parametrize("wc, tau", [(1.0, 0.2), (1.0, 0.5), (10.0, 0.05), (3.0, 0.4)])
def test_integrator_with_pure_delay(wc, tau):
    # L = (ωc/s) e^{−sτ}: |L| = ωc/ω, so the gain crossover is exactly ωc; ∠L = −90° − ωτ (rad → deg).
    #   PM = 90° − ωc τ·180/π,   delay margin = PM_rad/ωc = π/(2ωc) − τ.
    # Phase crossovers where ωτ = π/2 + 2πk: ω_k = (π/2 + 2πk)/τ, with |L| = ωc/ω_k, so
    #   GM_k = 20 log10(ω_k/ωc) ; the smallest is k = 0: GM = 20 log10(π/(2 ωc τ)).
    omega = np.logspace(-2, 3, 40001)
    s = 1j * omega
    m = stability_margins(loop(omega, wc / s * np.exp(-s * tau)))
    # grid Δ = 5 ln10/40000 = 2.9e-4: local-cubic error ~Δ⁴/24 ≈ 3e-16 relative to the derivatives; 1e-9 (1e-8
    # for the quantities that divide or take a log of a small difference)
    assert_allclose(m.gain_crossover_rad_s, wc, rtol=1e-9)
    assert_allclose(m.phase_margin_deg, 90.0 - np.degrees(wc * tau), rtol=1e-9)
    assert_allclose(m.delay_margin_s, np.pi / (2 * wc) - tau, rtol=1e-8)
    assert_allclose(m.gain_margin_db, 20 * np.log10(np.pi / (2 * wc * tau)), rtol=1e-8)
    assert_allclose(m.phase_crossover_rad_s, np.pi / (2 * tau), rtol=1e-9)   # the local-cubic bound above
    k = np.arange(0, 1000)
    w_k = (np.pi / 2 + 2 * np.pi * k) / tau
    w_k = w_k[w_k < omega[-1]]
    # up to 1e3 rad/s the phase ωτ turns by up to 0.15 rad per grid interval: the cubic error grows as (Δ·ωτ)⁴,
    # 1e-8 (1e-7 for the GMs)
    assert_allclose(m.phase_crossovers, w_k, rtol=1e-8)             # all of them, none spurious
    assert_allclose(m.gain_margins_db, 20 * np.log10(w_k / wc), rtol=1e-7)


@pytest.mark.parametrize("K, tau", [(0.5, 0.1), (0.8, 1.0)])
def test_pure_delay_below_unity(K, tau):
    # L = K e^{−sτ}, K < 1: |L| = K never crosses 1 (PM = inf, no delay margin); L = −K at
    # ωτ = π(2k+1), so GM = −20 log10 K there; |1 + L| ≥ 1 − K with equality at ω = π/τ.
    omega = np.linspace(0.1, 20.0 / tau, 20001)
    m = stability_margins(loop(omega, K * np.exp(-1j * omega * tau)))
    assert m.gain_crossovers.size == 0
    assert m.phase_margin_deg == np.inf and np.isnan(m.gain_crossover_rad_s) and m.delay_margin_s == np.inf
    # |L| = K exactly at every point; crossovers on a uniform grid of spacing 1e-3/τ: cubic error ~1e-13
    # relative, 1e-9
    assert_allclose(m.gain_margin_db, -20 * np.log10(K), rtol=1e-9)
    assert_allclose(m.phase_crossover_rad_s, np.pi / tau, rtol=1e-9)
    w_k = np.pi * (2 * np.arange(10) + 1) / tau
    assert_allclose(m.phase_crossovers, w_k[w_k < omega[-1]], rtol=1e-9)
    assert_allclose(m.modulus_margin, 1.0 - K, rtol=1e-9)
    # a flat minimum: its location is known to ~sqrt(value error / curvature), about 1e-5 relative here; 1e-4
    assert_allclose(m.modulus_margin_rad_s, np.pi / tau, rtol=1e-4)
    d = m.to_dict()
    assert d["phase_margin_deg"] is None and d["gain_crossover_rad_s"] is None
    json.dumps(d, allow_nan=False)


def test_no_phase_crossover_gives_infinite_gain_margin():
    # L = 1/(s(s+1)): the phase tends to −180° without reaching it.
    s = 1j * DENSE
    m = stability_margins(loop(DENSE, 1.0 / (s * (s + 1))))
    assert m.gain_margin_db == np.inf and np.isnan(m.phase_crossover_rad_s)
    assert m.phase_crossovers.size == 0 and m.stable_hint
    # |L| = 1 ⇔ ω⁴ + ω² − 1 = 0 ⇔ ω² = (√5 − 1)/2; PM = 90° − atan ω
    w = np.sqrt((np.sqrt(5) - 1) / 2)
    # DENSE grid: see test_third_order_loop
    assert_allclose(m.phase_margin_deg, 90.0 - np.degrees(np.arctan(w)), rtol=1e-9)


def test_modulus_margin_closed_form():
    # L = K/(s(s+1)). With u = ω²: |1 + L|² = |K − u + jω|² / |−u + jω|² = ((K − u)² + u)/(u² + u).
    # d/du = 0  ⇔  (2u + 1 − 2K)(u² + u) = (u² + (1 − 2K)u + K²)(2u + 1)  ⇔  2u² − 2Ku − K = 0,
    # so u* = (K + √(K² + 2K))/2 and the modulus margin is √(((K − u*)² + u*)/(u*² + u*)) at √u*.
    for K in (0.5, 1.0, 5.0, 20.0):
        s = 1j * DENSE
        m = stability_margins(loop(DENSE, K / (s * (s + 1))))
        u = (K + np.sqrt(K**2 + 2 * K)) / 2
        # the minimum's value from the refined local cubics: second order in the location error, ~1e-13
        assert_allclose(m.modulus_margin, np.sqrt(((K - u) ** 2 + u) / (u**2 + u)), rtol=1e-9)
        assert_allclose(m.modulus_margin_rad_s, np.sqrt(u), rtol=1e-4)   # a flat minimum: looser
        S = sensitivity(m.frf)
        # the largest grid value of |S| misses the true peak by (Δ/2)²·curvature/2 ≈ 3e-8 relative (curvature ~1
        # in ln ω); 1e-6
        assert_allclose(1.0 / np.max(np.abs(S.response)), m.modulus_margin, rtol=1e-6)


@pytest.mark.parametrize("wc", [0.3, 1.0, 50.0])
def test_bandwidth_of_integrator_loop(wc):
    # L = ωc/s: T = ωc/(s + ωc), |T|² = ωc²/(ω² + ωc²). The reference is |T| at the lowest grid
    # frequency ω0: |T|² = |T(ω0)|²/2 ⇔ ω² = ωc² + 2ω0² (→ ωc, the usual answer, as ω0 → 0).
    s = 1j * DENSE
    m = stability_margins(loop(DENSE, wc / s))
    w0 = DENSE[0]
    # the −3.01 dB crossing from local cubics on DENSE (see above), and the closed form with the grid's ω0;
    # against ωc alone the difference is ω0²/ωc² <= 1.1e-5 (ωc >= 0.3): 1e-4; ∠(ωc/jω) = −90° at every point, so
    # PM is 90 up to rounding: 1e-12
    assert_allclose(m.bandwidth_rad_s, np.sqrt(wc**2 + 2 * w0**2), rtol=1e-8)
    assert_allclose(m.bandwidth_rad_s, wc, rtol=1e-4)
    assert_allclose(m.phase_margin_deg, 90.0, rtol=1e-12)
    assert m.gain_margin_db == np.inf


def test_bandwidth_is_relative_to_the_low_frequency_value():
    # L = K/(s + 1): T = K/(s + 1 + K), |T|² = K²/((1 + K)² + ω²), |T(0)| = K/(1 + K) < 1 (type 0).
    # |T|² = |T(ω0)|²/2 ⇔ ω² = (1 + K)² + 2ω0²: about 1 + K, relative to the static value, not to 1.
    K = 3.0
    s = 1j * DENSE
    m = stability_margins(loop(DENSE, K / (s + 1)))
    # DENSE grid: local-cubic error, see above
    assert_allclose(m.bandwidth_rad_s, np.sqrt((1.0 + K) ** 2 + 2 * DENSE[0] ** 2), rtol=1e-8)
    assert m.gain_crossovers.size == 1     # |L| = 1 at ω = √(K² − 1)
    assert_allclose(m.gain_crossover_rad_s, np.sqrt(K**2 - 1), rtol=1e-9)


def test_bandwidth_not_reached_is_infinite():
    omega = np.logspace(-2, 0, 100)
    m = stability_margins(loop(omega, 1e3 / (1j * omega)))
    assert m.bandwidth_rad_s == np.inf and m.to_dict()["bandwidth_rad_s"] is None


# --------------------------------------------------------------------------- resonances
def resonant_loop(omega, wc, wn, zeta, tau):
    s = 1j * omega
    return wc / s * np.exp(-s * tau) * wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)


def test_lightly_damped_resonance_three_crossovers():
    # L = (ωc/s) e^{−sτ} ωn²/(s² + 2ζωn s + ωn²), ωc = 1, ωn = 10, ζ = 0.01: the resonance peak
    # (|L(jωn)| ≈ ωc/(2ζωn) = 5) crosses 0 dB twice more. |L| does not depend on τ:
    #   |L|² = 1  ⇔  u³ + (4ζ² − 2)ωn² u² + ωn⁴ u − ωc² ωn⁴ = 0  (u = ω²): three positive roots.
    # ∠L = −90° − ωτ − atan2(2ζωnω, ωn² − ω²) (rad → deg), continuous from −90°.
    # τ is chosen so that ∠L(ω3) = −500°: PM3 = 40° at the highest crossover, the worst one (the
    # first has ~67°, the second sits on the far side of −540°: PM ≈ −139°, |PM| large).
    wc, wn, zeta = 1.0, 10.0, 0.01
    roots = np.roots([1.0, (4 * zeta**2 - 2) * wn**2, wn**4, -(wc**2) * wn**4])
    # three simple real roots of a cubic (condition <= 1e3 for ζ = 0.01): imaginary parts are rounding, << 1e-9
    assert np.all(np.abs(roots.imag) < 1e-9) and np.all(roots.real > 0)
    w_all = np.sort(np.sqrt(roots.real))
    psi = np.degrees(np.arctan2(2 * zeta * wn * w_all, wn**2 - w_all**2))
    tau = np.radians(410.0 - psi[2]) / w_all[2]
    phase = -90.0 - np.degrees(w_all * tau) - psi
    pm = wrap180(180.0 + phase)
    # τ was solved for PM3 = 40° in closed form: rounding only
    assert np.argmin(np.abs(pm)) == 2 and abs(pm[2] - 40.0) < 1e-9

    omega = np.logspace(-1, 2, 60001)
    m = stability_margins(loop(omega, resonant_loop(omega, wc, wn, zeta, tau)))
    # grid Δ = 1.15e-4 in ln ω, but the resonance's features are 2ζ = 0.02 wide: the cubic error scales as
    # (Δ/2ζ)⁴ ≈ 1e-9 of the phase swing (180°): ~1e-6 deg, 1e-5 deg for phases; crossovers sit where |L| is
    # smooth (1e-8); delay margins divide by them (1e-6); the phase-crossover checks evaluate the closed form at
    # our crossovers (1e-6 rad, 1e-5 dB)
    assert_allclose(m.gain_crossovers, w_all, rtol=1e-8)
    assert_allclose(m.phase_margins_deg, pm, atol=1e-5)
    assert_allclose(m.phase_margin_deg, 40.0, atol=1e-5)
    assert_allclose(m.gain_crossover_rad_s, w_all[2], rtol=1e-8)
    dm = np.radians(np.mod(pm, 360.0)) / w_all
    assert_allclose(m.delay_margins_s, dm, rtol=1e-6)        # divide by crossovers (above): 1e-6
    assert_allclose(m.delay_margin_s, dm.min(), rtol=1e-6)
    # every phase crossover found is one (closed-form phase ≡ −180°) and its GM is −20 log10|L| there
    L_pc = resonant_loop(m.phase_crossovers, wc, wn, zeta, tau)
    assert_allclose(np.angle(-L_pc), 0.0, atol=1e-6)
    assert_allclose(m.gain_margins_db, -20 * np.log10(np.abs(L_pc)), atol=1e-5)
    frame = m.to_pandas()
    assert list(frame["kind"]).count("gain") == 3
    assert frame.loc[frame["reported"] & (frame["kind"] == "gain"), "omega"].item() == m.gain_crossover_rad_s


# --------------------------------------------------------------------------- python-control
def _tf(num, den):
    return control.tf(num, den)


RATIONAL = {
    "third order": _tf([2.0], [1.0, 3.0, 2.0, 0.0]),
    "third order, unstable": _tf([8.0], [1.0, 3.0, 2.0, 0.0]),
    "lead": _tf(np.polymul([50.0], [1.0, 1.0]), np.polymul([1.0, 0.0], np.polymul([1.0, 10.0], [1.0, 0.2]))),
    "resonance above 0 dB": _tf([100.0], [1.0, 0.2, 100.0, 0.0]),
    "PI + mass + mode": _tf(np.polymul([30.0, 300.0], [400.0**2]),
                            np.polymul([1.0, 0.0, 0.0], [1.0, 2 * 0.05 * 400.0, 400.0**2])),
    "conditionally stable": _tf(np.polymul([100.0], np.polymul([1.0, 1.0], [1.0, 1.0])), [1.0, 10.0, 0.0, 0.0, 0.0]),
    "fourth order": _tf([5.0], np.polymul([1.0, 1.0], np.polymul([1.0, 1.0], [1.0, 2.0, 4.0]))),
}


@pytest.mark.parametrize("name", list(RATIONAL))
def test_against_python_control(name):
    sys = RATIONAL[name]
    omega = np.logspace(-3, 4, 40001)
    m = stability_margins(loop(omega, sys(1j * omega), name=name))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, sm, wpc, wgc, wms = control.stability_margins(sys)
        GM, PM, SM, W180, WC, WS = control.stability_margins(sys, returnall=True)
    gm_db = 20 * np.log10(gm) if np.isfinite(gm) else np.inf
    # python-control: crossovers are polynomial roots (~1e-12), but its modulus margin is a scipy minimisation
    # whose location at a flat minimum is known to ~1e-4; our grid (Δ = 4e-4, local cubics) is accurate to
    # ~1e-12 except the same flat minimum. 1e-3 is set by the oracle's minimiser and kept for all quantities
    # (any modelling error is O(1))
    assert_allclose(m.gain_margin_db, gm_db, rtol=1e-3, atol=1e-4)
    assert_allclose(m.phase_margin_deg, pm, rtol=1e-3, atol=1e-4)
    assert_allclose(m.modulus_margin, sm, rtol=1e-3)
    assert_allclose(m.modulus_margin_rad_s, wms, rtol=1e-3)
    if np.isfinite(wpc):
        assert_allclose(m.phase_crossover_rad_s, wpc, rtol=1e-3)     # the oracle's minimiser bound, above
    else:
        assert np.isnan(m.phase_crossover_rad_s)
    assert_allclose(m.gain_crossover_rad_s, wgc, rtol=1e-3)
    # all crossovers, not only the reported ones
    assert_allclose(m.gain_crossovers, np.sort(WC), rtol=1e-3)
    assert_allclose(m.phase_margins_deg, PM[np.argsort(WC)], rtol=1e-3, atol=1e-4)
    assert_allclose(m.phase_crossovers, np.sort(W180), rtol=1e-3)
    assert_allclose(m.gain_margins_db, 20 * np.log10(GM[np.argsort(W180)]), rtol=1e-3, atol=1e-4)


def test_coarse_grid_still_accurate():
    # 80 points over 4 decades: the cubic refinement keeps PM/GM within small tolerances.
    sys = RATIONAL["third order"]
    omega = np.logspace(-2, 2, 80)
    m = stability_margins(loop(omega, sys(1j * omega)))
    # 80 points over 4 decades: Δ = 0.117 in ln ω, local-cubic error Δ⁴/24·|y''''| ≈ 8e-6·|y''''| ≈ 1e-4 deg or
    # dB here: 1e-3 (reference values from python-control's polynomial roots, exact to 1e-12)
    assert_allclose(m.phase_margin_deg, 32.613097047774, atol=1e-3)
    assert_allclose(m.gain_margin_db, 20 * np.log10(3.0), atol=1e-3)
    assert_allclose(m.modulus_margin, 0.43246721408683, rtol=1e-3)


def test_crossover_exactly_on_a_grid_point_is_found_once():
    omega = np.logspace(-2, 2, 401)            # contains ω = 1 exactly
    assert np.any(omega == 1.0)
    m = stability_margins(loop(omega, 1.0 / (1j * omega)))
    assert m.gain_crossovers.size == 1
    # a crossover exactly on a grid point, and ∠(1/jω) = −90° exactly: rounding only
    assert_allclose(m.gain_crossover_rad_s, 1.0, rtol=1e-12)
    assert_allclose(m.phase_margin_deg, 90.0, rtol=1e-12)


# --------------------------------------------------------------------------- sampled loop
@pytest.mark.parametrize("K", [0.5, 1.0, 1.5])
def test_discrete_integrator(K):
    # L(z) = K/(z − 1) at z = e^{jθ}, θ = ωT: z − 1 = e^{jθ/2}·2j sin(θ/2), so
    #   L = K/(2 sin(θ/2)) · e^{−j(π/2 + θ/2)}.
    # |L| = 1 at sin(θc/2) = K/2: ω_gc = 2 asin(K/2)/T; ∠L = −90° − θc/2, so PM = 90° − asin(K/2) (deg);
    # delay margin = PM_rad/ω_gc = T (π/2 − asin(K/2))/(2 asin(K/2)) — in samples without the T.
    # ∠L = −180° only at θ = π (Nyquist), where L = −K/2: GM = 20 log10(2/K) at ω = π/T.
    # |1 + L|² = 1 − K + K²/(2(1 − cos θ)) is smallest at θ = π: modulus margin 1 − K/2 at π/T.
    # T = K/(z − 1 + K) = K/(z − a), a = 1 − K, |T|² = K²/(1 + a² − 2a cos θ). Relative to the lowest
    # grid frequency θ0: |T|² = |T(θ0)|²/2 ⇔ 1 + a² − 2a cos θ = 2(1 + a² − 2a cos θ0)
    #   ⇔ cos θ = (4a cos θ0 − 1 − a²)/(2a); for θ0 → 0, (1 + a² − 2K²)/(2a). No solution for
    #   K ≥ 1 (|T| ≥ 1/√2 up to Nyquist): bandwidth inf.
    T = 1e-3
    omega = np.logspace(0, np.log10(0.999 * np.pi / T), 4000)
    z = np.exp(1j * omega * T)
    m = stability_margins(loop(omega, K / (z - 1), sample_period=T, name="discrete integrator"))
    a = np.arcsin(K / 2)
    # grid Δ = ln(3138)/4000 = 2e-3 in ln ω: local-cubic error ~Δ⁴/24 ≈ 7e-13 relative to the derivatives: 1e-9
    # (1e-8 for the delay margins, which divide by the crossover); at π/T (phase crossover and modulus-margin
    # location, exact by construction: 1e-12) the values are extrapolated from the last grid point at 0.999π/T
    # with the even/odd symmetry, a second-order error in 0.001π: 1e-6
    assert_allclose(m.gain_crossover_rad_s, 2 * a / T, rtol=1e-9)
    assert_allclose(m.phase_margin_deg, 90.0 - np.degrees(a), rtol=1e-9)
    assert_allclose(m.delay_margin_samples, (np.pi / 2 - a) / (2 * a), rtol=1e-8)
    assert_allclose(m.delay_margin_s, T * (np.pi / 2 - a) / (2 * a), rtol=1e-8)
    assert_allclose(m.phase_crossover_rad_s, np.pi / T, rtol=1e-12)    # π/T by construction: rounding
    assert_allclose(m.gain_margin_db, 20 * np.log10(2 / K), rtol=1e-6)  # extrapolated from 0.999π/T: 1e-6
    assert_allclose(m.modulus_margin, 1 - K / 2, rtol=1e-6)             # the same extrapolation
    assert_allclose(m.modulus_margin_rad_s, np.pi / T, rtol=1e-12)      # π/T by construction
    a_ = 1.0 - K
    c = (4 * a_ * np.cos(omega[0] * T) - 1 - a_**2) / (2 * a_) if K != 1 else np.inf
    if abs(c) <= 1:
        # local cubic on this grid: see above
        assert_allclose(m.bandwidth_rad_s, np.arccos(c) / T, rtol=1e-8)
    else:
        assert m.bandwidth_rad_s == np.inf
    # python-control agrees on PM and modulus margin (its GM misses the crossing at z = −1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, pm, sm, _, wgc, _ = control.stability_margins(control.tf([K], [1.0, -1.0], T))
    # python-control on the discrete transfer function: polynomial roots on the unit circle, but its modulus
    # margin is a scipy minimisation (~1e-8 in value): 1e-6
    assert_allclose([m.phase_margin_deg, m.gain_crossover_rad_s, m.modulus_margin], [pm, wgc, sm], rtol=1e-6)


def test_sampled_grid_far_from_nyquist_adds_no_crossover():
    T = 1e-3
    omega = np.logspace(0, np.log10(0.5 * np.pi / T), 2000)
    m = stability_margins(loop(omega, 1.0 / (np.exp(1j * omega * T) - 1), sample_period=T))
    assert m.phase_crossovers.size == 0 and m.gain_margin_db == np.inf


# --------------------------------------------------------------------------- invariants, helpers, errors
@settings(max_examples=25, deadline=None)
@given(st.floats(min_value=0.05, max_value=20.0))
def test_gain_scaling_shifts_gain_margins(scale):
    # Scaling L by a positive constant moves no phase crossover and lowers every GM by 20 log10(scale).
    omega = np.logspace(-2, 2, 4001)
    s = 1j * omega
    L = 2.0 / (s * (s + 1) * (s + 2)) * np.exp(-0.3 * s)
    m1 = stability_margins(loop(omega, L))
    m2 = stability_margins(loop(omega, scale * L))
    # scaling by a positive constant leaves the phase bit-identical: the same crossovers up to rounding; the GMs
    # shift by 20 log10(scale) up to the rounding of the logs of values ~1e3: 1e-9 dB
    assert_allclose(m2.phase_crossovers, m1.phase_crossovers, rtol=1e-12)
    assert_allclose(m2.gain_margins_db, m1.gain_margins_db - 20 * np.log10(scale), atol=1e-9)


def test_closed_loop_and_sensitivity():
    T_s = 1e-3
    omega = np.logspace(0, 3, 50)
    L = loop(omega, 30.0 / (1j * omega), name="velocity-open", sample_period=T_s)
    T, S = closed_loop(L), sensitivity(L)
    # L/(1+L) + 1/(1+L) with |T|, |S| <= 1.1 (|L| <= 30): one division each, <= 4 eps ≈ 1e-15; 1e-12. The next
    # line is the same formula: exact
    assert_allclose(T.response + S.response, 1.0, rtol=1e-12)
    assert_allclose(T.response, L.response / (1 + L.response))
    assert T.sample_period == S.sample_period == T_s
    assert not T.open_loop and T.name == "velocity-open T" and S.name == "velocity-open S"


def test_to_dict_and_to_pandas():
    s = 1j * DENSE
    m = stability_margins(loop(DENSE, 2.0 / (s * (s + 1) * (s + 2)), name="L"))
    d = m.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["name"] == "L" and d["stable_hint"] is True and d["delay_margin_samples"] is None
    # the same number through to_dict: exact
    assert_allclose(d["gain_margin_db"], m.gain_margin_db)
    frame = m.to_pandas()
    assert list(frame.columns) == ["kind", "omega", "frequency_hz", "phase_margin_deg", "delay_margin_s",
                                   "gain_margin_db", "reported"]
    assert list(frame["kind"]) == ["gain", "phase"] and frame["reported"].all()
    # the same division: exact
    assert_allclose(frame["frequency_hz"], frame["omega"] / (2 * np.pi))
    assert isinstance(m, Margins) and m.gain_crossovers.flags.writeable is False


@pytest.mark.parametrize("omega, values, what", [
    ([1.0], [1.0], "at least 2"),
    ([2.0, 1.0], [1.0, 1.0], "ascending"),
    ([0.0, 1.0], [1.0, 1.0], "positive"),
    ([1.0, 2.0], [1.0, 1.0, 1.0], "response values"),
    ([1.0, 2.0], [1.0, np.inf], "not finite"),
])
def test_invalid_response_raises(omega, values, what):
    with pytest.raises(ModelError, match=what):
        stability_margins(FrequencyResponse(np.asarray(omega), np.asarray(values, dtype=complex)))
    assert issubclass(ModelError, ValueError)


# --------------------------------------------------------------------------- figures
def test_bode_and_nichols_figures(tmp_path):
    omega = np.logspace(-1, 2, 3000)
    wc, wn, zeta = 1.0, 10.0, 0.01
    frf = loop(omega, resonant_loop(omega, wc, wn, zeta, 0.4), name="resonant")
    m = stability_margins(frf)
    bode = bode_figure([frf, closed_loop(frf)], margins=[m, None], title="velocity loop")
    assert isinstance(bode, Figure) and len(bode.axes) == 2
    nichols = nichols_figure([frf], margins=m)
    assert isinstance(nichols, Figure) and len(nichols.axes) == 1
    lo, hi = nichols.axes[0].get_xlim()
    assert lo < -180.0 < hi
    for kind in ("bode", "nichols"):
        fig = m.plot(kind)
        assert isinstance(fig, Figure)
        save_figure(fig, tmp_path / f"{kind}.png")
        assert (tmp_path / f"{kind}.png").stat().st_size > 0
    with pytest.raises(ModelError, match="plot kind"):
        m.plot("nyquist")
    with pytest.raises(ModelError, match="one margins entry per response"):
        bode_figure([frf], margins=[m, m])


def test_frequency_response_plot_nichols_and_sampled_bode():
    T = 1e-3
    omega = np.logspace(0, np.log10(0.999 * np.pi / T), 500)
    z = np.exp(1j * omega * T)
    frf = loop(omega, 0.5 / (z - 1) * (1 + 0.1 / (1 - 1 / z)) / z, name="sampled", sample_period=T)
    fig = frf.plot("nichols")
    assert isinstance(fig, Figure) and len(fig.axes) == 1
    fig = frf.plot("bode")
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    nyquist = [ln for ln in fig.axes[0].get_lines() if np.allclose(ln.get_xdata(), 0.5 / T)]
    assert nyquist                                  # the Nyquist frequency is marked
    fig = bode_figure(frf, margins=stability_margins(frf))
    assert len(fig.axes) == 2
