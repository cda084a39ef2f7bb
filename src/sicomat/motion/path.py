"""Multi-axis paths: lines and circular arcs joined into a tool path, and the circle-test path."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["Line", "Arc", "Path", "CircleTestPath", "circle_test_path", "RADIUS_RTOL", "RADIUS_ATOL"]

RADIUS_RTOL = 1e-6
"""Relative tolerance on an arc's end radius against its start radius."""
RADIUS_ATOL = 1e-6
"""Absolute tolerance (m) on an arc's end radius, and on the gap between consecutive segments."""
TWO_PI = 2 * math.pi


def _point(value: Sequence[float] | np.ndarray, name: str, dim: int | None = None) -> tuple[float, ...]:
    arr = np.asarray(value, dtype=float).ravel()
    if arr.size not in (2, 3) or (dim is not None and arr.size != dim):
        expected = f"{dim}" if dim is not None else "2 or 3"
        raise ModelError(f"{name} must have {expected} coordinates", value=tuple(value), has_value=True)
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} must be finite", value=tuple(arr), has_value=True)
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class Line:
    """A straight segment from ``start`` to ``end`` (m), 2 or 3 coordinates."""

    start: tuple[float, ...]
    end: tuple[float, ...]

    def __post_init__(self) -> None:
        start = _point(self.start, "line start")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", _point(self.end, "line end", len(start)))
        if self.length == 0.0:
            raise ModelError("a line needs distinct start and end points", value=start, has_value=True)

    @property
    def dimension(self) -> int:
        """Number of axes."""
        return len(self.start)

    @property
    def length(self) -> float:
        """Length (m)."""
        return float(np.linalg.norm(np.subtract(self.end, self.start)))

    def point(self, u: np.ndarray) -> np.ndarray:
        """Points (n, dim) at arc lengths ``u`` (m) from the start."""
        u = np.atleast_1d(np.asarray(u, dtype=float))[:, None]
        return np.asarray(self.start) + u * self.tangent(u[:, 0])

    def tangent(self, u: np.ndarray) -> np.ndarray:
        """Unit tangents (n, dim), in the direction of travel."""
        d = np.subtract(self.end, self.start) / self.length
        return np.broadcast_to(d, (np.size(u), self.dimension)).copy()

    def curvature(self, u: np.ndarray) -> np.ndarray:
        """Second derivatives d²p/ds² (n, dim) (1/m): zero on a line."""
        return np.zeros((np.size(u), self.dimension))


@dataclass(frozen=True)
class Arc:
    """A circular arc in the plane of axes ``plane`` (default X, Y), other coordinates constant.

    ``clockwise`` is seen from the positive third axis (G02 in G17); counter-clockwise turns from the
    plane's first axis towards its second. ``start == end`` (within :data:`RADIUS_ATOL`) is a full
    circle. ``center`` has the path's number of coordinates, or only the two in-plane ones. The radius
    is the start radius; the end radius may differ by ``max(RADIUS_RTOL·r, RADIUS_ATOL)`` at most, and
    the arc then ends on its circle at the end point's angle.

    Raises
    ------
    ModelError
        Zero radius, start and end radii differing beyond the tolerance, or a helix (an
        out-of-plane coordinate that changes).
    """

    start: tuple[float, ...]
    end: tuple[float, ...]
    center: tuple[float, ...]
    clockwise: bool = False
    plane: tuple[int, int] = (0, 1)
    radius: float = field(init=False)
    start_angle: float = field(init=False)
    sweep: float = field(init=False)

    def __post_init__(self) -> None:
        start = _point(self.start, "arc start")
        end = _point(self.end, "arc end", len(start))
        i, j = (int(k) for k in self.plane)
        if i == j or not (0 <= i < len(start) and 0 <= j < len(start)):
            raise ModelError(f"arc plane must be two distinct axis indices below {len(start)}",
                             value=self.plane, has_value=True)
        given = np.asarray(self.center, dtype=float).ravel()
        if given.size == 2 and len(start) == 3:
            full = np.array(start)
            full[[i, j]] = given
            given = full
        center = _point(given, "arc center", len(start))
        for k in range(len(start)):
            if k not in (i, j) and abs(end[k] - start[k]) > RADIUS_ATOL:
                raise ModelError(f"helical arcs are not supported: axis {k} moves from {start[k]:.9g} m "
                                 f"to {end[k]:.9g} m out of the arc's plane")
        r0 = math.hypot(start[i] - center[i], start[j] - center[j])
        r1 = math.hypot(end[i] - center[i], end[j] - center[j])
        if r0 <= RADIUS_ATOL:
            raise ModelError("arc radius is zero: the centre is the start point", value=center, has_value=True)
        tol = max(RADIUS_RTOL * r0, RADIUS_ATOL)
        if abs(r1 - r0) > tol:
            raise ModelError(f"arc start and end radii differ by {abs(r1 - r0) * 1e6:.4g} µm (start radius "
                             f"{r0 * 1e3:.6g} mm, end radius {r1 * 1e3:.6g} mm; tolerance {tol * 1e6:.3g} µm)")
        a0 = math.atan2(start[j] - center[j], start[i] - center[i])
        a1 = math.atan2(end[j] - center[j], end[i] - center[i])
        if math.hypot(end[i] - start[i], end[j] - start[j]) <= tol:
            sweep = TWO_PI
        else:
            sweep = (a1 - a0) % TWO_PI if not self.clockwise else (a0 - a1) % TWO_PI
        for name, value in (("start", start), ("end", end), ("center", center), ("plane", (i, j)),
                            ("clockwise", bool(self.clockwise)), ("radius", r0), ("start_angle", a0),
                            ("sweep", -sweep if self.clockwise else sweep)):
            object.__setattr__(self, name, value)

    @property
    def dimension(self) -> int:
        """Number of axes."""
        return len(self.start)

    @property
    def length(self) -> float:
        """Arc length (m)."""
        return self.radius * abs(self.sweep)

    def _angle(self, u: np.ndarray) -> np.ndarray:
        return self.start_angle + np.sign(self.sweep) * np.atleast_1d(np.asarray(u, dtype=float)) / self.radius

    def point(self, u: np.ndarray) -> np.ndarray:
        """Points (n, dim) at arc lengths ``u`` (m) from the start."""
        th = self._angle(u)
        out = np.tile(np.asarray(self.start), (th.size, 1))
        i, j = self.plane
        out[:, i] = self.center[i] + self.radius * np.cos(th)
        out[:, j] = self.center[j] + self.radius * np.sin(th)
        return out

    def tangent(self, u: np.ndarray) -> np.ndarray:
        """Unit tangents (n, dim), in the direction of travel."""
        th, sgn = self._angle(u), np.sign(self.sweep)
        out = np.zeros((th.size, self.dimension))
        out[:, self.plane[0]] = -sgn * np.sin(th)
        out[:, self.plane[1]] = sgn * np.cos(th)
        return out

    def curvature(self, u: np.ndarray) -> np.ndarray:
        """Second derivatives d²p/ds² (n, dim) (1/m): towards the centre, magnitude 1/radius."""
        th = self._angle(u)
        out = np.zeros((th.size, self.dimension))
        out[:, self.plane[0]] = -np.cos(th) / self.radius
        out[:, self.plane[1]] = -np.sin(th) / self.radius
        return out


Segment = Line | Arc


@dataclass(frozen=True, eq=False)
class Path:
    """Consecutive lines and arcs, with optional per-segment feeds (m/s) and axis names.

    Parameters
    ----------
    segments : sequence of Line or Arc
        Each starts where the previous one ends (within :data:`RADIUS_ATOL`), all with the same
        number of axes.
    feeds : sequence of float, optional
        Programmed path velocity of each segment (m/s), > 0; used by :func:`interpolate` when it is
        given no feed.
    axis_names : sequence of str, optional
        Default ``("x", "y")`` or ``("x", "y", "z")``.
    """

    segments: tuple[Segment, ...]
    feeds: tuple[float, ...] | None = None
    # None (the default) is replaced by the default names in __post_init__: readers always see a tuple
    axis_names: tuple[str, ...] = None  # type: ignore[assignment]
    starts: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        segments = tuple(self.segments)
        if not segments:
            raise ModelError("a path needs at least one segment")
        for k, seg in enumerate(segments):
            if not isinstance(seg, (Line, Arc)):
                raise ModelError(f"segment {k} must be a Line or an Arc", value=seg, has_value=True)
            if seg.dimension != segments[0].dimension:
                raise ModelError(f"segment {k} has {seg.dimension} axes, segment 0 has {segments[0].dimension}")
        for k in range(1, len(segments)):
            prev_end = segments[k - 1].point(np.array([segments[k - 1].length]))[0]
            gap = float(np.linalg.norm(prev_end - np.asarray(segments[k].start)))
            if gap > RADIUS_ATOL:
                raise ModelError(f"segment {k} starts {gap * 1e6:.4g} µm away from the end of segment {k - 1}: "
                                 "the path must be continuous")
        if self.feeds is not None:
            feeds = tuple(float(f) for f in self.feeds)
            if len(feeds) != len(segments):
                raise ModelError(f"expected {len(segments)} feeds, one per segment (got {len(feeds)})")
            for k, f in enumerate(feeds):
                if not (np.isfinite(f) and f > 0):
                    raise ModelError(f"feed of segment {k} must be > 0 (m/s)", value=f, has_value=True)
            object.__setattr__(self, "feeds", feeds)
        names = tuple(self.axis_names) if self.axis_names is not None else ("x", "y", "z")[:segments[0].dimension]
        if len(names) != segments[0].dimension:
            raise ModelError(f"expected {segments[0].dimension} axis names", value=names, has_value=True)
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "axis_names", names)
        object.__setattr__(self, "starts", np.concatenate([[0.0], np.cumsum([s.length for s in segments])]))

    @property
    def dimension(self) -> int:
        """Number of axes."""
        return self.segments[0].dimension

    @property
    def length(self) -> float:
        """Total arc length (m)."""
        return float(self.starts[-1])

    @property
    def start(self) -> np.ndarray:
        """First point (m)."""
        return np.asarray(self.segments[0].start)

    def locate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment index and arc length inside it for path arc lengths ``s`` (clipped to [0, length])."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        idx = np.clip(np.searchsorted(self.starts, s, side="right") - 1, 0, len(self.segments) - 1)
        return idx, s - self.starts[idx]

    def _evaluate(self, s: np.ndarray, what: str) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        idx, u = self.locate(s.ravel())
        out = np.empty((u.size, self.dimension))
        for k, seg in enumerate(self.segments):
            sel = idx == k
            if sel.any():
                out[sel] = getattr(seg, what)(u[sel])
        return out.reshape(s.shape + (self.dimension,))

    def point(self, s: np.ndarray) -> np.ndarray:
        """Points (m) at arc lengths ``s`` (m): shape ``s.shape + (dimension,)``."""
        return self._evaluate(s, "point")

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """Unit tangents at arc lengths ``s`` (m): shape ``s.shape + (dimension,)``."""
        return self._evaluate(s, "tangent")

    def curvature(self, s: np.ndarray) -> np.ndarray:
        """Curvature vectors d²p/ds² (1/m) at arc lengths ``s``: shape ``s.shape + (dimension,)``."""
        return self._evaluate(s, "curvature")

def _positive(name: str, value: float) -> float:
    if value is None or not np.isfinite(value) or value <= 0:
        raise ModelError(f"{name} must be a finite number > 0", value=value, has_value=True)
    return float(value)


@dataclass(frozen=True, eq=False)
class CircleTestPath:
    """A circle-test path and the arc-length interval ``window = (s0, s1)`` (m) of the evaluated 360°."""

    path: Path
    window: tuple[float, float]
    center: tuple[float, ...]
    radius: float
    clockwise: bool
    start_angle: float

    def window_mask(self, s: np.ndarray) -> np.ndarray:
        """True for arc lengths ``s`` (m) inside the evaluated 360° (half-open ``[s0, s1)``)."""
        s = np.asarray(s, dtype=float)
        return (s >= self.window[0]) & (s < self.window[1])


def circle_test_path(center: Sequence[float], radius: float, clockwise: bool = False, *,
                     lead_in_angle: float = math.pi, lead_out_angle: float | None = None,
                     start_angle: float = 0.0) -> CircleTestPath:
    """The ballbar (ISO 230-4) circle: lead-in arc, the evaluated full circle, lead-out arc.

    All three arcs lie on the test circle itself, as in a ballbar run (the bar's length is fixed):
    the lead-in arc (default 180°) ends at ``start_angle`` where the evaluated 360° begins, and the
    lead-out arc (default: as long as the lead-in) follows it. The path is tangent-continuous, so
    :func:`interpolate` crosses it with one S-curve: the acceleration happens on the lead-in and the
    braking on the lead-out, and the evaluated circle is run at constant speed provided the lead-in
    is longer than the acceleration distance (``feed·(feed/a + a/j)/2`` when ``feed·j ≥ a²``).

    Parameters
    ----------
    center : sequence of float
        Circle centre (m), 2 or 3 coordinates (the circle is in the X-Y plane).
    radius : float
        Nominal radius (m), > 0.
    clockwise : bool
        Direction of travel seen from +Z (G02 when True).
    lead_in_angle, lead_out_angle : float
        Lengths of the lead-in and lead-out arcs (rad), in [0, 2π].
    start_angle : float
        Polar angle (rad) at which the evaluated circle starts and ends.

    Returns
    -------
    CircleTestPath
    """
    radius = _positive("radius", radius)
    lead_out_angle = lead_in_angle if lead_out_angle is None else lead_out_angle
    for name, value in (("lead_in_angle", lead_in_angle), ("lead_out_angle", lead_out_angle)):
        if not (0.0 <= value <= TWO_PI):
            raise ModelError(f"{name} must be between 0 and 2π rad", value=value, has_value=True)
    c = np.asarray(_point(center, "circle centre"))
    centre = tuple(float(v) for v in c)
    sgn = -1.0 if clockwise else 1.0

    def at(angle: float) -> tuple[float, ...]:
        p = c.copy()
        p[:2] += radius * np.array([math.cos(angle), math.sin(angle)])
        return tuple(float(v) for v in p)

    segments: list[Segment] = []
    if lead_in_angle > 0:
        segments.append(Arc(at(start_angle - sgn * lead_in_angle), at(start_angle), centre, clockwise))
    segments.append(Arc(at(start_angle), at(start_angle), centre, clockwise))
    if lead_out_angle > 0:
        segments.append(Arc(at(start_angle), at(start_angle + sgn * lead_out_angle), centre, clockwise))
    s0 = radius * lead_in_angle
    return CircleTestPath(Path(tuple(segments)), (s0, s0 + TWO_PI * radius), tuple(float(v) for v in c), radius,
                          bool(clockwise), float(start_angle))
