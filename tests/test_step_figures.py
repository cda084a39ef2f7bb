"""Step figures: one definition (simulation.timeseries.step_figures) behind `simulate`'s metrics and the
sampled step responses of `step` and `tune --method time`, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sicomat.lti.response import zoh_matrices
from sicomat.simulation.timeseries import step_figures, step_metrics
from sicomat.tuning.time import StepResponse, _step


def _sampled_lag(tau: float, h: float, n: int) -> StepResponse:
    """The unit step response of 1/(τs + 1) sampled at h, exactly: x+ = a x + (1 − a), y = x,
    a = exp(−h/τ), i.e. y_k = 1 − exp(−k h/τ)."""
    a = math.exp(-h / tau)
    return _step(np.array([[a]]), np.array([1.0 - a]), np.array([1.0]), h, n, h, tail=1)


def _sampled_second_order(zeta: float, wn: float, h: float, n: int) -> StepResponse:
    """The unit step response of ωn²/(s² + 2ζωn s + ωn²), sampled exactly (a step is held: ZOH)."""
    A = np.array([[0.0, 1.0], [-wn**2, -2 * zeta * wn]])
    B = np.array([[0.0], [wn**2]])
    Ad, Bd = zoh_matrices(A, B, h)
    return _step(Ad, Bd[:, 0], np.array([1.0, 0.0]), h, n, h, tail=1)


@pytest.mark.parametrize("tau", [0.01, 1.0])
def test_rise_and_settling_of_a_sampled_first_order_lag(tau):
    # y = 1 − exp(−t/τ): rise 10→90 % = τ ln 9; the 2 % band is entered at τ ln 50.
    # Rise: each crossing is interpolated linearly; the chord's error is ≤ h² max|y''|/8 = h²/(8τ²)
    # and the slope there ≥ 0.1/τ, so each crossing moves ≤ 1.25 h²/τ, the rise time ≤ 2.5 h²/τ.
    # With h = τ/100 that is 2.5e-4 τ, a quarter of the one sample (1e-2 τ) the first sample beyond
    # the level could be off by (the old definition). Settling: the first sample inside, ≤ h late.
    h = tau / 100
    r = _sampled_lag(tau, h, 2000)
    assert r.stable
    final = r.response[-1]          # 1 − exp(−20), the tail's final value the figures refer to
    expected_rise = tau * math.log(9)
    assert abs(r.rise_time - expected_rise) <= 2.5 * h**2 / tau + 1e-12 * tau
    expected_settle = -tau * math.log(0.02 * final / 1.0 + (1.0 - final))   # |y − final| = 0.02 final
    assert expected_settle - 1e-12 <= r.settling_time <= expected_settle + h
    assert r.overshoot_percent == 0.0


@pytest.mark.parametrize("zeta", [0.1, 0.3, 0.6])
def test_overshoot_of_a_sampled_second_order_step(zeta):
    # Peak of 1 − e^{−ζωn t}(cos ωd t + ζ/√(1−ζ²) sin ωd t) is exp(−ζπ/√(1−ζ²)) at t = π/ωd. The largest
    # sample is below it by ≤ (h/2)² max|y''|/2 with |y''| ≤ ωn²(1 + ζ/√(1−ζ²)) ≤ 2 ωn² (ζ ≤ 0.6), i.e.
    # ≤ ωn² h²/4 of the step; the final value (the last sample, at t_end = 40/(ζωn)) differs from
    # 1 by e^{−40}/√(1−ζ²) < 1e-16. ωn = 10, h = 1e-3: ≤ 2.5e-5 of the step = 2.5e-3 %.
    wn, h = 10.0, 1e-3
    n = int(round(40.0 / (zeta * wn) / h))
    r = _sampled_second_order(zeta, wn, h, n)
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    assert r.stable
    assert expected - 2.5e-3 <= r.overshoot_percent <= expected + 1e-9


def test_simulate_and_step_share_one_definition():
    # The same samples through simulate's step_metrics (a move of distance d to a final setpoint d)
    # and the step response's figures (a unit step scaled by its final value) give the same figures:
    # the two scalings differ by one rounding (d/d), far below 1e-12 relative.
    tau, h = 0.05, 1e-3
    r = _sampled_lag(tau, h, 1500)
    final = r.response[-1]
    d = 0.01
    m = step_metrics(r.time, np.full(r.time.size, d * final), d * r.response, d * final)
    assert m.rise_time == pytest.approx(r.rise_time, rel=1e-12)
    assert m.settling_time == pytest.approx(r.settling_time, rel=1e-12)
    assert m.overshoot_percent == pytest.approx(r.overshoot_percent, abs=1e-12)


def test_negative_step_and_unsettled_response():
    t = np.linspace(0.0, 5.0, 5001)
    f = step_figures(t, -(1 - np.exp(-t)), -1.0)
    assert f.rise_time == pytest.approx(math.log(9), abs=2.5e-6)   # bound as for the lag above, h = 1e-3
    assert f.overshoot_percent == 0.0
    # still outside the 2 % band of its final value at the last sample: no settling time
    g = step_figures(t, 1 - np.exp(-t / 10), 1.0)
    assert g.settling_time is None


def test_unstable_step_has_no_figures():
    r = _step(np.array([[1.5]]), np.array([1.0]), np.array([1.0]), 1e-3, 100, 1e-3)
    assert not r.stable and r.overshoot_percent == np.inf and r.rise_time is None and r.settling_time is None
    assert r.to_dict() == {"overshoot_percent": None, "rise_time": None, "settling_time": None, "stable": False}
