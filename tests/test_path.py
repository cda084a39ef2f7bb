"""sicomat.motion.path: line/arc geometry, the interpolator's limits and junctions, the circle-test path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.figure import Figure
from numpy.testing import assert_allclose

from sicomat.errors import ModelError
from sicomat.motion import Arc, Line, Path, circle_test_path, interpolate

R = 0.05
A, J, PERIOD = 2.0, 40.0, 1e-3


def line_and_arc():
    """A 100 mm line along +X, then a tangent quarter circle (R = 50 mm, CCW) up to (150, 50) mm."""
    return Path([Line((0.0, 0.0), (0.1, 0.0)), Arc((0.1, 0.0), (0.15, 0.05), (0.1, 0.05))])


# ------------------------------------------------------------------ geometry
def test_length_point_and_tangent_of_line_plus_arc():
    p = line_and_arc()
    # closed-form geometry, in this file: lengths are sums of one or two products (<= 2 roundings, 1e-15 ≈ 4.5
    # eps); points are R·cos/sin (libm <= 1 ulp) plus offsets, all <= 0.3 m, so a few ulp of 0.3 m ≈ 1e-16 (atol
    # 1e-15); the curvature 1/R = 20 1/m to a few eps of 20 (atol 1e-12)
    assert_allclose(p.length, 0.1 + math.pi * R / 2, rtol=1e-15)
    s = np.array([0.0, 0.05, 0.1, 0.1 + math.pi * R / 4, p.length])
    c45 = math.sqrt(0.5)
    assert_allclose(p.point(s), [[0, 0], [0.05, 0], [0.1, 0], [0.1 + R * c45, R - R * c45], [0.15, 0.05]],
                    atol=1e-15)                                         # a few ulp of 0.3 m, above
    assert_allclose(p.tangent(s), [[1, 0], [1, 0], [1, 0], [c45, c45], [0, 1]], atol=1e-15)   # cos/sin: an ulp of 1
    assert_allclose(p.curvature(s)[-1], [-1 / R, 0.0], atol=1e-12)   # a few eps of 20 (above)
    assert p.point(0.05).shape == (2,)
    assert p.axis_names == ("x", "y")


@pytest.mark.parametrize("clockwise, sweep", [(False, math.pi / 2), (True, -3 * math.pi / 2)])
def test_arc_direction(clockwise, sweep):
    arc = Arc((R, 0.0), (0.0, R), (0.0, 0.0), clockwise=clockwise)
    # atan2 of exact points: <= 1 ulp; the length one more product
    assert_allclose(arc.sweep, sweep, rtol=1e-15)
    assert_allclose(arc.length, abs(sweep) * R, rtol=1e-15)
    mid = arc.point(np.array([arc.length / 2]))[0]
    expected = math.pi / 4 if not clockwise else -3 * math.pi / 4
    # R·cos/sin of a sweep/2 known to an ulp: a few ulp of R = 0.05 (7e-18 each), atol 1e-15
    assert_allclose(mid, [R * math.cos(expected), R * math.sin(expected)], atol=1e-15)


def test_full_circle_and_three_axes():
    arc = Arc((R, 0.0, 0.01), (R, 0.0, 0.01), (0.0, 0.0), clockwise=True)
    # 2πR in one product; points R·(cos, sin) with libm's <= 1 ulp: radius to a few eps (1e-15)
    assert_allclose(arc.length, 2 * math.pi * R, rtol=1e-15)
    pts = arc.point(np.linspace(0, arc.length, 9))
    assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), R, rtol=1e-15)
    # the third axis is copied: exact
    assert_allclose(pts[:, 2], 0.01)
    assert_allclose(pts[2], [0.0, -R, 0.01], atol=1e-15)       # clockwise: through -Y first
    assert arc.center == (0.0, 0.0, 0.01)


def test_arc_radius_within_tolerance_is_accepted_and_ends_on_its_circle():
    arc = Arc((R, 0.0), (0.0, R + 0.5e-6), (0.0, 0.0))
    end = arc.point(np.array([arc.length]))[0]
    # the arc ends exactly on its given end point (the 0.5 µm radius mismatch is absorbed): rounding only
    assert_allclose(end, [0.0, R], atol=1e-15)


@pytest.mark.parametrize("make, match", [
    (lambda: Arc((R, 0.0), (0.0, R + 5e-6), (0.0, 0.0)), "arc start and end radii differ by 5 µm"),
    (lambda: Arc((R, 0.0), (0.0, 2 * R), (0.0, 0.0)), "radii differ"),
    (lambda: Arc((0.0, 0.0), (0.0, 0.0), (0.0, 0.0)), "arc radius is zero"),
    (lambda: Arc((R, 0.0, 0.0), (0.0, R, 0.01), (0.0, 0.0)), "helical arcs are not supported"),
    (lambda: Line((0.1, 0.2), (0.1, 0.2)), "distinct start and end"),
    (lambda: Line((0.0, 0.0), (1.0, 0.0, 0.0)), "line end must have 2 coordinates"),
    (lambda: Path([Line((0, 0), (1, 0)), Line((1, 1e-5), (2, 0))]), "segment 1 starts 10 µm away"),
    (lambda: Path([]), "at least one segment"),
    (lambda: Path([Line((0, 0), (1, 0))], feeds=[0.0]), "feed of segment 0 must be > 0"),
])
def test_bad_geometry_is_a_model_error(make, match):
    with pytest.raises(ModelError, match=match):
        make()


# ------------------------------------------------------------------ interpolation
def _check_limits(out, feed, a=A, j=J):
    # limits hold exactly in the closed-form profile; samples evaluate its polynomials at t = k·T, rounding
    # ~eps·(t/T) of the values: 1e-9 relative is slack
    tol = 1e-9
    assert np.all(out.path_velocity >= -1e-12)
    assert out.path_velocity.max() <= feed * (1 + tol)
    assert np.abs(out.path_acceleration).max() <= a * (1 + tol)
    assert np.abs(out.path_jerk).max() <= j * (1 + tol)
    assert np.all(np.linalg.norm(out.velocity, axis=1) <= feed * (1 + tol))
    assert np.all(np.diff(out.s) >= -1e-15)


def test_line_duration_closed_form_and_limits():
    p = Path([Line((0.0, 0.0, 0.0), (0.3, 0.4, 0.0))])          # 0.5 m
    feed = 0.2
    out = interpolate(p, feed, A, J, PERIOD)
    # closed form of the s-curve time: three quotients summed; the profile computes the same in another order: a
    # few eps (1e-12)
    assert_allclose(out.profile.duration, 0.5 / feed + feed / A + A / J, rtol=1e-12)   # v J >= A², both reached
    _check_limits(out, feed)
    # k·T: one rounding each
    assert_allclose(out.time[1] - out.time[0], PERIOD)
    assert out.time[-1] >= out.profile.end_time and out.time[-2] < out.profile.end_time
    # the end point is held exactly after the move; velocities are the path velocity times the unit direction
    # (0.6, 0.8): one rounding of values <= 0.2 m/s
    assert_allclose(out.position[-1], [0.3, 0.4, 0.0], atol=1e-15)
    assert_allclose(out.velocity, out.path_velocity[:, None] * [0.6, 0.8, 0.0], atol=1e-15)


def test_samples_are_consistent_derivatives():
    out = interpolate(line_and_arc(), 0.1, A, J, 2e-4)
    h = out.period
    vel_fd = np.gradient(out.position, h, axis=0)
    acc_fd = np.gradient(out.velocity, h, axis=0)
    inner = slice(2, -2)
    # central differences: O(J h²) where the acceleration is continuous, O(a h) at the line-arc
    # junction where the centripetal acceleration v²/R steps in
    err = np.abs(vel_fd[inner] - out.velocity[inner]).max(axis=1)
    assert np.all(err <= (A + 0.1 ** 2 / R) * h)
    assert np.sum(err > J * h * h) <= 2
    # the curvature steps at the line-arc junction: acceleration is continuous elsewhere
    jump = np.abs(acc_fd - out.acceleration).max(axis=1)
    assert np.sum(jump > 1e-3 * A + J * h) <= 2


def test_tangent_junction_keeps_the_feed_and_corner_stops():
    feed = 0.05
    tangent = interpolate(line_and_arc(), feed, A, J, PERIOD)
    at_junction = np.argmin(np.abs(tangent.s - 0.1))
    # at a tangent junction the cruise phase continues: the plateau value in a few roundings
    assert_allclose(tangent.path_velocity[at_junction], feed, rtol=1e-12)
    assert tangent.profile.kind == "s-curve"
    corner = Path([Line((0.0, 0.0), (0.1, 0.0)), Line((0.1, 0.0), (0.1, 0.1))])
    out = interpolate(corner, feed, A, J, PERIOD)
    assert out.profile.kind == "s-curve sequence"
    t_corner = out.profile.breaks[0] + sum(out.profile.segment_durations[:7])
    s, v, a = out.profile.evaluate(t_corner)
    # the profile at its break time: polynomials evaluated at a sum of segment durations, rounding ~eps·t·(v, a,
    # j) ≈ 1e-15; 1e-12
    assert_allclose([s, v, a], [0.1, 0.0, 0.0], atol=1e-12)
    _check_limits(out, feed)
    # a tiny kink under the tolerance is crossed at speed
    kink = Path([Line((0.0, 0.0), (0.1, 0.0)), Line((0.1, 0.0), (0.2, 1e-5))])
    assert interpolate(kink, feed, A, J, PERIOD).profile.kind == "s-curve"


def test_arc_speed_limited_by_centripetal_acceleration():
    small = 0.002
    p = Path([Line((0.0, 0.0), (0.05, 0.0)), Arc((0.05, 0.0), (0.05, 2 * small), (0.05, small))])
    out = interpolate(p, 0.5, A, J, 1e-4)
    v_arc = math.sqrt(A * small)
    # the arc limit √(A·r) in closed form, the same in the interpolator: a few roundings
    assert_allclose(out.path_velocity.max(), v_arc, rtol=1e-12)
    on_arc = out.s > 0.05
    assert np.all(out.path_velocity[on_arc] ** 2 / small <= A * (1 + 1e-9))
    _check_limits(out, 0.5)


def test_per_segment_feeds_stop_where_the_feed_changes():
    p = Path([Line((0.0, 0.0), (0.1, 0.0)), Line((0.1, 0.0), (0.2, 0.0))], feeds=[0.05, 0.02])
    out = interpolate(p, None, A, J, PERIOD)
    assert out.profile.kind == "s-curve sequence"
    # plateaus at the segments' feeds: a few roundings
    assert_allclose(out.path_velocity[out.s < 0.1].max(), 0.05, rtol=1e-12)
    assert_allclose(out.path_velocity[out.s > 0.1].max(), 0.02, rtol=1e-12)
    same = interpolate(p, 0.03, A, J, PERIOD)                  # one feed overrides them
    assert same.profile.kind == "s-curve"


@pytest.mark.parametrize("args, match", [
    ((0.0, A, J, PERIOD), "feed must be a finite number > 0"),
    ((-0.1, A, J, PERIOD), "feed must be a finite number > 0"),
    ((0.1, 0.0, J, PERIOD), "max_acceleration must be a finite number > 0"),
    ((0.1, A, -1.0, PERIOD), "max_jerk must be a finite number > 0"),
    ((0.1, A, J, 0.0), "period must be a finite number > 0"),
    ((None, A, J, PERIOD), "no feed"),
])
def test_bad_interpolation_input(args, match):
    with pytest.raises(ModelError, match=match):
        interpolate(line_and_arc(), *args)


def test_axis_setpoint_matches_samples_and_is_relative():
    p = Path([Line((0.01, 0.02), (0.11, 0.02)), Arc((0.11, 0.02), (0.16, 0.07), (0.11, 0.07))])
    out = interpolate(p, 0.05, A, J, PERIOD)
    sp = out.axis_setpoint("y")
    pos, vel, acc = sp.evaluate(out.time)
    assert sp.name == "y" and sp.offset == 0.02
    # the same numbers minus the offset (rounding of values <= 0.1 m); the acceleration of an arc includes v²·κ
    # computed in another order: a few eps of a ~ A (1e-12)
    assert_allclose(pos, out.position[:, 1] - 0.02, atol=1e-15)
    assert_allclose(vel, out.velocity[:, 1], atol=1e-15)
    assert_allclose(acc, out.acceleration[:, 1], atol=1e-12)
    assert_allclose(sp.distance, 0.05, rtol=1e-12)
    assert sp.end_time == out.profile.end_time
    frame = out.to_pandas()
    assert {"s", "x.position", "y.acceleration"} <= set(frame.columns)
    assert out.to_dict()["samples"] == out.time.size
    assert isinstance(out.plot(), Figure)


# ------------------------------------------------------------------ circle test path
@pytest.mark.parametrize("clockwise", [False, True])
def test_circle_test_path_has_a_steady_evaluated_circle(clockwise):
    center = (0.2, -0.1)
    ct = circle_test_path(center, R, clockwise)
    assert len(ct.path.segments) == 3
    # sums of π·R terms: a few roundings
    assert_allclose(ct.path.length, 4 * math.pi * R, rtol=1e-12)     # 180° + 360° + 180°
    assert_allclose(ct.window, (math.pi * R, 3 * math.pi * R), rtol=1e-12)
    assert_allclose(ct.path.point(ct.window[0]), [0.2 + R, -0.1], atol=1e-15)   # starts at 0°
    feed = 2.0 / 60                                                # F2000
    out = interpolate(ct.path, feed, A, J, PERIOD)
    inside = ct.window_mask(out.s)
    # the window is inside the cruise phase: the plateau value; points on the circle are center + R·(cos, sin):
    # the radius is recovered to eps·|position|/R ≈ 1.1e-15 (1e-14)
    assert_allclose(out.path_velocity[inside], feed, rtol=1e-12)
    assert_allclose(np.hypot(*(out.position - center).T), R, rtol=1e-14)
    angle = np.unwrap(np.arctan2(*(out.position - center).T[::-1]))
    assert np.sign(angle[-1] - angle[0]) == (-1 if clockwise else 1)
    sweep = angle[inside][-1] - angle[inside][0]
    # the first and last samples inside the window miss its ends by at most one sample's angle each, feed·T/R
    assert_allclose(abs(sweep), 2 * math.pi, atol=2 * feed * PERIOD / R)


def test_circle_test_path_options_and_errors():
    ct = circle_test_path((0.0, 0.0, 0.3), R, lead_in_angle=math.pi / 2, lead_out_angle=0.0,
                          start_angle=math.pi / 2)
    assert len(ct.path.segments) == 2 and ct.path.dimension == 3
    # R·cos/sin of the start angle π/2 and an offset: rounding
    assert_allclose(ct.path.start, [R, 0.0, 0.3], atol=1e-15)
    with pytest.raises(ModelError, match="radius must be a finite number > 0"):
        circle_test_path((0, 0), 0.0)
    with pytest.raises(ModelError, match="lead_in_angle must be between 0 and 2π"):
        circle_test_path((0, 0), R, lead_in_angle=-1.0)
