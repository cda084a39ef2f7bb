"""sicomat.motion.circle.evaluate_circle: ISO 230-4 figures on synthetic circles and on first-order followers."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest
from matplotlib.figure import Figure
from numpy.testing import assert_allclose
from scipy import signal

from sicomat.motion.circle import evaluate_circle, least_squares_circle
from sicomat.errors import ModelError
from sicomat.motion import circle_test_path, interpolate
from sicomat.plots.base import save_figure

R = 0.05
CENTER = (0.12, -0.03)
FEED = 5.0 / 60          # F5000 mm/min
THETA = np.linspace(0, 2 * np.pi, 3600, endpoint=False)


def polar(radius):
    return CENTER[0] + radius * np.cos(THETA), CENTER[1] + radius * np.sin(THETA)


# ------------------------------------------------------------------ first-order followers
@functools.lru_cache(maxsize=None)
def follower(clockwise, kv_x, kv_y):
    """Each axis follows its setpoint as x' = Kv (x_ref - x), simulated exactly by lsim (linear
    interpolation of the 2 ms interpolator samples) along a circle-test path with 180° lead-in."""
    ct = circle_test_path(CENTER, R, clockwise)
    out = interpolate(ct.path, FEED, 2.0, 50.0, 2e-3)
    actual = []
    for k, kv in enumerate((kv_x, kv_y)):
        x0 = out.position[0, k]
        _, y, _ = signal.lsim(signal.lti([kv], [1.0, kv]), out.position[:, k] - x0, out.time)
        actual.append(y + x0)
    return evaluate_circle(*actual, CENTER, R, s=out.s, window=ct.window, feed=FEED)


@pytest.mark.parametrize("clockwise", [False, True])
def test_equal_gains_give_the_first_order_radius_error_and_no_mismatch(clockwise):
    kv = 30.0
    res = follower(clockwise, kv, kv)
    expected = -FEED ** 2 / (2 * kv ** 2 * R)       # amplitude R/sqrt(1 + (w/Kv)^2) ~ R (1 - w²/2Kv²)
    # a first-order closed form in w/Kv (w = v/R = 1.67 rad/s): the next term is O((w/Kv)²) = 3e-3 relative;
    # lsim interpolates the 2 ms samples linearly (error (wT)²/8 ≈ 1e-6) and the 180° lead-in lets the transient
    # decay (e^(-Kv·1.9 s)): 1 %. With equal gains the figure is a circle: mismatch, G and spikes are rounding
    # and the sampled-extremes error (< 1e-3 of the radius error)
    assert_allclose(res.mean_radial_deviation, expected, rtol=0.01)
    assert_allclose([res.radial_deviation_min, res.radial_deviation_max], expected, rtol=0.01)
    assert res.clockwise is clockwise
    assert res.servo_mismatch < 1e-3 * abs(expected)
    assert res.circular_deviation < 1e-3 * abs(expected)                     # the same sampled-extremes bound
    assert all(abs(s.height) < 1e-3 * abs(expected) for s in res.reversal_spikes)   # and again


@pytest.mark.parametrize("clockwise", [False, True])
def test_gain_mismatch_gives_an_ellipse_at_45_degrees(clockwise):
    """Expected tilt, to first order in w/Kv (w = v/R): each axis lags its setpoint by
    phi = atan(w/Kv) ~ w/Kv. Counter-clockwise, x = R cos(u + d), y = R sin(u - d) with
    d = (phi_y - phi_x)/2, so r² = R² (1 - sin 2d sin 2u): r ~ R - R d sin 2θ. With Kv_y < Kv_x,
    d > 0 and r is largest at θ = -45° (and 135°): the major axis is at -45°. Clockwise, y changes
    sign, θ ~ -u, and the major axis is at +45°. Amplitude R d ~ v (1/Kv_y - 1/Kv_x) / 2."""
    kv_x, kv_y = 30.0, 25.0
    res = follower(clockwise, kv_x, kv_y)
    expected_angle = 45.0 if clockwise else -45.0
    # second order: the axes' amplitudes differ by R·w²(1/Kv_y² − 1/Kv_x²)/2, an axis-aligned ellipse of 1.7e-5
    # m beside the 2.8e-4 m mismatch, which turns the major axis by atan(0.061)/2 = 1.7°: 2°; the amplitude and
    # time to the first-order error O(w/Kv)·d and O((w/Kv)²) ≈ 1 %: 3 %; the mean radius and G 2 %
    assert_allclose(math.degrees(res.servo_mismatch_angle), expected_angle, atol=2.0)
    assert_allclose(res.servo_mismatch, FEED * (1 / kv_y - 1 / kv_x) / 2, rtol=0.03)
    assert_allclose(res.servo_mismatch_time, 1 / kv_y - 1 / kv_x, rtol=0.03)
    # the mean radius error is the average of the two axes' first-order errors
    expected_mean = -FEED ** 2 / (4 * R) * (1 / kv_x ** 2 + 1 / kv_y ** 2)
    assert_allclose(res.mean_radial_deviation, expected_mean, rtol=0.02)
    assert_allclose(res.circular_deviation, 2 * res.servo_mismatch, rtol=0.02)


# ------------------------------------------------------------------ synthetic circles
def test_ellipse_amplitude_and_direction():
    e, tilt = 5e-6, math.radians(30.0)
    res = evaluate_circle(*polar(R + e * np.cos(2 * (THETA - tilt))), CENTER, R)
    # synthetic data, a pure 2θ harmonic on 3600 uniform angles: the harmonic fit is exact by discrete
    # orthogonality, up to rounding of 3600-term sums (1e-9); the extremes at 30° and 120° fall on the 0.1°
    # grid, and the least-squares circle absorbs nothing of a 2θ term: rounding of the fit (1e-6)
    assert_allclose(res.servo_mismatch, e, rtol=1e-9)
    assert_allclose(res.servo_mismatch_angle, tilt, rtol=1e-9)
    assert_allclose(res.circular_deviation, 2 * e, rtol=1e-6)
    assert_allclose([res.radial_deviation_min, res.radial_deviation_max], [-e, e], rtol=1e-6)
    assert res.clockwise is False and res.servo_mismatch_time is None


def test_off_centre_circle_least_squares_centre():
    shift = np.array([4e-6, -3e-6])
    x, y = polar(R)
    res = evaluate_circle(x + shift[0], y + shift[1], CENTER, R)
    # an exact circle: the least-squares centre and radius to the rounding of its Gauss–Newton sums (values ~0.1
    # m: 1e-15 m is ~70 ulp); G = 0 up to that; F about the nominal centre is |shift| + O(shift²/R) plus the
    # grid's sampling of a cos (Δθ²/2 = 1.5e-6): 1e-3
    assert_allclose(res.lsc_center, np.add(CENTER, shift), atol=1e-15)
    assert_allclose(res.lsc_radius, R, rtol=1e-12)
    assert res.circular_deviation < 1e-12                       # a true circle: G = 0
    assert_allclose(res.radial_deviation_max, 5e-6, rtol=1e-3)   # F about the nominal centre
    assert_allclose(res.radial_deviation_min, -5e-6, rtol=1e-3)
    # the Kasa start gives the same centre
    assert_allclose(least_squares_circle(x + shift[0], y + shift[1])[0], np.add(CENTER, shift), atol=1e-15)


@pytest.mark.parametrize("quadrant", [0, 1, 2, 3])
def test_reversal_spike_height_and_place(quadrant):
    h, sigma = 3e-6, math.radians(1.0)
    at = quadrant * math.pi / 2
    dtheta = (THETA - at + math.pi) % (2 * math.pi) - math.pi
    radius = R - 10e-6 + 4e-6 * np.cos(2 * THETA) + h * np.exp(-0.5 * (dtheta / sigma) ** 2)
    res = evaluate_circle(*polar(radius)[::-1], CENTER[::-1], R, clockwise=True)   # swap axes: CW data
    # with x and y swapped the angle seen is 90° - θ: the spike of quadrant k appears at 90° - 90° k
    k = (1 - quadrant) % 4
    spikes = res.reversal_spikes
    assert [s.quadrant_deg for s in spikes] == [0, 90, 180, 270]
    assert [s.axis for s in spikes] == ["x", "y", "x", "y"]
    # a Gaussian spike (σ = 1°) over a background 4e-6·cos 2θ: the background's curvature over ±3σ is 2e-8 m,
    # 0.7 % of h: 2 %; the spike sits on a grid point, the angle to 2 grid steps (0.2°); the other spikes are
    # that background residue (< 2 % of h); the spike adds its 2θ harmonic, h·σ·√(2π)/π ≈ 1 % of the 4 µm
    # mismatch: 2 %
    assert_allclose(spikes[k].height, h, rtol=0.02)
    assert_allclose(spikes[k].angle_deg, 90.0 * k, atol=0.2)
    assert all(abs(s.height) < 0.02 * h for i, s in enumerate(spikes) if i != k)
    assert_allclose(res.servo_mismatch, 4e-6, rtol=0.02)


def test_window_mask_and_to_dict_and_plot(tmp_path):
    x, y = polar(R - 2e-6 * np.sin(2 * THETA))
    s = np.linspace(-1.0, 2.0, THETA.size)
    res = evaluate_circle(x, y, CENTER, R, s=s, window=(0.0, 1.0), mask=np.ones(THETA.size, bool), feed=FEED)
    assert res.angle.size == np.count_nonzero((s >= 0) & (s < 1))
    data = json.loads(json.dumps(res.to_dict()))
    assert {"circular_deviation", "radial_deviation_min", "radial_deviation_max", "mean_radial_deviation",
            "reversal_spikes", "servo_mismatch", "servo_mismatch_angle_deg", "servo_mismatch_time"} <= set(data)
    assert len(data["reversal_spikes"]) == 4
    fig = res.plot()
    assert isinstance(fig, Figure) and fig.axes[0].name == "polar"
    assert "circular deviation G" in fig.get_suptitle()
    assert save_figure(res.plot(magnification=2000), tmp_path / "ballbar.png").stat().st_size > 0


@pytest.mark.parametrize("kwargs, match", [
    (dict(radius=0.0), "radius must be a finite number > 0"),
    (dict(mask=np.zeros(THETA.size, bool)), "at least 16 selected samples"),
    (dict(window=(0.0, 1.0)), "window needs s"),
])
def test_bad_input(kwargs, match):
    args = dict(radius=R) | kwargs
    with pytest.raises(ModelError, match=match):
        evaluate_circle(*polar(R), CENTER, **args)
    with pytest.raises(ModelError, match="same length"):
        evaluate_circle(np.zeros(20), np.zeros(21), CENTER, R)
