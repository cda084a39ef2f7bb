"""Stability margins of textbook loops with closed-form answers, and against python-control."""

from __future__ import annotations

import control
import numpy as np
import pytest

from sicomat.lti.response import FrequencyResponse
from sicomat.frequency.margins import stability_margins

W = np.logspace(-3, 3, 20000)


def _frf(L, omega=W, period=None):
    return FrequencyResponse(omega, L, "test", period, open_loop=True)


@pytest.mark.parametrize("K", [1.0, 2.0, 4.5])
def test_third_order_loop_gain_margin_is_six_over_k(K):
    """L = K/(s(s+1)(s+2)): the phase is -180 deg at w = sqrt(2), where |L| = K/6."""
    s = 1j * W
    m = stability_margins(_frf(K / (s * (s + 1) * (s + 2))))
    # W: 20000 points over 6 decades, Δ = 6.9e-4 in ln ω; the local-cubic error Δ⁴/24·|y''''| ≈ 1e-14 (see
    # test_margins). These textbook checks keep looser, round bounds (1e-6 relative, 1e-4 dB, 1e-3 deg) than
    # test_margins' derived ones on purpose: they document the textbook values, test_margins pins the accuracy
    assert m.phase_crossover_rad_s == pytest.approx(np.sqrt(2), rel=1e-6)
    assert m.gain_margin_db == pytest.approx(20 * np.log10(6 / K), abs=1e-4)
    # phase margin: solve |L(jw)| = 1 independently
    from scipy.optimize import brentq

    wc = brentq(lambda w: K - w * np.sqrt(w ** 2 + 1) * np.sqrt(w ** 2 + 4), 1e-3, 10)
    pm = 180 - 90 - np.degrees(np.arctan(wc) + np.arctan(wc / 2))
    # brentq's default xtol 2e-12 on the reference crossover: negligible; the same grid bounds as above
    assert m.phase_margin_deg == pytest.approx(pm, abs=1e-3)
    assert m.gain_crossover_rad_s == pytest.approx(wc, rel=1e-6)


@pytest.mark.parametrize("wc,tau", [(10.0, 0.02), (50.0, 0.01), (2.0, 0.3)])
def test_integrator_with_pure_delay(wc, tau):
    """L = (wc/s) e^{-s tau}: crosses 0 dB at wc with PM = 90 deg - wc tau; phase crossover at
    w tau = pi/2, GM = 20 log10(pi / (2 wc tau)); delay margin = pi/(2 wc) - tau."""
    s = 1j * W
    m = stability_margins(_frf(wc / s * np.exp(-s * tau)))
    # the W grid's local-cubic error (see the first test) is ~1e-14; the phase ωτ turns fast at high ω,
    # so the phase crossover and GM get round bounds one order looser (1e-5, 1e-3 dB), the delay margin
    # (a difference π/(2ωc) − τ, up to 5 times smaller than its terms) 1e-4
    assert m.gain_crossover_rad_s == pytest.approx(wc, rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(90 - np.degrees(wc * tau), abs=1e-3)
    assert m.phase_crossover_rad_s == pytest.approx(np.pi / (2 * tau), rel=1e-5)
    assert m.gain_margin_db == pytest.approx(20 * np.log10(np.pi / (2 * wc * tau)), abs=1e-3)
    assert m.delay_margin_s == pytest.approx(np.pi / (2 * wc) - tau, rel=1e-4)   # a difference, above: 1e-4


def test_integrator_bandwidth_is_its_crossover():
    s = 1j * W
    m = stability_margins(_frf(7.0 / s))
    # closed forms relative to the lowest grid point ω0 = 1e-3: the bandwidth is √(49 + 2ω0²), 7(1 + 2e-8); the
    # modulus margin approaches 1 as ω grows: at the grid's last point, 1e3 rad/s, |1 + 7/jω| = 1 + 2.5e-5: 1e-3
    assert m.bandwidth_rad_s == pytest.approx(7.0, rel=1e-4)   # T = 7/(s + 7)
    assert m.modulus_margin == pytest.approx(1.0, abs=1e-3)     # |1 + 7/(jw)| >= 1, -> 1 at high w


@pytest.mark.parametrize("num,den", [
    ([2.0], [1, 3, 3, 1]),
    ([10.0, 10.0], [1, 2, 5, 0]),
    ([0.5, 2.0], [1, 1.2, 4, 1, 0]),
])
def test_rational_loops_against_python_control(num, den):
    sys = control.tf(num, den)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(sys)
    L = np.asarray(sys.frequency_response(W).complex).ravel()
    m = stability_margins(_frf(L))
    if np.isfinite(gm):
        # python-control's margins from polynomial roots (exact to ~1e-12) against our grid (1e-14 for the
        # crossovers); 1e-3 and 0.05° are round bounds far above both (any modelling error is O(1))
        assert 10 ** (m.gain_margin_db / 20) == pytest.approx(gm, rel=1e-3)
        assert m.phase_crossover_rad_s == pytest.approx(wpc, rel=1e-3)
    assert m.phase_margin_deg == pytest.approx(pm, abs=0.05)
    assert m.gain_crossover_rad_s == pytest.approx(wgc, rel=1e-3)


def test_every_resonant_crossover_is_found_and_the_worst_reported():
    """An integrator loop with a lightly damped mode whose peak rises above 0 dB crosses three times."""
    w = np.logspace(-1, 3, 40000)
    s = 1j * w
    wn, zeta = 100.0, 0.005
    L = 20.0 / s * wn ** 2 / (s ** 2 + 2 * zeta * wn * s + wn ** 2) * np.exp(-s * 1e-3)
    m = stability_margins(_frf(L, w))
    assert len(m.gain_crossovers) == 3
    # the first crossover is the integrator's, near 20 rad/s, with a large margin; a resonant one is worse
    # a physical approximation: the integrator's crossover K alone, moved by the resonance's gain there (a few
    # %): 5 %
    assert m.gain_crossovers[0] == pytest.approx(20.0, rel=0.05)
    assert abs(m.phase_margin_deg) < abs(m.phase_margins_deg[0])


def test_sampled_integrator():
    """L(z) = K T/(z - 1) at z = e^{jwT}: |L| = K T / (2 sin(wT/2)), arg L = -pi/2 - wT/2."""
    T, K = 1e-3, 100.0
    w = np.linspace(1.0, 0.999 * np.pi / T, 20000)
    z = np.exp(1j * w * T)
    m = stability_margins(_frf(K * T / (z - 1), w, period=T))
    wc = 2 / T * np.arcsin(K * T / 2)
    # a uniform grid of 20000 points up to 0.999π/T: Δω = 0.16 rad/s, local cubics in ln ω: error ~(Δω/ω)⁴ ≈
    # 1e-9 at ω = 100 rad/s; 1e-5 and 1e-3° are round bounds
    assert m.gain_crossover_rad_s == pytest.approx(wc, rel=1e-5)
    assert m.phase_margin_deg == pytest.approx(90 - np.degrees(wc * T / 2), abs=1e-3)
