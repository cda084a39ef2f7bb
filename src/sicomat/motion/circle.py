"""The circle test (ISO 230-4, the ballbar test): deviations of an actual circular path from the nominal one."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["CircleResult", "ReversalSpike", "evaluate_circle", "least_squares_circle"]

QUADRANTS_DEG = (0.0, 90.0, 180.0, 270.0)


@dataclass(frozen=True)
class ReversalSpike:
    """The spike of radial deviation where an axis reverses (m, outward positive).

    ``quadrant_deg`` is the nominal quadrant point (0, 90, 180, 270), ``axis`` the axis that reverses
    there (the first axis at 0° and 180°, the second at 90° and 270°), ``height`` the signed peak of
    the radial deviation within the spike window relative to its neighbourhood, ``angle_deg`` where
    that peak is.
    """

    quadrant_deg: float
    axis: str
    height: float
    angle_deg: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return dict(self.__dict__)


@dataclass(frozen=True, eq=False)
class CircleResult:
    """Figures of an ISO 230-4 circle test (metres, radians; outward deviations positive).

    Attributes
    ----------
    center, radius : nominal circle (m).
    clockwise : direction of travel (seen from +Z).
    angle : ndarray
        Polar angle (rad) of each evaluated sample about the nominal centre.
    radial_deviation : ndarray
        ``F(θ) = r − R`` about the nominal centre (m), outward positive.
    radial_deviation_min, radial_deviation_max : float
        ISO 230-4 radial deviation ``F min`` and ``F max`` (m), about the nominal centre.
    mean_radial_deviation : float
        Mean of ``F`` over the samples (m).
    circular_deviation : float
        ISO 230-4 circular deviation ``G`` (m): the radial range (max − min radius) about the
        least-squares circle centre.
    lsc_center, lsc_radius : least-squares circle (m).
    reversal_spikes : tuple of ReversalSpike
        At 0°, 90°, 180°, 270°.
    servo_mismatch : float
        Amplitude (m) of the 2nd harmonic of ``F(θ)``: the elliptical component, half its
        peak-to-valley.
    servo_mismatch_angle : float
        Direction (rad, in (−π/2, π/2]) of the ellipse's major axis; ±45° for a gain mismatch.
    servo_mismatch_time : float or None
        With ``feed`` given: the lag mismatch ``1/Kv_y − 1/Kv_x`` (s) that explains the 45° part of the
        ellipse (positive when the second axis lags more). Squareness also makes a 45° ellipse, but of
        the same sign in both directions; a servo mismatch changes sign between CW and CCW.
    feed : float or None
        Path velocity of the test (m/s) when known.
    """

    center: tuple[float, float]
    radius: float
    clockwise: bool
    angle: np.ndarray
    radial_deviation: np.ndarray
    radial_deviation_min: float
    radial_deviation_max: float
    mean_radial_deviation: float
    circular_deviation: float
    lsc_center: tuple[float, float]
    lsc_radius: float
    reversal_spikes: tuple[ReversalSpike, ...]
    servo_mismatch: float
    servo_mismatch_angle: float
    servo_mismatch_time: float | None = None
    feed: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures (SI; angles in degrees where the key says ``_deg``); no sample arrays."""
        return {"circular_deviation": self.circular_deviation,
                "radial_deviation_min": self.radial_deviation_min,
                "radial_deviation_max": self.radial_deviation_max,
                "mean_radial_deviation": self.mean_radial_deviation,
                "reversal_spikes": [s.to_dict() for s in self.reversal_spikes],
                "servo_mismatch": self.servo_mismatch,
                "servo_mismatch_angle_deg": math.degrees(self.servo_mismatch_angle),
                "servo_mismatch_time": self.servo_mismatch_time,
                "lsc_center": list(self.lsc_center), "lsc_radius": self.lsc_radius,
                "center": list(self.center), "radius": self.radius, "clockwise": self.clockwise,
                "feed": self.feed, "samples": int(self.angle.size),
                "radius_mm": self.radius * 1e3,
                "feed_mm_min": None if self.feed is None else self.feed * 6e4}

    def plot(self, magnification: float | None = None, *, label: str | None = None,
             others: "Mapping[str, CircleResult] | None" = None):
        """Polar plot of the radial deviation, magnified, as a ballbar report shows it; ``others`` (by
        label) are drawn beside it, thinner; returns the Figure."""
        from ..plots.motion import plot_circle

        return plot_circle(self, magnification, label=label, others=others)


def least_squares_circle(x: np.ndarray, y: np.ndarray, center: Sequence[float] | None = None,
                         iterations: int = 50) -> tuple[tuple[float, float], float]:
    """Centre (m) and radius (m) minimising ``Σ (r_i − ρ)²``, by Gauss-Newton from ``center``.

    Starts from ``center`` (default: the algebraic Kåsa fit) and stops when the step is below
    1e-15 of the radius.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if center is None:
        design = np.column_stack([x, y, np.ones_like(x)])
        sol = np.linalg.lstsq(design, x * x + y * y, rcond=None)[0]
        center = (sol[0] / 2, sol[1] / 2)
    a, b = float(center[0]), float(center[1])
    rho = float(np.mean(np.hypot(x - a, y - b)))
    for _ in range(iterations):
        dx, dy = x - a, y - b
        r = np.hypot(dx, dy)
        jac = np.column_stack([-dx / r, -dy / r, -np.ones_like(r)])
        step = np.linalg.lstsq(jac, -(r - rho), rcond=None)[0]
        a, b, rho = a + step[0], b + step[1], rho + step[2]
        if np.max(np.abs(step)) <= 1e-15 * max(abs(rho), 1e-300):
            break
    return (float(a), float(b)), float(np.mean(np.hypot(x - a, y - b)))


def _harmonics(theta: np.ndarray, order: int = 2) -> np.ndarray:
    cols = [np.ones_like(theta)]
    for k in range(1, order + 1):
        cols += [np.cos(k * theta), np.sin(k * theta)]
    return np.column_stack(cols)


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def evaluate_circle(x: np.ndarray, y: np.ndarray, center: Sequence[float], radius: float, *,
                    mask: np.ndarray | None = None, s: np.ndarray | None = None,
                    window: tuple[float, float] | None = None, clockwise: bool | None = None,
                    feed: float | None = None, spike_window_deg: float = 5.0,
                    axis_names: tuple[str, str] = ("x", "y")) -> CircleResult:
    """Evaluate a circle test as ISO 230-4 does (the ballbar test).

    Parameters
    ----------
    x, y : array_like (n,)
        Actual positions of the two axes (m), in time order.
    center : sequence of float
        Nominal centre (m); a third coordinate is ignored.
    radius : float
        Nominal radius (m), > 0.
    mask : array_like of bool (n,), optional
        Samples to evaluate (the steady 360°).
    s, window : optional
        Alternatively (or in addition), the setpoint's arc length per sample (m) and the interval
        ``[s0, s1)`` to evaluate, e.g. :attr:`sicomat.motion.path.CircleTestPath.window`.
    clockwise : bool, optional
        Direction of travel; by default found from the data.
    feed : float, optional
        Path velocity (m/s): gives :attr:`CircleResult.servo_mismatch_time`.
    spike_window_deg : float
        Half-width (°) of the zone around each quadrant point where a reversal spike is sought; its
        neighbourhood is the zone between 1× and 3× that half-width on both sides.
    axis_names : (str, str)
        Names of the two axes, for the reversal spikes.

    Returns
    -------
    CircleResult

    Notes
    -----
    Radial deviation ``F`` is taken about the nominal centre (the ballbar's pivot) and circular
    deviation ``G`` about the least-squares circle centre, following ISO 230-4. The elliptical
    component is the 2nd harmonic of ``F(θ)``, fitted by least squares together with the 0th and
    1st harmonics on the samples outside the spike zones. A first-order follower of gain Kv per axis
    at feed v gives ``F ≈ −v²/(2 Kv² R)``; with ``Kv_x ≠ Kv_y`` the ellipse has amplitude
    ``≈ v·|1/Kv_y − 1/Kv_x|/2`` and its major axis at −45° counter-clockwise (+45° clockwise) when the
    Y axis lags more. A reversal spike's height is the signed extreme of the residual of that fit
    within ``spike_window_deg`` of the quadrant point, relative to the residual's median in the
    neighbourhood.

    Raises
    ------
    ModelError
        Arrays of different lengths, fewer than 16 samples selected, a radius ≤ 0.
    """
    x, y = np.asarray(x, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    if x.shape != y.shape:
        raise ModelError(f"x and y must have the same length ({x.size} and {y.size})")
    if not (np.isfinite(radius) and radius > 0):
        raise ModelError("radius must be a finite number > 0 (m)", value=radius, has_value=True)
    keep = np.ones(x.size, dtype=bool)
    if mask is not None:
        keep &= np.asarray(mask, dtype=bool).ravel()
    if window is not None:
        if s is None:
            raise ModelError("window needs s, the setpoint's arc length per sample")
        s = np.asarray(s, dtype=float).ravel()
        keep &= (s >= window[0]) & (s < window[1])
    if keep.shape != x.shape or keep.sum() < 16:
        raise ModelError(f"the circle test needs at least 16 selected samples (got {int(keep.sum())})")
    x, y = x[keep], y[keep]
    cx, cy = float(center[0]), float(center[1])
    theta = np.arctan2(y - cy, x - cx)
    deviation = np.hypot(x - cx, y - cy) - radius
    if clockwise is None:
        clockwise = bool(np.sum(np.diff(np.unwrap(theta))) < 0)
    lsc_center, lsc_radius = least_squares_circle(x, y, (cx, cy))
    r_lsc = np.hypot(x - lsc_center[0], y - lsc_center[1])

    half = math.radians(spike_window_deg)
    quadrants = np.radians(QUADRANTS_DEG)
    near_any = np.zeros(theta.size, dtype=bool)
    for q in quadrants:
        near_any |= np.abs(_wrap(theta - q)) <= half
    fit_on = ~near_any if (~near_any).sum() >= 16 else np.ones_like(near_any)
    coef = np.linalg.lstsq(_harmonics(theta[fit_on]), deviation[fit_on], rcond=None)[0]
    residual = deviation - _harmonics(theta) @ coef
    a2, b2 = coef[3], coef[4]

    spikes = []
    for q_deg, q in zip(QUADRANTS_DEG, quadrants):
        d = np.abs(_wrap(theta - q))
        near, flank = d <= half, (d > half) & (d <= 3 * half)
        height, at = float("nan"), float("nan")
        if near.any():
            local = residual[near] - (np.median(residual[flank]) if flank.any() else 0.0)
            k = int(np.argmax(np.abs(local)))
            height, at = float(local[k]), float(np.degrees(theta[near][k]) % 360.0)
        spikes.append(ReversalSpike(q_deg, axis_names[0] if q_deg in (0.0, 180.0) else axis_names[1], height, at))

    angle = 0.5 * math.atan2(b2, a2)
    if angle <= -math.pi / 2:
        angle += math.pi
    mismatch_time = None
    if feed is not None:
        mismatch_time = float((2.0 if clockwise else -2.0) * b2 / feed)
    return CircleResult(center=(cx, cy), radius=float(radius), clockwise=bool(clockwise), angle=theta,
                        radial_deviation=deviation, radial_deviation_min=float(deviation.min()),
                        radial_deviation_max=float(deviation.max()),
                        mean_radial_deviation=float(deviation.mean()),
                        circular_deviation=float(r_lsc.max() - r_lsc.min()), lsc_center=lsc_center,
                        lsc_radius=lsc_radius, reversal_spikes=tuple(spikes),
                        servo_mismatch=float(math.hypot(a2, b2)), servo_mismatch_angle=float(angle),
                        servo_mismatch_time=mismatch_time, feed=None if feed is None else float(feed))
