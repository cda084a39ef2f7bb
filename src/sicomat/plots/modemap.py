"""Figure of a mode map over the stroke (:class:`sicomat.tasks.modemap.ModeMap`): f1…fn against the
table's position, the worst position (lowest first mode) marked."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    from matplotlib.figure import Figure

__all__ = ["plot_mode_map"]


class MapLike(Protocol):
    """What the figure reads of a mode map (``sicomat.tasks.modemap.ModeMap``, a layer above plots)."""

    @property
    def axis(self) -> str: ...  # pragma: no cover

    @property
    def stroke(self) -> float: ...  # pragma: no cover

    @property
    def position(self) -> "np.ndarray": ...  # pragma: no cover

    @property
    def frequencies_hz(self) -> "np.ndarray": ...  # pragma: no cover

    @property
    def modes(self) -> int: ...  # pragma: no cover

    @property
    def worst_position(self) -> float | None: ...  # pragma: no cover

    @property
    def lowest_first_mode_hz(self) -> float | None: ...  # pragma: no cover


def plot_mode_map(result: MapLike) -> "Figure":
    """One line per flexible mode against the position in mm; a logarithmic frequency axis when the
    mapped frequencies span more than a decade (a mode that stiffens without bound near an end)."""
    import numpy as np

    fig = new_figure(figsize=(7.0, 4.2))
    ax = fig.subplots()
    x_mm = 1e3 * result.position
    f = result.frequencies_hz
    for k in range(result.modes):
        ax.plot(x_mm, f[:, k], marker="o", markersize=3, linewidth=1.4, label=f"f{k + 1}")
    worst, lowest = result.worst_position, result.lowest_first_mode_hz
    if worst is not None and lowest is not None:
        ax.plot([1e3 * worst], [lowest], marker="o", markersize=11, markerfacecolor="none",
                markeredgecolor="tab:red", markeredgewidth=2, linestyle="none", clip_on=False, zorder=5,
                label=f"worst: f1 = {lowest:.4g} Hz at {1e3 * worst:.4g} mm")
        ax.axvline(1e3 * worst, color="tab:red", linewidth=0.8, linestyle=":")
    finite = f[np.isfinite(f)]
    if finite.size and finite.max() > 10.0 * finite.min():
        ax.set_yscale("log")
    ax.set_xlim(x_mm[0], x_mm[-1])
    ax.set_xlabel("table position from the motor-side end (mm)")
    ax.set_ylabel("undamped natural frequency (Hz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"axis {result.axis}: flexible modes over the stroke ({1e3 * result.stroke:.4g} mm)", fontsize=10)
    return fig
