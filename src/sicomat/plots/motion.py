"""Figures of setpoints, paths and circle tests (matplotlib Figure, no pyplot). Computing never happens here."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, cast

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure
    from matplotlib.projections.polar import PolarAxes

    from ..motion.circle import CircleResult
    from ..motion import PathSamples
    from ..motion.trajectory import JerkProfile

__all__ = ["plot_circle", "plot_path_samples", "plot_jerk_profile"]


def _figure(**kwargs) -> "Figure":
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _nice_step(span: float) -> float:
    """A 1-2-5 step giving about three rings over ``span``."""
    raw = max(span, 1e-15) / 3
    exp = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10 ** exp >= raw:
            return m * 10 ** exp
    return 10 ** (exp + 1)  # pragma: no cover


def plot_circle(result: "CircleResult", magnification: float | None = None) -> "Figure":
    """Ballbar-style polar plot: nominal circle, radial deviation magnified, figures in the title.

    The nominal circle is drawn at unit radius and a deviation ``F`` at ``1 + magnification·F/R``;
    the rings are labelled in µm of deviation. By default the magnification is the 1-2-5 value that draws
    the largest deviation at 8–20 % of the radius (:func:`sicomat.plots.base.auto_magnification`); the
    factor is in the title and the legend.
    """
    from .base import auto_magnification

    dev, radius = result.radial_deviation, result.radius
    peak = float(np.max(np.abs(dev))) if dev.size else 0.0
    if magnification is None:
        magnification = auto_magnification(peak, radius)
    scale = magnification / radius                         # plot units per metre of deviation
    order = np.argsort(result.angle)
    theta = np.append(result.angle[order], result.angle[order][0] + 2 * math.pi)
    rho = 1.0 + scale * np.append(dev[order], dev[order][0])
    fig = _figure(figsize=(6.4, 6.8), layout="constrained")
    ax = cast("PolarAxes", fig.add_subplot(projection="polar"))
    circle = np.linspace(0, 2 * math.pi, 361)
    ax.plot(circle, np.ones_like(circle), color="gray", linestyle="--", linewidth=0.8, label="nominal")
    ax.plot(theta, rho, color="tab:blue", linewidth=1.0, label=f"actual (deviation ×{magnification:g})")
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
    feed = f", F = {result.feed * 60e3:.4g} mm/min" if result.feed else ""
    fig.suptitle(f"Circle test R = {radius * 1e3:.4g} mm, {direction}{feed}, deviation drawn ×{magnification:g}\n"
                 f"circular deviation G = {result.circular_deviation * 1e6:.3g} µm, "
                 f"F min/max = {result.radial_deviation_min * 1e6:.3g} / {result.radial_deviation_max * 1e6:.3g} µm\n"
                 f"mean radial deviation {result.mean_radial_deviation * 1e6:.3g} µm, servo mismatch "
                 f"{result.servo_mismatch * 1e6:.3g} µm at {math.degrees(result.servo_mismatch_angle):.1f}°",
                 fontsize=9)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.12), fontsize=8)
    return fig


def plot_path_samples(samples: "PathSamples") -> "Figure":
    """The path in the plane of its first two axes (mm) and the path velocity (mm/s) against time."""
    fig = _figure(figsize=(10, 4.5), layout="constrained")
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
    fig = _figure(figsize=(8, 8), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    for ax, values, label in zip(axes, (pos, vel, acc, profile.jerk(t)),
                                 ("position (m)", "velocity (m/s)", "acceleration (m/s²)", "jerk (m/s³)")):
        ax.plot(t, values, linewidth=1.0, drawstyle="steps-post" if label.startswith("jerk") else "default")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    return fig
