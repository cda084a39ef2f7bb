"""Multi-axis paths (lines and circular arcs), the CNC interpolator along them, and the circle-test path."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..budget import require_memory
from ..errors import ModelError
from .trajectory import JerkProfile, scurve_sequence

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["Line", "Arc", "Path", "PathSamples", "AxisSetpoint", "CircleTestPath", "interpolate",
           "circle_test_path", "RADIUS_RTOL", "RADIUS_ATOL"]

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


@dataclass(frozen=True)
class AxisSetpoint:
    """One axis of an interpolated path as a setpoint profile (interface of ``setpoints.Profile``).

    ``evaluate(t)`` is exact at any time (the S-curve in arc length mapped through the geometry);
    positions are relative to ``offset``, the axis coordinate at the path's start (m), so that a
    plant at rest at 0 starts on the path.
    """

    path: Path
    profile: JerkProfile
    axis: int
    offset: float
    kind: str = "path axis"

    @property
    def name(self) -> str:
        """Axis name, e.g. ``"x"``."""
        return self.path.axis_names[self.axis]

    @property
    def breaks(self) -> tuple[float, ...]:
        """Breaks of the arc-length profile (s)."""
        return self.profile.breaks

    @property
    def end_time(self) -> float:
        """Time at which the path is finished (s)."""
        return self.profile.end_time

    @property
    def distance(self) -> float:
        """Net displacement of the axis over the path (m)."""
        return float(self.path.point(np.array(self.path.length))[self.axis] - self.path.start[self.axis])

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (m, relative to ``offset``), velocity (m/s), acceleration (m/s²) at times ``t`` (s)."""
        s, sd, sdd = self.profile.evaluate(t)
        k = self.axis
        pos = self.path.point(s)[..., k] - self.offset
        tan = self.path.tangent(s)[..., k]
        return pos, tan * sd, tan * sdd + self.path.curvature(s)[..., k] * sd ** 2


@dataclass(frozen=True, eq=False)
class PathSamples:
    """The interpolator's output at its sample period (SI units).

    Attributes
    ----------
    time : ndarray (n,)
        Sample times (s), ``start + k·period``, up to and including the end of the motion.
    s, path_velocity, path_acceleration, path_jerk : ndarray (n,)
        Arc length (m) along the path and its derivatives (m/s, m/s², m/s³).
    position, velocity, acceleration : ndarray (n, dimension)
        Per-axis setpoints (m, m/s, m/s²), columns in ``path.axis_names`` order.
    path : Path
    profile : JerkProfile
        The arc length as a function of time.
    period : float
        Interpolator period (s).
    """

    time: np.ndarray
    s: np.ndarray
    path_velocity: np.ndarray
    path_acceleration: np.ndarray
    path_jerk: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    path: Path
    profile: JerkProfile
    period: float

    def axis_setpoint(self, axis: str | int) -> AxisSetpoint:
        """The exact setpoint of one axis (by name or index), for a single-axis simulation."""
        k = self.path.axis_names.index(axis) if isinstance(axis, str) else int(axis)
        return AxisSetpoint(self.path, self.profile, k, float(self.path.start[k]))

    def to_pandas(self) -> "pandas.DataFrame":
        """A DataFrame indexed by time (s): ``s``, ``path.velocity``, ``path.acceleration`` and, per axis,
        ``<axis>.position``, ``<axis>.velocity``, ``<axis>.acceleration``."""
        import pandas as pd

        cols = {"s": self.s, "path.velocity": self.path_velocity, "path.acceleration": self.path_acceleration}
        for k, name in enumerate(self.path.axis_names):
            cols.update({f"{name}.position": self.position[:, k], f"{name}.velocity": self.velocity[:, k],
                         f"{name}.acceleration": self.acceleration[:, k]})
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time"))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: duration (s), length (m), period (s), samples, peak values per axis."""
        names = self.path.axis_names
        return {"duration": self.profile.duration, "length": self.path.length, "period": self.period,
                "samples": int(self.time.size),
                "max_path_velocity": float(np.max(np.abs(self.path_velocity))),
                "max_path_acceleration": float(np.max(np.abs(self.path_acceleration))),
                "max_velocity": {n: float(np.max(np.abs(self.velocity[:, k]))) for k, n in enumerate(names)},
                "max_acceleration": {n: float(np.max(np.abs(self.acceleration[:, k]))) for k, n in enumerate(names)}}

    def plot(self):
        """The path in the plane of its first two axes and the path velocity against time; returns the Figure."""
        from ..plots.motion import plot_path_samples

        return plot_path_samples(self)


def _positive(name: str, value: float) -> float:
    if value is None or not np.isfinite(value) or value <= 0:
        raise ModelError(f"{name} must be a finite number > 0", value=value, has_value=True)
    return float(value)


def _groups(path: Path, feeds: Sequence[float], corner_tolerance: float) -> list[tuple[int, int]]:
    """Runs ``[first, last]`` of segments crossed without stopping: tangent junctions, same feed."""
    groups, first = [], 0
    for k in range(1, len(path.segments)):
        prev, seg = path.segments[k - 1], path.segments[k]
        t_out = prev.tangent(np.array([prev.length]))[0]
        t_in = seg.tangent(np.array([0.0]))[0]
        angle = math.acos(float(np.clip(t_out @ t_in, -1.0, 1.0)))
        if angle > corner_tolerance or feeds[k] != feeds[k - 1]:
            groups.append((first, k - 1))
            first = k
    groups.append((first, len(path.segments) - 1))
    return groups


def interpolate(path: Path, feed: float | None, max_acceleration: float, max_jerk: float, period: float,
                *, corner_tolerance: float = 1e-3, start: float = 0.0) -> PathSamples:
    """Interpolate ``path`` as a CNC does: a jerk-limited S-curve in arc length, sampled every ``period``.

    The path is cut into runs crossed without stopping: a junction whose tangents differ by more than
    ``corner_tolerance`` (rad), or where the programmed feed changes, is an exact stop. Each run is one
    time-optimal rest-to-rest S-curve (:func:`~sicomat.motion.trajectory.scurve_sequence`) with
    ``|s̈| ≤ max_acceleration``, ``|s⃛| ≤ max_jerk`` and ``ṡ ≤ min(feed, √(max_acceleration·R))`` over
    its arcs (radius R), so that the centripetal acceleration ``ṡ²/R`` stays within
    ``max_acceleration`` (while the speed changes on an arc the per-axis acceleration can reach
    ``√(s̈² + (ṡ²/R)²)``). A slow arc therefore slows its whole run (conservative: no look-ahead).

    Parameters
    ----------
    path : Path
    feed : float or None
        Path velocity (m/s), > 0, for every segment; ``None`` uses ``path.feeds``.
    max_acceleration : float
        Path acceleration limit (m/s²), > 0.
    max_jerk : float
        Path jerk limit (m/s³), > 0.
    period : float
        Interpolator sample period (s), > 0.
    corner_tolerance : float
        Largest tangent angle (rad) still crossed at speed.
    start : float
        Time (s) at which the motion starts.

    Returns
    -------
    PathSamples

    Raises
    ------
    ModelError
        A feed, limit or period that is not > 0, or no feed at all.

    Examples
    --------
    >>> p = Path([Line((0, 0), (0.1, 0)), Arc((0.1, 0), (0.1, 0.1), (0.1, 0.05), clockwise=False)])
    >>> out = interpolate(p, 0.05, 1.0, 20.0, 1e-3)
    >>> bool(out.path_velocity.max() <= 0.05)
    True
    """
    a_max = _positive("max_acceleration", max_acceleration)
    j_max = _positive("max_jerk", max_jerk)
    period = _positive("period", period)
    if feed is not None:
        feeds = [_positive("feed", feed)] * len(path.segments)
    elif path.feeds is not None:
        feeds = list(path.feeds)
    else:
        raise ModelError("no feed: pass feed= (m/s) or give the path its feeds")
    lengths, limits = [], []
    for first, last in _groups(path, feeds, corner_tolerance):
        segs = path.segments[first:last + 1]
        lengths.append(sum(s.length for s in segs))
        limits.append(min([feeds[first]] + [math.sqrt(a_max * s.radius) for s in segs if isinstance(s, Arc)]))
    profile = scurve_sequence(lengths, limits, a_max, j_max, start=start)
    n_float = math.ceil(profile.duration / period - 1e-9) + 1.0
    # time, s and its three derivatives, and position, velocity, acceleration per axis; as much again
    # for the temporaries of the evaluation (tangents, curvatures)
    values = 5 + 3 * path.dimension
    require_memory(16.0 * n_float * values, "this path interpolation",
                   f"{n_float:.0f} samples of {period:g} s x {values} values x 8 bytes, twice")
    n = int(n_float)
    t = start + period * np.arange(n)
    s, sd, sdd = profile.evaluate(t)
    s = np.clip(s, 0.0, path.length)
    tan, curv = path.tangent(s), path.curvature(s)
    return PathSamples(time=t, s=s, path_velocity=sd, path_acceleration=sdd, path_jerk=profile.jerk(t),
                       position=path.point(s), velocity=tan * sd[:, None],
                       acceleration=tan * sdd[:, None] + curv * (sd ** 2)[:, None],
                       path=path, profile=profile, period=period)


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
