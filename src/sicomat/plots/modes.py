"""Figures of modal analyses: mode shapes (matplotlib Figure, no pyplot)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..mechanics.modal import ModalResult

__all__ = ["plot_modes"]


def plot_modes(result: "ModalResult", max_modes: int = 8) -> "Figure":
    """Mode shapes as bars per dof, one panel per mode, with frequency and damping in the title."""
    import numpy as np

    modes = result.modes[:max_modes]
    count = max(len(modes), 1)
    cols = min(count, 4)
    rows = (count + cols - 1) // cols
    fig = new_figure(figsize=(3.2 * cols, 2.6 * rows + 0.6))
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
        if k % cols == 0:
            ax.set_ylabel("amplitude (largest = 1)", fontsize=8)
    for ax in axes[len(modes):]:
        ax.set_visible(False)
    from matplotlib.patches import Patch

    fig.legend(handles=[Patch(color="tab:blue", label="moves with the largest component (+)"),
                        Patch(color="tab:orange", label="moves against it (−)")],
               loc="outside lower center", ncols=2, fontsize=8, frameon=False)
    f_meca = result.f_meca_hz
    suffix = f" — suggested f_meca = {f_meca:.4g} Hz" if f_meca else ""
    fig.suptitle(f"Mode shapes{suffix}", fontsize=10)
    return fig
