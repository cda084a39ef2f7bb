"""Figures of setpoints, paths, path runs and circle tests (matplotlib Figure, no pyplot). Computing never happens here."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Mapping, cast

import numpy as np

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure
    from matplotlib.projections.polar import PolarAxes

    from ..motion.circle import CircleResult
    from ..motion import PathSamples
    from ..motion.trajectory import JerkProfile

__all__ = ["plot_circle", "plot_path_samples", "plot_jerk_profile", "plot_path_run", "auto_magnification",
           "magnified_trace"]


def _nice_step(span: float) -> float:
    """A 1-2-5 step giving about three rings over ``span``."""
    raw = max(span, 1e-15) / 3
    exp = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10 ** exp >= raw:
            return m * 10 ** exp
    return 10 ** (exp + 1)  # pragma: no cover


def plot_circle(result: "CircleResult", magnification: float | None = None, *, label: str | None = None,
                others: "Mapping[str, CircleResult] | None" = None) -> "Figure":
    """Ballbar-style polar plot: nominal circle, radial deviation magnified, figures in the title.

    The nominal circle is drawn at unit radius and a deviation ``F`` at ``1 + magnification·F/R``;
    the rings are labelled in µm of deviation. By default the magnification is the 1-2-5 value that draws
    the largest deviation at 8–20 % of the radius (:func:`auto_magnification`); the
    factor is in the title and the legend. ``label`` names the figure's trace (a model); ``others`` are
    circles of other models drawn thinner beside it (the figures in the title are ``result``'s).
    """
    dev, radius = result.radial_deviation, result.radius
    others = dict(others or {})
    peak = max([float(np.max(np.abs(c.radial_deviation))) for c in [result, *others.values()] if c.radial_deviation.size],
               default=0.0)
    if magnification is None:
        magnification = auto_magnification(peak, radius)
    scale = magnification / radius                         # plot units per metre of deviation
    order = np.argsort(result.angle)
    theta = np.append(result.angle[order], result.angle[order][0] + 2 * math.pi)
    rho = 1.0 + scale * np.append(dev[order], dev[order][0])
    if others:
        fig = new_figure(figsize=(6.4, 9.0), layout="none")
        ax = cast("PolarAxes", fig.add_axes((0.1, 0.32, 0.8, 0.56), projection="polar"))
    else:
        fig = new_figure(figsize=(6.4, 6.8))
        ax = cast("PolarAxes", fig.add_subplot(projection="polar"))
    circle = np.linspace(0, 2 * math.pi, 361)
    ax.plot(circle, np.ones_like(circle), color="gray", linestyle="--", linewidth=0.8, label="nominal")
    name = f"{label}: actual" if label else "actual"
    ax.plot(theta, rho, color="tab:blue", linewidth=1.2, label=f"{name} (deviation ×{magnification:g})", zorder=3)
    for (other_name, other), color in zip(others.items(), ("tab:orange", "tab:green", "tab:purple")):
        o = np.argsort(other.angle)
        ax.plot(np.append(other.angle[o], other.angle[o][0] + 2 * math.pi),
                1.0 + scale * np.append(other.radial_deviation[o], other.radial_deviation[o][0]),
                color=color, linewidth=0.8, alpha=0.8, linestyle="-.",
                label=f"{other_name}: G = {other.circular_deviation * 1e6:.3g} µm")
    span = max(peak, 1e-12)
    step = _nice_step(span)
    count = int(math.ceil(span / step))
    rings = [k * step for k in range(-count, count + 1)]
    ax.set_rticks([1.0 + scale * r for r in rings], [f"{r * 1e6:+.3g} µm" if r else "0" for r in rings])
    ax.set_rlim(1.0 + scale * (rings[0] - 0.5 * step), 1.0 + scale * (rings[-1] + 0.5 * step))
    ax.tick_params(axis="y", labelsize=7)
    for spike in result.reversal_spikes:
        if not math.isnan(spike.height) and abs(spike.height) >= 0.05 * span:
            at = math.radians(spike.angle_deg)
            ax.annotate(f"{spike.height * 1e6:+.2g} µm", (at, float(np.interp(at, theta, rho, period=2 * math.pi))),
                        fontsize=7, color="tab:red")
    direction = "CW" if result.clockwise else "CCW"
    feed = f", F = {result.feed * 60e3:.5g} mm/min" if result.feed else ""
    model = f" ({label} model)" if label else ""
    fig.suptitle(f"Circle test{model} R = {radius * 1e3:.4g} mm, {direction}{feed}, deviation drawn ×{magnification:g}\n"
                 f"circular deviation G = {result.circular_deviation * 1e6:.3g} µm, "
                 f"F min/max = {result.radial_deviation_min * 1e6:.3g} / {result.radial_deviation_max * 1e6:.3g} µm\n"
                 f"mean radial deviation {result.mean_radial_deviation * 1e6:.3g} µm, servo mismatch "
                 f"{result.servo_mismatch * 1e6:.3g} µm at {math.degrees(result.servo_mismatch_angle):.1f}°",
                 fontsize=9)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.12), fontsize=8)
    if others:
        # the differences are often far below the deviation itself: drawn on their own scale
        diff_ax = fig.add_axes((0.15, 0.05, 0.8, 0.14))
        at = np.mod(result.angle, 2 * math.pi)
        mine = np.argsort(at)
        for (other_name, other), color in zip(others.items(), ("tab:orange", "tab:green", "tab:purple")):
            o = np.argsort(other.angle)
            theirs = np.interp(at[mine], other.angle[o], other.radial_deviation[o], period=2 * math.pi)
            diff_ax.plot(np.degrees(at[mine]), (dev[mine] - theirs) * 1e6, color=color, linewidth=0.9,
                         label=f"{label or 'actual'} − {other_name}")
        diff_ax.set_xlim(0.0, 360.0)
        diff_ax.set_xticks(range(0, 361, 45))
        diff_ax.set_xlabel("angle (°)")
        diff_ax.set_ylabel("radial deviation\ndifference (µm)")
        diff_ax.grid(True, alpha=0.3)
        diff_ax.legend(fontsize=8, loc="upper right")
    return fig


def plot_path_samples(samples: "PathSamples") -> "Figure":
    """The path in the plane of its first two axes (mm) and the path velocity (mm/s) against time."""
    fig = new_figure(figsize=(10, 4.5))
    ax1, ax2 = fig.subplots(1, 2)
    names = samples.path.axis_names
    ax1.plot(samples.position[:, 0] * 1e3, samples.position[:, 1] * 1e3, linewidth=1.0)
    ax1.set_xlabel(f"{names[0]} (mm)")
    ax1.set_ylabel(f"{names[1]} (mm)")
    ax1.set_aspect("equal", adjustable="datalim")
    ax2.plot(samples.time, samples.path_velocity * 1e3, linewidth=1.0)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("path velocity (mm/s)")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    return fig


def plot_jerk_profile(profile: "JerkProfile", samples: int = 2000) -> "Figure":
    """Position, velocity, acceleration and jerk of a profile against time, four stacked panels."""
    start, end = profile.breaks[0], profile.end_time
    pad = 0.05 * max(end - start, 1e-3)
    t = np.union1d(np.linspace(start - pad, end + pad, samples), profile.breaks)
    pos, vel, acc = profile.evaluate(t)
    fig = new_figure(figsize=(8, 8))
    axes = fig.subplots(4, 1, sharex=True)
    for ax, values, label in zip(axes, (pos, vel, acc, profile.jerk(t)),
                                 ("position (m)", "velocity (m/s)", "acceleration (m/s²)", "jerk (m/s³)")):
        ax.plot(t, values, linewidth=1.0, drawstyle="steps-post" if label.startswith("jerk") else "default")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    return fig


def plot_path_run(run, magnification: float | None = None) -> "Figure":
    """The programmed and actual paths in the plane (the deviation magnified) and the contour error.

    The distance from the path (the contour error, not the lag along it) is drawn magnified
    (:func:`magnified_trace`); by default (``magnification=None``) so that the largest contour error is
    8–20 % of the path's size, half the diagonal of its bounding box (:func:`auto_magnification`). The
    factor is in the legend and the title.
    """
    import numpy as np

    fig = new_figure(figsize=(10, 4.5))
    ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.4]})
    sp, act = run.setpoint, run.actual
    if magnification is None:
        size = 0.5 * float(np.linalg.norm(np.ptp(sp[:, :2], axis=0))) if len(sp) else 0.0
        magnification = auto_magnification(run.max_contour_error, size)
    shown = magnified_trace(sp, act, magnification)
    ax1.plot(sp[:, 0] * 1e3, sp[:, 1] * 1e3, label="programmed", linewidth=1.0)
    ax1.plot(shown[:, 0] * 1e3, shown[:, 1] * 1e3, label=f"actual (contour error ×{magnification:g})", linewidth=0.9)
    names = run.path.axis_names
    ax1.set_xlabel(f"{names[0]} (mm)")
    ax1.set_ylabel(f"{names[1]} (mm)")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.legend(fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(run.time, np.asarray(run.contour_error) * 1e6, linewidth=1.0)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("contour error (µm)")
    ax2.grid(True, alpha=0.3)
    fig.suptitle(f"max contour error {run.max_contour_error * 1e6:.3g} µm; contour error drawn ×{magnification:g}",
                 fontsize=10)
    return fig


def auto_magnification(deviation: float, size: float, fraction: float = 0.2) -> float:
    """The magnification that draws a largest ``deviation`` at most ``fraction`` of the path's ``size``,
    rounded down to 1, 2 or 5 × 10^k (so the drawn deviation is 8–20 % of the size by default); 1 when
    there is no deviation, no size, or the deviation is already visible."""
    import math

    if not (deviation > 0 and size > 0 and math.isfinite(deviation) and math.isfinite(size)):
        return 1.0
    raw = fraction * size / deviation
    if raw <= 1.0:
        return 1.0
    exp = math.floor(math.log10(raw))
    return max(m * 10.0 ** exp for m in (1, 2, 5) if m * 10.0 ** exp <= raw)


def magnified_trace(setpoint, actual, magnification: float):
    """The actual trace with its distance to the programmed one magnified: each actual point is moved
    away from its foot on the setpoint polyline (the nearest point of the nearest segment) by
    ``magnification``; a lag along the path is not magnified. The setpoint samples are dense (one per
    position period), so the polyline is the path to within its chords' sagitta."""
    import numpy as np
    from scipy.spatial import cKDTree

    sp, act = np.asarray(setpoint, dtype=float), np.asarray(actual, dtype=float)
    if magnification == 1.0 or len(sp) < 2:
        return act
    nearest = cKDTree(sp).query(act)[1]
    best = np.full(len(act), np.inf)
    foot = act.copy()
    for lo in (nearest - 1, nearest):               # the segments before and after the nearest sample
        lo = np.clip(lo, 0, len(sp) - 2)
        a, b = sp[lo], sp[lo + 1]
        ab = b - a
        length2 = np.einsum("ij,ij->i", ab, ab)
        t = np.clip(np.einsum("ij,ij->i", act - a, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
        point = a + t[:, None] * ab
        dist = np.linalg.norm(act - point, axis=1)
        better = dist < best
        best[better], foot[better] = dist[better], point[better]
    return foot + magnification * (act - foot)
