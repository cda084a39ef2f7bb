"""Figures of mode maps: over the stroke (:class:`sicomat.tasks.modemap.ModeMap`), f1…fn against the
table's position, the worst position (lowest first mode) marked; over a robot's workspace
(:class:`sicomat.tasks.workspace_map.WorkspaceModeMap`), the same lines against one joint, or heat maps of
the first modes over two."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    from matplotlib.figure import Figure

__all__ = ["plot_mode_map", "plot_workspace_map"]


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
    fig = new_figure(figsize=(7.0, 4.2))
    ax = fig.subplots()
    worst = None if result.worst_position is None else 1e3 * result.worst_position
    _mode_lines(ax, 1e3 * result.position, result.frequencies_hz, worst, result.lowest_first_mode_hz, "mm")
    ax.set_xlabel("table position from the motor-side end (mm)")
    ax.set_title(f"axis {result.axis}: flexible modes over the stroke ({1e3 * result.stroke:.4g} mm)", fontsize=10)
    return fig


def _mode_lines(ax, x: "np.ndarray", f: "np.ndarray", worst: float | None, lowest: float | None, unit: str) -> None:
    """One line per column of ``f`` against ``x`` (display units), the worst point ringed."""
    import numpy as np

    for k in range(f.shape[1]):
        ax.plot(x, f[:, k], marker="o", markersize=3, linewidth=1.4, label=f"f{k + 1}")
    if worst is not None and lowest is not None:
        ax.plot([worst], [lowest], marker="o", markersize=11, markerfacecolor="none",
                markeredgecolor="tab:red", markeredgewidth=2, linestyle="none", clip_on=False, zorder=5,
                label=f"worst: f1 = {lowest:.4g} Hz at {worst:.4g} {unit}")
        ax.axvline(worst, color="tab:red", linewidth=0.8, linestyle=":")
    finite = f[np.isfinite(f)]
    if finite.size and finite.max() > 10.0 * finite.min():
        ax.set_yscale("log")
    ax.set_xlim(x[0], x[-1])
    ax.set_ylabel("undamped natural frequency (Hz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")


# --------------------------------------------------------------------------- over a robot's workspace
class WorkspaceMapLike(Protocol):
    """What the figure reads of a workspace mode map (``sicomat.tasks.workspace_map.WorkspaceModeMap``)."""

    @property
    def machine(self) -> str: ...  # pragma: no cover

    @property
    def axis(self) -> str | None: ...  # pragma: no cover

    @property
    def joints(self) -> tuple[str, ...]: ...  # pragma: no cover

    @property
    def kinds(self) -> tuple[str, ...]: ...  # pragma: no cover

    @property
    def grid(self) -> "tuple[np.ndarray, ...]": ...  # pragma: no cover

    @property
    def undamped_hz(self) -> "np.ndarray": ...  # pragma: no cover

    @property
    def modes(self) -> int: ...  # pragma: no cover

    @property
    def locked(self) -> tuple[str, ...]: ...  # pragma: no cover

    @property
    def failed(self) -> "tuple[Any, ...]": ...  # pragma: no cover

    @property
    def worst_position(self) -> tuple[float, ...] | None: ...  # pragma: no cover

    @property
    def lowest_first_mode_hz(self) -> float | None: ...  # pragma: no cover


def _display(kind: str) -> tuple[float, str]:
    """Scale from SI and unit of a joint's values on a figure: mm for a prismatic joint, deg for a revolute one."""
    import math

    return (1e3, "mm") if kind == "translational" else (180.0 / math.pi, "deg")


def _title(result: WorkspaceMapLike) -> str:
    locked = ", ".join(result.locked) or "none"
    who = result.machine or "robot"
    if result.axis is None:
        return f"{who}: modes over {' and '.join(result.joints)}, motors locked ({locked}), gravity stiffness kept"
    return (f"{who}: axis {result.axis}'s model over {' and '.join(result.joints)}\n(motor {result.axis} free, "
            f"locked: {locked}; gravity compensated)")


def plot_workspace_map(result: WorkspaceMapLike) -> "Figure":
    """One joint: one line per mode against the joint (mm or deg), the worst point ringed and failed points
    crossed on the axis. Two joints: a filled contour of the first mode over the grid (the first joint
    along x), and of the second beside it when there is one; failed points crossed, the worst ringed."""
    import numpy as np
    from matplotlib.ticker import ScalarFormatter

    scales = [_display(kind) for kind in result.kinds]
    labels = [f"{name} ({unit})" for name, (_, unit) in zip(result.joints, scales)]
    failed = [tuple(f.values) for f in result.failed]
    worst = result.worst_position
    if len(result.joints) == 1:
        (scale, unit), = scales
        fig = new_figure(figsize=(7.0, 4.2))
        ax = fig.subplots()
        _mode_lines(ax, scale * result.grid[0], result.undamped_hz, None if worst is None else scale * worst[0],
                    result.lowest_first_mode_hz, unit)
        if failed:
            ax.plot([scale * v[0] for v in failed], np.zeros(len(failed)), marker="x", color="tab:gray",
                    linestyle="none", transform=ax.get_xaxis_transform(), clip_on=False, zorder=6,
                    label=f"failed ({len(failed)}: see the table or JSON)")
            ax.legend(fontsize=8, loc="best")
        ax.set_xlabel(labels[0])
        ax.set_title(_title(result), fontsize=10)
        return fig
    panels = min(result.modes, 2)
    fig = new_figure(figsize=(6.0 * panels + 0.6, 5.0))
    axes = np.atleast_1d(fig.subplots(1, panels))
    x, y = scales[0][0] * result.grid[0], scales[1][0] * result.grid[1]
    for k, ax in enumerate(axes):
        z = np.ma.masked_invalid(result.undamped_hz[:, :, k].T)      # rows: the second joint (y)
        values = z.compressed()
        # contours of a map flat to rounding (1e-9 relative: far above the ~1e-13 of a modal analysis, far below
        # any physical change) would draw noise: one colour instead
        if values.size and np.ptp(values) > 1e-9 * np.max(np.abs(values)):
            filled = ax.contourf(x, y, z, levels=16, cmap="viridis")
        else:
            filled = ax.pcolormesh(x, y, z, cmap="viridis", shading="nearest")
        bar = fig.colorbar(filled, ax=ax, label=f"f{k + 1} (Hz)")
        bar.formatter = ScalarFormatter(useOffset=False)            # absolute Hz, never "1e-5 + 92.75"
        bar.update_ticks()
        if failed:
            ax.plot([scales[0][0] * v[0] for v in failed], [scales[1][0] * v[1] for v in failed], marker="x",
                    color="tab:red", markersize=4, linestyle="none", label=f"failed ({len(failed)})")
        if k == 0 and worst is not None and result.lowest_first_mode_hz is not None:
            ax.plot([scales[0][0] * worst[0]], [scales[1][0] * worst[1]], marker="o", markersize=11,
                    markerfacecolor="none", markeredgecolor="tab:red", markeredgewidth=2, linestyle="none",
                    clip_on=False, zorder=5, label=f"lowest f1 = {result.lowest_first_mode_hz:.4g} Hz")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        ax.set_title(f"mode {k + 1}", fontsize=10)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="upper right", framealpha=0.8)
    fig.suptitle(_title(result), fontsize=10)
    return fig
