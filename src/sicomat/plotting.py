"""Figures drawn from result objects (matplotlib, headless). Computing never happens here."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .modal import ModalResult

__all__ = ["plot_modes", "plot_timeseries", "plot_path_run", "plot_step", "save_figure"]


def _figure(**kwargs) -> "Figure":
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def plot_modes(result: "ModalResult", max_modes: int = 8) -> "Figure":
    """Mode shapes as bars per dof, one panel per mode, with frequency and damping in the title."""
    import numpy as np

    modes = result.modes[:max_modes]
    count = max(len(modes), 1)
    cols = min(count, 4)
    rows = (count + cols - 1) // cols
    fig = _figure(figsize=(3.2 * cols, 2.6 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, sharey=True)).ravel()
    positions = np.arange(len(result.dofs))
    for k, (ax, mode) in enumerate(zip(axes, modes)):
        values = [mode.shape[d] for d in result.dofs]
        colors = ["tab:blue" if v >= 0 else "tab:orange" for v in values]
        ax.bar(positions, values, color=colors)
        ax.axhline(0.0, color="black", linewidth=0.6)
        title = "rigid body" if mode.rigid else f"{mode.frequency_hz:.4g} Hz, ζ={mode.damping_ratio:.3g}"
        ax.set_title(f"mode {k + 1}: {title}", fontsize=9)
        ax.set_xticks(positions, result.dofs, rotation=45, ha="right", fontsize=8)
        ax.set_ylim(-1.1, 1.1)
    for ax in axes[len(modes):]:
        ax.set_visible(False)
    f_meca = result.f_meca_hz
    suffix = f" — suggested f_meca = {f_meca:.4g} Hz" if f_meca else ""
    fig.suptitle(f"Mode shapes{suffix}", fontsize=10)
    return fig


def plot_timeseries(series, signals=None) -> "Figure":
    """Three stacked panels: positions, following error (µm), effort command; or chosen signals."""
    t = series.time
    if signals:
        fig = _figure(figsize=(8, 2.2 * len(signals) + 0.5), layout="constrained")
        axes = fig.subplots(len(signals), 1, sharex=True, squeeze=False)[:, 0]
        for ax, name in zip(axes, signals):
            ax.plot(t, series[name], linewidth=1.0)
            ax.set_ylabel(name, fontsize=8)
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("time (s)")
        return fig
    fig = _figure(figsize=(8, 7), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    ax1.plot(t, series["setpoint.fine"] * 1e3, label="setpoint", linewidth=1.0)
    ax1.plot(t, (series["setpoint.fine"] - series["following_error"]) * 1e3, label="position (feedback)",
             linewidth=1.0)
    ax1.plot(t, series["tool.position"] * 1e3, label="tool", linewidth=0.8, linestyle="--")
    ax1.set_ylabel("position (mm)")
    ax1.legend(fontsize=8)
    ax2.plot(t, series["following_error"] * 1e6, linewidth=1.0)
    ax2.set_ylabel("following error (µm)")
    ax3.plot(t, series["effort.command"], linewidth=1.0, label="command")
    ax3.plot(t, series["drive.effort"], linewidth=0.8, label="drive")
    ax3.set_ylabel("force / torque")
    ax3.legend(fontsize=8)
    ax3.set_xlabel("time (s)")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
    return fig


def plot_path_run(run, magnification: float = 1.0) -> "Figure":
    """The programmed and actual paths in the plane (the deviation magnified) and the contour error."""
    import numpy as np

    fig = _figure(figsize=(10, 4.5), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.4]})
    sp, act = run.setpoint, run.actual
    shown = sp + magnification * (act - sp)
    ax1.plot(sp[:, 0] * 1e3, sp[:, 1] * 1e3, label="programmed", linewidth=1.0)
    ax1.plot(shown[:, 0] * 1e3, shown[:, 1] * 1e3, label=f"actual (deviation ×{magnification:g})", linewidth=0.9)
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
    fig.suptitle(f"max contour error {run.max_contour_error * 1e6:.3g} µm", fontsize=10)
    return fig


def plot_step(response, title: str = "step response") -> "Figure":
    """A step response with its overshoot and rise time in the title."""
    fig = _figure(figsize=(7, 3.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(response.time * 1e3, response.response, linewidth=1.0)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("response to a unit step")
    ax.grid(True, alpha=0.3)
    rise = "-" if response.rise_time is None else f"{response.rise_time * 1e3:.3g} ms"
    ax.set_title(f"{title}: overshoot {response.overshoot_percent:.3g} %, rise time {rise}", fontsize=10)
    return fig


def save_figure(fig: "Figure", path: str | os.PathLike) -> Path:
    """Save ``fig`` to ``path`` atomically, under the output policy (``docs/outputs.md``); the
    format is the name's extension: .png, .svg or .pdf."""
    from .atomic import atomic_write, check_output

    target = check_output(path, "figure")
    suffix = target.suffix.lower()
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format=suffix[1:], dpi=120), suffix=suffix,
                        kind="figure")
