"""Jerk-limited setpoints: the time-optimal 7-segment S-curve and sequences of such moves along a path."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["JerkProfile", "scurve_profile", "scurve_sequence", "scurve_durations"]


@dataclass(frozen=True)
class JerkProfile:
    """A piecewise-cubic setpoint: constant jerk inside each piece.

    Same interface as :class:`sicomat.motion.setpoints.Profile` (``evaluate(t) -> (position, velocity,
    acceleration)``, ``distance``, ``end_time``, ``breaks``, ``kind``) plus :meth:`jerk`.

    Attributes
    ----------
    breaks : tuple of float
        Start time of each piece (s), increasing. After the last break the profile is at rest.
    positions, velocities, accelerations : tuple of float
        Position (m), velocity (m/s) and acceleration (m/s²) at the start of each piece.
    jerks : tuple of float
        Jerk inside each piece (m/s³).
    segment_durations : tuple of float
        For each rest-to-rest move, the seven phase durations (s) ``(t_j, t_a, t_j, t_v, t_j, t_a,
        t_j)``: jerk up, constant acceleration, jerk down, cruise, and the mirror image. Zero-length
        phases are kept here but have no piece in ``breaks``.
    kind : str
        ``"s-curve"`` for one move, ``"s-curve sequence"`` for several.

    Before the first break everything is 0, like :class:`~sicomat.motion.setpoints.Profile`.
    """

    breaks: tuple[float, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    accelerations: tuple[float, ...]
    jerks: tuple[float, ...]
    segment_durations: tuple[float, ...] = ()
    kind: str = "s-curve"

    @property
    def distance(self) -> float:
        """Net displacement (m) at the end of the profile."""
        return float(self.positions[-1])

    @property
    def end_time(self) -> float:
        """Time of the last break (s): from then on the profile is at rest."""
        return float(self.breaks[-1])

    @property
    def duration(self) -> float:
        """Time from the first to the last break (s)."""
        return float(self.breaks[-1] - self.breaks[0])

    def _pieces(self, t: np.ndarray):
        breaks = np.asarray(self.breaks)
        idx = np.searchsorted(breaks, t, side="right") - 1
        before = idx < 0
        idx = np.clip(idx, 0, len(breaks) - 1)
        return idx, before, t - breaks[idx]

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (m), velocity (m/s) and acceleration (m/s²) at times ``t`` (s), arrays of ``t``'s shape."""
        t = np.asarray(t, dtype=float)
        idx, before, dt = self._pieces(t)
        p0, v0, a0, j0 = (np.asarray(x)[idx] for x in
                          (self.positions, self.velocities, self.accelerations, self.jerks))
        pos = p0 + dt * (v0 + dt * (a0 / 2 + dt * j0 / 6))
        vel = v0 + dt * (a0 + dt * j0 / 2)
        acc = a0 + dt * j0
        zero = np.zeros_like(pos)
        return np.where(before, zero, pos), np.where(before, zero, vel), np.where(before, zero, acc)

    def jerk(self, t: np.ndarray) -> np.ndarray:
        """Jerk (m/s³) at times ``t`` (s); at a break, the jerk of the piece that starts there."""
        t = np.asarray(t, dtype=float)
        idx, before, _ = self._pieces(t)
        return np.where(before, 0.0, np.asarray(self.jerks)[idx])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: kind, distance (m), start and end time (s), phase durations (s)."""
        return {"kind": self.kind, "distance": self.distance, "start": float(self.breaks[0]),
                "end_time": self.end_time, "segment_durations": list(self.segment_durations)}

    def plot(self):
        """Position, velocity, acceleration and jerk against time; returns the Figure."""
        from ..plots.motion import plot_jerk_profile

        return plot_jerk_profile(self)


def _check_limits(max_velocity: float, max_acceleration: float, max_jerk: float) -> None:
    for name, value in (("max_velocity", max_velocity), ("max_acceleration", max_acceleration),
                        ("max_jerk", max_jerk)):
        if not np.isfinite(value) or value <= 0:
            raise ModelError(f"{name} must be a finite number > 0", value=value, has_value=True)


def scurve_durations(distance: float, max_velocity: float, max_acceleration: float,
                     max_jerk: float) -> tuple[float, float, float]:
    """Phase durations ``(t_j, t_a, t_v)`` (s) of the time-optimal rest-to-rest move over ``|distance|``.

    ``t_j`` is each of the four jerk phases, ``t_a`` each of the two constant-acceleration phases and
    ``t_v`` the cruise phase; the move lasts ``4 t_j + 2 t_a + t_v``.

    Parameters
    ----------
    distance : float
        Displacement (m); only its magnitude matters.
    max_velocity, max_acceleration, max_jerk : float
        Limits (m/s, m/s², m/s³), each > 0.

    Raises
    ------
    ModelError
        (a ``ValueError``) if a limit is not a finite number > 0.
    """
    _check_limits(max_velocity, max_acceleration, max_jerk)
    d, v, a, j = abs(float(distance)), float(max_velocity), float(max_acceleration), float(max_jerk)
    if d == 0.0:
        return 0.0, 0.0, 0.0
    # the acceleration phase that reaches v: a is reached iff v j >= a^2
    if v * j >= a * a:
        tj, ta = a / j, v / a - a / j
    else:
        tj, ta = np.sqrt(v / j), 0.0
    d_v = v * (2 * tj + ta)          # distance of accelerating to v and braking back (symmetric)
    if d >= d_v:
        return float(tj), float(ta), float((d - d_v) / v)
    # v is not reached; a is reached iff d >= 2 a^3 / j^2 (peak velocity a^2/j, no plateau)
    if d >= 2 * a ** 3 / j ** 2:
        tj = a / j
        ta = (-3 * tj + np.sqrt(tj * tj + 4 * d / a)) / 2     # d = a (tj + ta) (2 tj + ta)
        return float(tj), float(max(ta, 0.0)), 0.0
    return float(np.cbrt(d / (2 * j))), 0.0, 0.0               # d = 2 j tj^3


def _append_move(pieces: list, state: list, durations: Sequence[float], jerks: Sequence[float],
                 t: float) -> float:
    """Integrate the phases of one move from ``state = [p, v, a]``, appending the non-empty pieces."""
    p, v, a = state
    for d, jj in zip(durations, jerks):
        if d <= 0.0:
            continue
        pieces.append((t, p, v, a, jj))
        p, v, a = (p + d * (v + d * (a / 2 + d * jj / 6)), v + d * (a + d * jj / 2), a + d * jj)
        t += d
    state[:] = [p, v, a]
    return t


def scurve_sequence(distances: Sequence[float], max_velocities: Sequence[float] | float,
                    max_acceleration: float, max_jerk: float, start: float = 0.0) -> JerkProfile:
    """Rest-to-rest S-curve moves one after the other, as one profile of the summed displacement.

    This is the velocity profile along a path's arc length ``s``: each entry is a stretch of the path
    (m) crossed without stopping, at most at its own velocity limit, and the move stops at the end of
    each stretch. Each move is time-optimal under the limits (see :func:`scurve_profile`).

    Parameters
    ----------
    distances : sequence of float
        Signed displacements of the successive moves (m).
    max_velocities : float or sequence of float
        Velocity limit (m/s) of every move, or one per move; each > 0.
    max_acceleration : float
        Acceleration limit (m/s²), > 0.
    max_jerk : float
        Jerk limit (m/s³), > 0.
    start : float
        Time (s) at which the first move starts.

    Returns
    -------
    JerkProfile
        ``kind="s-curve sequence"``; ``segment_durations`` holds seven phases per move.

    Raises
    ------
    ModelError
        (a ``ValueError``) a limit ≤ 0 or not finite, or not one velocity limit per move.

    Examples
    --------
    >>> prof = scurve_sequence([0.1, -0.05], 0.5, 5.0, 100.0)
    >>> round(prof.distance, 12)
    0.05
    """
    distances = [float(d) for d in distances]
    for d in distances:
        if not np.isfinite(d):
            raise ModelError("distance must be a finite number", value=d, has_value=True)
    if not distances:
        raise ModelError("scurve_sequence needs at least one move")
    vmax = np.broadcast_to(np.asarray(max_velocities, dtype=float), (len(distances),)) \
        if np.ndim(max_velocities) == 0 else np.asarray(max_velocities, dtype=float)
    if vmax.shape != (len(distances),):
        raise ModelError(f"expected {len(distances)} velocity limits, one per move (got {vmax.size})")
    pieces: list = []
    state = [0.0, 0.0, 0.0]
    phases: list[float] = []
    t, target = float(start), 0.0
    for d, v in zip(distances, vmax):
        tj, ta, tv = scurve_durations(d, float(v), max_acceleration, max_jerk)
        jj = max_jerk if d >= 0 else -max_jerk
        durations = (tj, ta, tj, tv, tj, ta, tj)
        t = _append_move(pieces, state, durations, (jj, 0.0, -jj, 0.0, -jj, 0.0, jj), t)
        target += d
        state[:] = [target, 0.0, 0.0]         # exactly at rest on the target: no drift of rounding
        phases.extend(durations)
    pieces.append((t, target, 0.0, 0.0, 0.0))
    br, pos, vel, acc, jer = (tuple(float(x) for x in col) for col in zip(*pieces))
    kind = "s-curve" if len(distances) == 1 else "s-curve sequence"
    return JerkProfile(br, pos, vel, acc, jer, tuple(float(x) for x in phases), kind)


def scurve_profile(distance: float, max_velocity: float, max_acceleration: float, max_jerk: float,
                   start: float = 0.0) -> JerkProfile:
    """Time-optimal rest-to-rest move under velocity, acceleration and jerk limits (7-segment S-curve).

    The jerk is ``±max_jerk`` or 0 (bang-zero-bang); each limit is reached only when the distance
    allows it, so the profile covers all regimes: velocity and acceleration limits both reached,
    only one of them, or neither (then the move is four jerk phases of ``(|distance| / 2 j)^(1/3)``).

    Parameters
    ----------
    distance : float
        Signed displacement (m); 0 gives a profile that stays at rest.
    max_velocity : float
        Velocity limit (m/s), > 0.
    max_acceleration : float
        Acceleration limit (m/s²), > 0.
    max_jerk : float
        Jerk limit (m/s³), > 0.
    start : float
        Time (s) at which the move starts.

    Returns
    -------
    JerkProfile
        ``kind="s-curve"``, ``segment_durations`` the seven phases (s).

    Raises
    ------
    ModelError
        (a ``ValueError``) if a limit is not a finite number > 0.

    Examples
    --------
    Both limits reached: the move lasts ``D/v + v/a + a/j``.

    >>> prof = scurve_profile(0.5, 1.0, 10.0, 200.0)
    >>> round(prof.end_time, 12)
    0.65
    """
    return scurve_sequence([distance], [max_velocity], max_acceleration, max_jerk, start)
