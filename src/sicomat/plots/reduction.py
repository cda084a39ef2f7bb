"""Figures of model reductions: the full and reduced responses (matplotlib Figure, no pyplot)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..reduction.error import ReductionResult

__all__ = ["plot_reduction"]


def plot_reduction(result: "ReductionResult", max_channels: int = 4) -> "Figure":
    """Bode magnitude and phase of the full (solid) and reduced (dashed) models, one line pair per
    input/output channel (at most ``max_channels``), the band of interest shaded."""
    m = result.metrics
    order = np.argsort(m.omega)
    f = m.omega[order] / (2 * np.pi)
    fig = new_figure(figsize=(8, 6))
    ax_mag, ax_ph = fig.subplots(2, 1, sharex=True)
    channels = [(i, j) for i in range(len(result.full.outputs)) for j in range(len(result.full.inputs))]
    colors = [f"C{k}" for k in range(10)]
    for k, (i, j) in enumerate(channels[:max_channels]):
        label = f"{result.full.inputs[j]} → {result.full.outputs[i]}"
        for G, style, tag in ((m.full_response, "-", "full"), (m.reduced_response, "--", "reduced")):
            g = G[order, i, j]
            mag = 20 * np.log10(np.maximum(np.abs(g), 1e-300))
            ax_mag.semilogx(f, mag, style, color=colors[k % 10], linewidth=1.0,
                            label=f"{label} ({tag}, {result.order_before if tag == 'full' else result.order_after} states)")
            ax_ph.semilogx(f, np.degrees(np.unwrap(np.angle(g))), style, color=colors[k % 10], linewidth=1.0)
    if result.band_hz is not None:
        for ax in (ax_mag, ax_ph):
            ax.axvspan(max(result.band_hz[0], f[0]), result.band_hz[1], color="0.9", zorder=0)
    ax_mag.set_ylabel("magnitude (dB)")
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel("frequency (Hz)")
    for ax in (ax_mag, ax_ph):
        ax.grid(True, which="both", alpha=0.3)
    ax_mag.legend(fontsize=7)
    rel = m.hinf_relative_error
    fig.suptitle(f"{result.method} reduction ({result.variant}): {result.order_before} → "
                 f"{result.order_after} states, H∞ error {m.hinf_error:.3g}"
                 + (f" ({100 * rel:.3g} % of the flexible part)" if rel is not None else ""), fontsize=10)
    return fig
