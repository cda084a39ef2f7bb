"""Figures against time: simulated signals and step responses (matplotlib Figure, no pyplot)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_timeseries", "plot_step", "signal_unit", "plot_following_errors"]


def plot_timeseries(series, signals=None) -> "Figure":
    """Three stacked panels: positions, following error (µm), effort command; or chosen signals."""
    t = series.time
    if signals:
        fig = new_figure(figsize=(8, 2.2 * len(signals) + 0.5))
        axes = fig.subplots(len(signals), 1, sharex=True, squeeze=False)[:, 0]
        for ax, name in zip(axes, signals):
            ax.plot(t, series[name], linewidth=1.0)
            unit = signal_unit(name, series.info.get("effort_unit"))
            ax.set_ylabel(f"{name} ({unit})" if unit else name, fontsize=8)
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("time (s)")
        return fig
    fig = new_figure(figsize=(8, 7))
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
    effort = series.info.get("effort_unit")
    ax3.set_ylabel({"N": "force (N)", "N·m": "torque (N·m)"}.get(effort, "force (N) / torque (N·m)"))
    ax3.legend(fontsize=8)
    ax3.set_xlabel("time (s)")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
    return fig


def _signal_units() -> dict[str, str]:
    return {".x": "m", ".v": "m/s", ".theta": "rad", ".omega": "rad/s", ".force": "N", ".torque": "N·m",
            ".current": "A", ".position": "m", ".velocity": "m/s", "_error": "m"}


def signal_unit(name: str, effort_unit: str | None = None) -> str | None:
    """The SI unit of a named signal (``load.x``: m, ``drive.current``: A, ``drive.effort``: N or N·m),
    ``None`` when the name does not tell (a raw sensor output is in its sensor's units)."""
    if name.startswith("sensor."):
        return None
    if name.endswith(".effort") or name.endswith(".command") and name.startswith("effort"):
        return effort_unit
    return next((unit for end, unit in _signal_units().items() if name.endswith(end)), None)


def plot_step(response, title: str = "step response") -> "Figure":
    """A step response with its overshoot and rise time in the title."""
    fig = new_figure(figsize=(7, 3.5))
    ax = fig.subplots()
    ax.plot(response.time * 1e3, response.response, linewidth=1.0)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("response to a unit step")
    ax.grid(True, alpha=0.3)
    rise = "-" if response.rise_time is None else f"{response.rise_time * 1e3:.3g} ms"
    ax.set_title(f"{title}: overshoot {response.overshoot_percent:.3g} %, rise time {rise}", fontsize=10)
    return fig


def plot_following_errors(errors) -> "Figure":
    """The following error (µm) of several axes against time, one panel per axis (a coupled run:
    ``{axis: (time, following_error)}``)."""
    fig = new_figure(figsize=(8, 1.9 * len(errors) + 0.8))
    axes = fig.subplots(len(errors), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, (time, error)) in zip(axes, errors.items()):
        ax.plot(time, error * 1e6, linewidth=1.0)
        ax.set_ylabel(f"{name} following\nerror (µm)", fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    return fig
