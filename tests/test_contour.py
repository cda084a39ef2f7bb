"""sicomat.motion.contour.contour_error: exact distances to lines and arcs, a perfect follower, a dense-polyline peer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial import cKDTree

from sicomat.motion.contour import contour_error
from sicomat.errors import ModelError
from sicomat.motion.gcode import parse_gcode
from sicomat.motion import Arc, Line, Path, circle_test_path, interpolate

PROGRAM = """G90 G17 G01 X0 Y0 F3000
X40
G03 X60 Y20 I0 J20
G01 Y40
G03 X40 Y60 I-20 J0
G01 X0 Y30 (a corner)
X0 Y10
"""


def program_path():
    return parse_gcode(PROGRAM, axes="XY")


def test_perfect_follower_has_zero_contour_error():
    path = program_path()
    out = interpolate(path, None, 1.0, 20.0, 1e-3)
    with_hint = contour_error(path, out.position, out.s)
    without = contour_error(path, out.position)
    assert with_hint.shape == (out.time.size,)
    # the follower is exactly on the path: the distance is rounding of point − projection, values <= 0.3 m with
    # arcs through cos/sin: ~1e-16 m; 1e-12 m slack (1e-15 for a lagging follower on a line, which is a
    # difference of exactly representable coordinates)
    assert np.max(with_hint) <= 1e-12 and np.max(without) <= 1e-12


def test_circle_test_perfect_follower():
    ct = circle_test_path((0.1, 0.1), 0.05, clockwise=True)
    out = interpolate(ct.path, 0.05, 1.0, 20.0, 1e-3)
    # on the path up to rounding (see above): 1e-12 m
    assert np.max(np.abs(contour_error(ct.path, out.position, out.s, signed=True))) <= 1e-12


def test_lag_along_a_line_is_not_a_contour_error():
    path = Path([Line((0.0, 0.0), (0.2, 0.1))])
    out = interpolate(path, 0.1, 1.0, 20.0, 1e-3)
    lagging = np.vstack([out.position[:1]] * 25 + [out.position[:-25]])    # 25 ms behind
    assert np.max(np.linalg.norm(lagging - out.position, axis=1)) > 1e-3    # following error: mm
    assert np.max(contour_error(path, lagging, out.s)) <= 1e-15


def test_known_offsets_and_signs():
    line = Path([Line((0.0, 0.0), (1.0, 0.0))])
    pts = np.array([[0.5, 0.002], [0.5, -0.003], [1.3, 0.4], [-0.3, -0.4]])
    # distances to a line and to its end points in closed form: a few roundings (1e-12); to an arc, |r − R|
    # subtracts values 1e3 times larger than the distance (1e-4 m from 0.05 m): the rounding eps·R/d ≈ 1e-13
    # relative, 1e-9
    assert_allclose(contour_error(line, pts), [0.002, 0.003, 0.5, 0.5], rtol=1e-12)
    # signed: positive on the right of travel (+X travel: right is -Y)
    assert_allclose(contour_error(line, pts[:2], signed=True), [-0.002, 0.003], rtol=1e-12)
    r = 0.05
    for clockwise, outward_sign in ((False, 1.0), (True, -1.0)):
        arc = Path([Arc((r, 0.0), (0.0, r) if not clockwise else (0.0, -r), (0.0, 0.0), clockwise)])
        th = math.radians(30) * (-1 if clockwise else 1)
        pts = np.array([[(r + d) * math.cos(th), (r + d) * math.sin(th)] for d in (1e-4, -2e-4)])
        assert_allclose(contour_error(arc, pts), [1e-4, 2e-4], rtol=1e-9)    # |r − R|: eps·R/d, above
        assert_allclose(contour_error(arc, pts, signed=True), outward_sign * np.array([1e-4, -2e-4]), rtol=1e-9)
    # beyond the arc's end points the nearest point is an end point; the centre is R away
    quarter = Path([Arc((r, 0.0), (0.0, r), (0.0, 0.0))])
    # distances to end points: a hypot, one rounding
    assert_allclose(contour_error(quarter, [[0.0, -r], [0.0, 0.0]]), [r * math.sqrt(2), r], rtol=1e-12)


def test_three_axes_include_the_out_of_plane_offset():
    path = Path([Arc((0.05, 0.0, 0.01), (0.05, 0.0, 0.01), (0.0, 0.0))])
    pts = np.array([[0.0, 0.0503, 0.0104]])
    # |r − R| on a helix arc, as above: 1e-9
    assert_allclose(contour_error(path, pts), [math.hypot(3e-4, 4e-4)], rtol=1e-9)


def _peer(path, pts, n=200_001):
    """Distance to a dense polyline of the path (nearest vertex), an upper bound within the chord."""
    dense = path.point(np.linspace(0, path.length, n))
    return cKDTree(dense).query(pts)[0], path.length / (n - 1)


def test_against_a_dense_polyline_peer():
    path = program_path()
    rng = np.random.default_rng(7)
    s = rng.uniform(0, path.length, 3000)
    pts = path.point(s) + rng.normal(scale=1e-3, size=(s.size, 2))
    ours = contour_error(path, pts)
    peer, spacing = _peer(path, pts)
    # the exact distance is never above a polyline peer's (whose vertices lie on the path) up to rounding (1e-15
    # m), and above it by at most the peer's vertex spacing
    assert np.all(ours <= peer + 1e-15)
    assert_allclose(ours, peer, atol=spacing)
    # the arc-length hint gives the same answer for points near their setpoint (the path does not
    # come back near itself, which a search around the hint would miss)
    # the same closest point found from the hint: the same formula, rounding only
    assert_allclose(contour_error(path, pts, s), ours, atol=1e-15)


def test_hint_search_on_many_points():
    ct = circle_test_path((0.0, 0.0), 0.1)
    out = interpolate(ct.path, 0.5, 2.0, 50.0, 5e-5)             # ~1e5 samples
    assert out.time.size > 50_000
    actual = out.position * (1 + 1e-5)                           # 1 µm outward
    err = contour_error(ct.path, actual, out.s, signed=True)
    # a circle of R = 0.1 m about the origin scaled by 1 + 1e-5: the signed distance |p|(1 + 1e-5) − R subtracts
    # values 1e5 times the result, rounding eps·R ≈ 2e-17 m, 2e-11 of 1 µm; 1e-6 slack
    assert_allclose(err, 1e-6, rtol=1e-6)


def test_bad_shapes():
    path = program_path()
    with pytest.raises(ModelError, match=r"actual points must be an \(n, 2\) array"):
        contour_error(path, np.zeros((5, 3)))
    with pytest.raises(ModelError, match=r"s_hint must have shape \(5,\)"):
        contour_error(path, np.zeros((5, 2)), np.zeros(4))
