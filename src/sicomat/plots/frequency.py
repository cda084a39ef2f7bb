"""Bode and Nichols figures of frequency responses, with their stability margins (paper Figs. 6, 9, 10).

Figures are matplotlib ``Figure`` objects built without pyplot (nothing global, nothing shown); save
them with :func:`sicomat.plots.base.save_figure`. Nothing is computed here beyond what drawing needs:
the margins come from :func:`sicomat.frequency.margins.stability_margins`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError
from ..lti.response import FrequencyResponse
from .base import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..frequency.margins import Margins

__all__ = ["bode_figure", "nichols_figure", "M_CIRCLES_DB", "PHASE_MARGIN_GRID_DEG"]

#: Closed-loop magnitudes |T| (dB) drawn as contours on Nichols charts.
M_CIRCLES_DB = (-6.0, -3.0, 0.0, 1.0, 2.0, 3.0, 6.0)
#: Phase-margin targets (deg) drawn as dashed lines right of each critical point of a Nichols chart.
PHASE_MARGIN_GRID_DEG = (30.0, 45.0, 60.0)

_GRID_STYLE: dict[str, Any] = {"color": "0.6", "linewidth": 0.6}


def bode_figure(frfs: FrequencyResponse | Sequence[FrequencyResponse],
                margins: "Margins | Sequence[Margins | None] | None" = None,
                title: str | None = None) -> "Figure":
    """Bode diagram: magnitude (dB) and unwrapped phase (deg) against frequency (Hz, log scale).

    Parameters
    ----------
    frfs : FrequencyResponse or sequence of them
        The responses, one curve each (legend: their names).
    margins : Margins or sequence of (Margins or None), optional
        Margins to mark: one per response (``None`` for none), or a single one for the response it
        was computed from. Marked: every gain crossover (circles on 0 dB), every phase crossover
        (squares at ``−GM``), the reported phase margin (bar from −180° to the phase) and gain margin
        (bar from ``−GM`` to 0 dB), and a summary box.
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the frequency axis: magnitude on top, phase below. A sampled response
        (``sample_period`` set) gets a dashed vertical line at its Nyquist frequency ``1/(2T)``.

    Examples
    --------
    >>> import numpy as np
    >>> w = np.logspace(-1, 2, 200)
    >>> fig = bode_figure(FrequencyResponse(w, 10 / (1j * w * (1j * w + 1)), "L", open_loop=True))
    >>> len(fig.axes)
    2
    """
    frfs = _as_list(frfs)
    paired = _paired(frfs, margins)
    fig = new_figure(figsize=(8.0, 6.5))
    ax_mag, ax_ph = fig.subplots(2, 1, sharex=True)
    phase_lo, phase_hi = np.inf, -np.inf
    for frf, m in zip(frfs, paired):
        f = np.asarray(frf.frequency_hz, dtype=float)
        phase = np.asarray(frf.phase_deg, dtype=float)
        (line,) = ax_mag.semilogx(f, frf.magnitude_db, linewidth=1.2, label=frf.name or None)
        ax_ph.semilogx(f, phase, linewidth=1.2, color=line.get_color())
        if phase.size:
            phase_lo, phase_hi = min(phase_lo, float(phase.min())), max(phase_hi, float(phase.max()))
        if m is not None:
            _mark_bode(ax_mag, ax_ph, frf, m, line.get_color())
    for period in sorted({frf.sample_period for frf in frfs if frf.sample_period}):
        f_n = 0.5 / period
        for ax in (ax_mag, ax_ph):
            ax.axvline(f_n, color="0.35", linestyle="--", linewidth=0.8)
        ax_mag.annotate(f"Nyquist {f_n:.4g} Hz", (f_n, 0.0), xycoords=("data", "axes fraction"),
                        xytext=(-3, 3), textcoords="offset points", ha="right", va="bottom",
                        fontsize=7, color="0.35", rotation=90)
    if any(m is not None for m in paired):
        ax_mag.axhline(0.0, color="black", linewidth=0.6, linestyle=":")
        for level in _levels_between(phase_lo, phase_hi):
            ax_ph.axhline(level, color="black", linewidth=0.6, linestyle=":")
    ax_mag.set_ylabel("magnitude (dB)")
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel("frequency (Hz)")
    if np.isfinite(phase_lo):
        ax_ph.yaxis.set_major_locator(_phase_locator(phase_hi - phase_lo))
    for ax in (ax_mag, ax_ph):
        ax.grid(True, which="major", alpha=0.35)
        ax.grid(True, which="minor", alpha=0.12)
    if any(frf.name for frf in frfs):
        ax_mag.legend(fontsize=8, loc="upper right")
    fig.suptitle(title or "Bode diagram", fontsize=10)
    return fig


def nichols_figure(frfs: FrequencyResponse | Sequence[FrequencyResponse],
                   margins: "Margins | Sequence[Margins | None] | None" = None,
                   title: str | None = None) -> "Figure":
    """Nichols chart: open-loop gain (dB) against open-loop phase (deg), with the M-circles.

    The phase is the unwrapped one, shifted by a multiple of 360° (per response) so that its first
    gain crossover lies within 180° of −180°: the part near crossover sits around the critical point
    and the rest follows continuously, so the loops that lightly damped modes draw (paper Fig. 9)
    stay whole, each next to the critical point ``−180° + k·360°`` it actually approaches. Every
    critical point in view is marked, with the M-circles (contours of the closed-loop magnitude
    ``|L/(1+L)|``, :data:`M_CIRCLES_DB`) and dashed phase-margin targets (:data:`PHASE_MARGIN_GRID_DEG`)
    repeated around it. The view keeps gains between −40 dB and +50 dB.

    Parameters
    ----------
    frfs : FrequencyResponse or sequence of them
        Loop gains, one curve each.
    margins : Margins or sequence of (Margins or None), optional
        Margins to mark (as in :func:`bode_figure`): gain crossovers (circles), phase crossovers
        (squares), the reported phase margin (bar along 0 dB) and gain margin (bar along the phase
        level).
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        One axes.

    Examples
    --------
    >>> import numpy as np
    >>> w = np.logspace(-1, 2, 200)
    >>> fig = nichols_figure(FrequencyResponse(w, 10 / (1j * w * (1j * w + 1)), "L", open_loop=True))
    >>> len(fig.axes)
    1
    """
    frfs = _as_list(frfs)
    paired = _paired(frfs, margins)
    fig = new_figure(figsize=(7.5, 6.5))
    ax = fig.subplots()
    curves = []
    for frf, m in zip(frfs, paired):
        phase = np.asarray(frf.phase_deg, dtype=float)
        gain = np.asarray(frf.magnitude_db, dtype=float)
        shift = _nichols_shift(frf, phase, gain, m)
        (line,) = ax.plot(phase + shift, gain, linewidth=1.2, label=frf.name or None, zorder=3)
        curves.append((phase + shift, gain))
        if m is not None:
            _mark_nichols(ax, frf, m, shift, line.get_color())
    (x_lo, x_hi), (y_lo, y_hi) = _nichols_view(curves)
    _m_circles(ax, x_lo, x_hi, y_lo, y_hi)
    main = -180.0 + 360.0 * np.round((_first_shifted_crossover_phase(curves) + 180.0) / 360.0)
    for level in _levels_between(x_lo, x_hi):
        ax.plot(level, 0.0, marker="+", color="red", markersize=11, markeredgewidth=2, zorder=4)
        for pm in PHASE_MARGIN_GRID_DEG:
            if x_lo <= level + pm <= x_hi:
                ax.axvline(level + pm, linestyle="--", **_GRID_STYLE)
                if level == main:
                    ax.annotate(f"PM {pm:g}°", (level + pm, 1.0), xycoords=("data", "axes fraction"),
                                xytext=(2, -3), textcoords="offset points", ha="left", va="top",
                                fontsize=7, color="0.4", rotation=90, gid="pm-grid-label")
    ax.axhline(0.0, color="black", linewidth=0.6, linestyle=":")
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.xaxis.set_major_locator(_phase_locator(x_hi - x_lo))
    ax.set_xlabel("open-loop phase (deg)")
    ax.set_ylabel("open-loop gain (dB)")
    ax.grid(True, alpha=0.25)
    if any(frf.name for frf in frfs):
        ax.legend(fontsize=8, loc="upper left")
    fig.suptitle(title or "Nichols chart", fontsize=10)
    _declutter(fig, ax)
    return fig


# ---------------------------------------------------------------------------------------- helpers
_LABEL_BOX = {"boxstyle": "square,pad=0.1", "facecolor": "white", "edgecolor": "none", "alpha": 0.8}
_LABEL_PRIORITY = ("margin-label", "pm-grid-label", "m-circle-label")


def _declutter(fig: "Figure", ax: "Axes") -> None:
    """Hide every label that would overlap a more important one (margins first, then the phase-margin
    grid, then the M-circles' levels), measured once the layout is done; the curves stay whole."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    fig.draw_without_rendering()
    renderer = canvas.get_renderer()
    texts = [t for t in ax.texts if t.get_gid() in _LABEL_PRIORITY and t.get_visible()]
    texts.sort(key=lambda t: _LABEL_PRIORITY.index(t.get_gid()))
    kept: list[Any] = []     # the window extents (Bbox) of the labels kept
    for text in texts:
        box = text.get_window_extent(renderer)
        if any(box.overlaps(other) for other in kept):
            text.set_visible(False)
        else:
            kept.append(box)


def _as_list(frfs) -> list[FrequencyResponse]:
    items = [frfs] if isinstance(frfs, FrequencyResponse) else list(frfs)
    if not items:
        raise ModelError("expected at least one frequency response to plot, got none")
    for k, item in enumerate(items):
        if not isinstance(item, FrequencyResponse):
            raise ModelError(f"item {k}: expected a FrequencyResponse, got {type(item).__name__}")
    return items


def _paired(frfs: list[FrequencyResponse], margins) -> list:
    """One Margins (or None) per response."""
    if margins is None:
        return [None] * len(frfs)
    if not isinstance(margins, Sequence):   # a single Margins: to the response it belongs to
        owner = next((k for k, frf in enumerate(frfs) if frf is margins.frf), 0)
        return [margins if k == owner else None for k in range(len(frfs))]
    margins = list(margins)
    if len(margins) != len(frfs):
        raise ModelError(f"expected one margins entry per response ({len(frfs)}), got {len(margins)}")
    return margins


def _levels_between(lo: float, hi: float) -> list[float]:
    """The critical phases −180° + k·360° within [lo, hi]."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return []
    k0, k1 = int(np.ceil((lo + 180.0) / 360.0)), int(np.floor((hi + 180.0) / 360.0))
    return [-180.0 + 360.0 * k for k in range(k0, k1 + 1)]


def _phase_locator(span: float):
    from matplotlib.ticker import MultipleLocator

    step = next((s for s, limit in ((45.0, 450.0), (90.0, 900.0), (180.0, 1800.0)) if span <= limit), 360.0)
    return MultipleLocator(step)


def _interp_log(frf: FrequencyResponse, values: np.ndarray, omega) -> np.ndarray:
    """``values`` (on the grid of ``frf``) at ``omega``, linear in ln ω, clamped to the grid."""
    return np.interp(np.log(np.asarray(omega, dtype=float)), np.log(np.asarray(frf.omega, dtype=float)),
                     values)


def _nearest_level(phase):
    return -180.0 + 360.0 * np.round((np.asarray(phase) + 180.0) / 360.0)


def _summary(m: "Margins") -> str:
    def num(value, fmt, unit):
        return f"{value:{fmt}}{unit}" if np.isfinite(value) else "—"

    def at(omega):
        return f" @ {omega / (2 * np.pi):.4g} Hz" if np.isfinite(omega) else ""

    lines = [m.name] if m.name else []
    lines += [f"GM {num(m.gain_margin_db, '.3g', ' dB')}{at(m.phase_crossover_rad_s)}",
              f"PM {num(m.phase_margin_deg, '.3g', '°')}{at(m.gain_crossover_rad_s)}",
              f"delay margin {num(m.delay_margin_s * 1e3, '.3g', ' ms')}",
              f"modulus margin {m.modulus_margin:.3g}{at(m.modulus_margin_rad_s)}"]
    if len(m.gain_crossovers) > 1:
        lines.append(f"{len(m.gain_crossovers)} gain crossovers")
    return "\n".join(lines)


def _mark_bode(ax_mag: "Axes", ax_ph: "Axes", frf: FrequencyResponse, m: "Margins", color) -> None:
    phase = np.asarray(frf.phase_deg, dtype=float)
    if m.gain_crossovers.size:
        ax_mag.plot(m.gain_crossovers / (2 * np.pi), np.zeros(m.gain_crossovers.size), "o",
                    markerfacecolor="none", color=color, markersize=6)
    if m.phase_crossovers.size:
        finite = np.isfinite(m.gain_margins_db)
        levels = _nearest_level(_interp_log(frf, phase, m.phase_crossovers))
        ax_mag.plot(m.phase_crossovers[finite] / (2 * np.pi), -m.gain_margins_db[finite], "s",
                    markerfacecolor="none", color=color, markersize=5)
        ax_ph.plot(m.phase_crossovers / (2 * np.pi), levels, "s", markerfacecolor="none", color=color,
                   markersize=5)
    if np.isfinite(m.gain_crossover_rad_s):
        f_c = m.gain_crossover_rad_s / (2 * np.pi)
        phi = float(_interp_log(frf, phase, m.gain_crossover_rad_s))
        ax_ph.vlines(f_c, phi - m.phase_margin_deg, phi, color=color, linewidth=2.2)
        ax_ph.annotate(f"PM {m.phase_margin_deg:.3g}°", (f_c, phi), xytext=(4, 4),
                       textcoords="offset points", fontsize=8, color=color)
    if np.isfinite(m.phase_crossover_rad_s) and np.isfinite(m.gain_margin_db):
        f_p = m.phase_crossover_rad_s / (2 * np.pi)
        ax_mag.vlines(f_p, -m.gain_margin_db, 0.0, color=color, linewidth=2.2)
        ax_mag.annotate(f"GM {m.gain_margin_db:.3g} dB", (f_p, -m.gain_margin_db), xytext=(4, -10),
                        textcoords="offset points", fontsize=8, color=color)
    ax_mag.text(0.01, 0.02, _summary(m), transform=ax_mag.transAxes, fontsize=7, va="bottom",
                ha="left", color=color, bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.8,
                                              "edgecolor": "0.8"})


def _nichols_shift(frf: FrequencyResponse, phase: np.ndarray, gain: np.ndarray, m) -> float:
    """The multiple of 360° that brings the phase at the first gain crossover within 180° of −180°."""
    if phase.size == 0:
        return 0.0
    if m is not None and m.gain_crossovers.size:
        phi = float(_interp_log(frf, phase, m.gain_crossovers[0]))
    else:
        above = gain >= 0.0
        cross = np.flatnonzero(above[:-1] != above[1:])
        if cross.size:
            phi = float(phase[cross[0]])
        else:
            finite = np.isfinite(gain)
            if not finite.any():
                return 0.0
            phi = float(phase[finite][np.argmin(np.abs(gain[finite]))])
    return float(-360.0 * np.round((phi + 180.0) / 360.0))


def _first_shifted_crossover_phase(curves) -> float:
    phase, gain = curves[0]
    above = gain >= 0.0
    cross = np.flatnonzero(above[:-1] != above[1:])
    return float(phase[cross[0]]) if cross.size else -180.0


def _nichols_view(curves) -> tuple[tuple[float, float], tuple[float, float]]:
    """Axis limits: gains clipped to [−40, 50] dB (at least [−20, 10]); the phases of what is in view,
    at least ±60° around −180°."""
    gains = np.concatenate([g[np.isfinite(g)] for _, g in curves]) if curves else np.zeros(0)
    g_lo = max(float(gains.min()), -40.0) if gains.size else -20.0
    g_hi = min(float(gains.max()), 50.0) if gains.size else 10.0
    y_lo, y_hi = min(g_lo, -20.0) - 2.0, max(g_hi, 10.0) + 2.0
    in_view = [p[np.isfinite(g) & (g >= y_lo) & (g <= y_hi)] for p, g in curves]
    seen = np.concatenate(in_view) if in_view else np.zeros(0)
    x_lo = min(float(seen.min()) if seen.size else -240.0, -240.0)
    x_hi = max(float(seen.max()) if seen.size else -120.0, -120.0)
    pad = max(0.03 * (x_hi - x_lo), 15.0)
    return (x_lo - pad, x_hi + pad), (y_lo, y_hi)


def _m_circles(ax: "Axes", x_lo: float, x_hi: float, y_lo: float, y_hi: float) -> None:
    """Contours of the closed-loop magnitude |L/(1+L)| in Nichols coordinates."""
    n_phase = int(np.clip((x_hi - x_lo) / 0.5, 200, 3000))
    phi = np.linspace(x_lo, x_hi, n_phase)
    g = np.linspace(y_lo, y_hi, 500)
    L = 10.0 ** (g[:, None] / 20.0) * np.exp(1j * np.radians(phi)[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        t_db = 20.0 * np.log10(np.abs(L / (1.0 + L)))
    t_db = np.where(np.isfinite(t_db), t_db, 100.0)
    contours = ax.contour(phi, g, t_db, levels=list(M_CIRCLES_DB), colors="0.55", linewidths=0.6,
                          zorder=1)
    labels = ax.clabel(contours, fmt={level: f"{level:g} dB" for level in M_CIRCLES_DB}, fontsize=6, inline=False)
    for label in labels:
        label.set_bbox(_LABEL_BOX)
        label.set_gid("m-circle-label")


def _mark_nichols(ax: "Axes", frf: FrequencyResponse, m: "Margins", shift: float, color) -> None:
    phase = np.asarray(frf.phase_deg, dtype=float) + shift
    if m.gain_crossovers.size:
        ax.plot(_interp_log(frf, phase, m.gain_crossovers), np.zeros(m.gain_crossovers.size), "o",
                markerfacecolor="none", color=color, markersize=6, zorder=5)
    if m.phase_crossovers.size:
        finite = np.isfinite(m.gain_margins_db)
        levels = _nearest_level(_interp_log(frf, phase, m.phase_crossovers[finite]))
        ax.plot(levels, -m.gain_margins_db[finite], "s", markerfacecolor="none", color=color,
                markersize=5, zorder=5)
    if np.isfinite(m.gain_crossover_rad_s):
        phi = float(_interp_log(frf, phase, m.gain_crossover_rad_s))
        ax.plot([phi - m.phase_margin_deg, phi], [0.0, 0.0], color=color, linewidth=2.2, zorder=4)
        ax.annotate(f"PM {m.phase_margin_deg:.3g}°", (phi - 0.5 * m.phase_margin_deg, 0.0), xytext=(0, 5),
                    textcoords="offset points", ha="center", va="bottom", fontsize=8, color=color,
                    bbox=_LABEL_BOX, zorder=6, gid="margin-label")
    if np.isfinite(m.phase_crossover_rad_s) and np.isfinite(m.gain_margin_db):
        level = float(_nearest_level(_interp_log(frf, phase, m.phase_crossover_rad_s)))
        ax.plot([level, level], [-m.gain_margin_db, 0.0], color=color, linewidth=2.2, zorder=4)
        ax.annotate(f"GM {m.gain_margin_db:.3g} dB", (level, -0.5 * m.gain_margin_db), xytext=(5, 0),
                    textcoords="offset points", ha="left", va="center", fontsize=8, color=color,
                    bbox=_LABEL_BOX, zorder=6, gid="margin-label")
