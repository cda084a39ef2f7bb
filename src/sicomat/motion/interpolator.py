"""The CNC interpolator: one jerk-limited S-curve in arc length along a :class:`~sicomat.motion.path.Path`,
sampled at the position-loop period, and each axis of it as a setpoint profile."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..budget import require_memory
from ..errors import ModelError
from .path import Arc, Path, _positive
from .trajectory import JerkProfile, scurve_sequence

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["AxisSetpoint", "PathSamples", "interpolate"]


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
    >>> from sicomat.motion import Arc, Line, Path
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
