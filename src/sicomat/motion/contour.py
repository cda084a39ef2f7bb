"""Contour error: the normal distance from the actual tool point to the programmed path."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ModelError
from .path import Arc, Line, Path

__all__ = ["contour_error", "segment_distance"]


def segment_distance(segment: Line | Arc, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) from each of ``points`` (n, dim) to the nearest point of one segment, and a side.

    The nearest point is exact: the foot of the perpendicular on a line, the radial projection on an
    arc when it falls within the swept angle, otherwise the nearer end point.

    Returns
    -------
    distance : ndarray (n,)
        Unsigned Euclidean distance (m), out-of-plane offsets included.
    side : ndarray (n,)
        +1 where the point is on the right of the direction of travel in the plane of the first two
        axes (the arc's plane for arcs), −1 on the left.
    """
    pts = np.asarray(points, dtype=float)
    if isinstance(segment, Line):
        a, b = np.asarray(segment.start), np.asarray(segment.end)
        d = b - a
        t = np.clip((pts - a) @ d / (d @ d), 0.0, 1.0)
        dist = np.linalg.norm(pts - (a + t[:, None] * d), axis=1)
        cross = d[0] * (pts[:, 1] - a[1]) - d[1] * (pts[:, 0] - a[0])   # > 0: left of travel
        return dist, np.where(cross > 0, -1.0, 1.0)
    i, j = segment.plane
    c = np.asarray(segment.center)
    wi, wj = pts[:, i] - c[i], pts[:, j] - c[j]
    rho = np.hypot(wi, wj)
    direction = 1.0 if segment.sweep > 0 else -1.0
    radial = rho - segment.radius
    others = [k for k in range(pts.shape[1]) if k not in (i, j)]
    offset2 = np.sum((pts[:, others] - np.asarray(segment.start)[others]) ** 2, axis=1) if others else 0.0
    dist = np.sqrt(radial ** 2 + offset2)
    if abs(segment.sweep) < 2 * math.pi:
        u = ((np.arctan2(wj, wi) - segment.start_angle) * direction) % (2 * math.pi)
        outside = u > abs(segment.sweep)
        if outside.any():
            ends = segment.point(np.array([0.0, segment.length]))
            q = pts[outside]
            dist[outside] = np.minimum(np.linalg.norm(q - ends[0], axis=1), np.linalg.norm(q - ends[1], axis=1))
    return dist, np.where(radial * direction >= 0, 1.0, -1.0)


def contour_error(path: Path, actual: np.ndarray, s_hint: np.ndarray | None = None, *,
                  signed: bool = False, search_length: float | None = None) -> np.ndarray:
    """Normal distance (m) from each actual tool point to the programmed path.

    The distance to the nearest point of the whole path (lines and arcs, exact geometry), not the
    per-axis following errors: a tool lagging along the path has zero contour error.

    Parameters
    ----------
    path : Path
        The programmed path.
    actual : array_like (n, dimension)
        Actual tool points (m), one row per instant, columns in ``path.axis_names`` order.
    s_hint : array_like (n,), optional
        The setpoint's arc length (m) at each instant, e.g. ``PathSamples.s``. With it only the
        segments near the hint are searched, which makes ~1e5 points fast; without it every segment
        is searched for every point (exact in all cases, slower on long paths).
    signed : bool
        False (default): the distance, ≥ 0. True: negative where the tool is on the left of the
        direction of travel in the X-Y plane (the side G41 offsets to), positive on the right (G42
        side). On a counter-clockwise circle positive is outward, on a clockwise one inward; for the
        radial deviation of a circle test (always outward positive) see
        :func:`sicomat.motion.circle.evaluate_circle`.
    search_length : float, optional
        Half-width (m of arc length) of the window around ``s_hint`` searched for each point. By
        default 4× the distance between the point and the setpoint at ``s_hint``, which holds the
        nearest point unless the path comes back near itself elsewhere (a closed contour near its
        start and end, a crossing) or has a corner sharper than 60° within that window; search such
        paths without the hint, or with a larger ``search_length``.

    Returns
    -------
    ndarray (n,)
        Contour error (m).

    Raises
    ------
    ModelError
        If ``actual`` is not (n, dimension) or ``s_hint`` not (n,).

    Examples
    --------
    >>> from sicomat.motion import Line, Path
    >>> p = Path([Line((0.0, 0.0), (1.0, 0.0))])
    >>> contour_error(p, [[0.5, 0.001], [2.0, 0.0]]).round(6).tolist()
    [0.001, 1.0]
    """
    pts = np.asarray(actual, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != path.dimension:
        raise ModelError(f"actual points must be an (n, {path.dimension}) array", value=pts.shape, has_value=True)
    n = pts.shape[0]
    best = np.full(n, np.inf)
    side = np.ones(n)
    lengths = np.diff(path.starts)
    if s_hint is None:
        candidates = [np.arange(n)] * len(path.segments)
    else:
        hint = np.clip(np.asarray(s_hint, dtype=float), 0.0, path.length)
        if hint.shape != (n,):
            raise ModelError(f"s_hint must have shape ({n},)", value=hint.shape, has_value=True)
        if search_length is None:
            width = 4.0 * np.linalg.norm(pts - path.point(hint), axis=1) + 1e-12
        else:
            width = np.full(n, float(search_length))
        order = np.argsort(hint, kind="stable")
        ordered = hint[order]
        w_max = float(width.max()) if n else 0.0
        candidates = []
        for s0, length in zip(path.starts[:-1], lengths):
            lo = np.searchsorted(ordered, s0 - w_max, side="left")
            hi = np.searchsorted(ordered, s0 + length + w_max, side="right")
            cand = order[lo:hi]
            keep = (hint[cand] - width[cand] <= s0 + length) & (hint[cand] + width[cand] >= s0)
            candidates.append(cand[keep])
    for seg, cand in zip(path.segments, candidates):
        if cand.size == 0:
            continue
        dist, sgn = segment_distance(seg, pts[cand])
        better = dist < best[cand]
        best[cand[better]] = dist[better]
        side[cand[better]] = sgn[better]
    return best * side if signed else best
