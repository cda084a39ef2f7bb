"""Figures of a parameter study's results table (issue 14, ``docs/studies.md``): the scatter matrix, parallel
coordinates, histograms with their quantiles and the share of variants meeting a threshold, and the Pareto plot
of a front computed by :func:`sicomat.studies.pareto.pareto_front` (``plots/`` never computes). How the table is
read (columns, units, failed variants, colours) is :mod:`.study_table`. Failed variants are left out of every
figure and counted in its title."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from .base import new_figure
from .study_table import (Colour, as_numbers, check_columns, colormap, colour_groups, column_label, counts,
                          engineering_ticks, format_value, numbers, refuse, succeeded, table_units, unit_of)

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["scatter_matrix", "parallel_coordinates", "histograms", "pareto_plot", "THRESHOLD_OPS"]

THRESHOLD_OPS = (">=", ">", "<=", "<")
_SHOWN = {">=": "≥", ">": ">", "<=": "≤", "<": "<"}
_MAX_LABELS = 15          # variant numbers written on a Pareto plot, at most


# --------------------------------------------------------------------------- scatter matrix
@table_units
def scatter_matrix(table: "pd.DataFrame", columns: Sequence[str], *, color: str | None = None) -> "Figure":
    """Every pair of ``columns`` against each other, each column's histogram on the diagonal.

    Failed variants are left out (counted in the title), and so is a variant from the panels where one of its
    values is undefined (NaN). ``color``: a bool or text column colours the points by category (legend); a
    numeric one by a colour map (colour bar). Raises ``ModelError`` on an unknown or non-numeric column.
    """
    import numpy as np

    what = "scatter matrix"
    cols = check_columns(table, columns, what)
    data = [numbers(table, c, what) for c in cols]
    ok = succeeded(table)
    paint = colour_groups(table, color, ok, what)
    k = len(cols)
    fig = new_figure(figsize=(2.4 * k + 1.8, 2.3 * k + 0.7))
    axes = fig.subplots(k, k, squeeze=False, sharex="col", sharey="row")
    scatter = None
    for i in range(k):
        for j in range(k):
            ax = axes[i, j]
            if i == j:
                _diagonal(ax, data[i], ok, paint)
            else:
                both = np.isfinite(data[i]) & np.isfinite(data[j])
                scatter = _points(ax, data[j], data[i], both, ok, paint) or scatter
            if i == k - 1:
                ax.set_xlabel(column_label(cols[j]), fontsize=8)
            if j == 0:
                ax.set_ylabel(column_label(cols[i]), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.25)
    for j, values in enumerate(data):                   # shared: one formatter per column and per row
        engineering_ticks(axes[k - 1, j].xaxis, cols[j], values[ok])
        engineering_ticks(axes[j, 0].yaxis, cols[j], values[ok])
    _finish_colour(fig, axes, paint, scatter)
    undefined = int((ok & ~np.all([np.isfinite(d) for d in data], axis=0)).sum())
    note = f"; {undefined} with an undefined value, left out of its panels" if undefined else ""
    fig.suptitle(f"scatter matrix of {counts(ok)}{note}", fontsize=10)
    return fig


def _points(ax: "Axes", x: "np.ndarray", y: "np.ndarray", finite: "np.ndarray", ok: "np.ndarray",
            paint: Colour) -> Any:
    import numpy as np

    if paint.values is not None:
        sel = ok & finite
        return ax.scatter(x[sel], y[sel], c=paint.values[sel], cmap=colormap(), s=14,
                          vmin=np.nanmin(paint.values[ok]) if ok.any() else None,
                          vmax=np.nanmax(paint.values[ok]) if ok.any() else None,
                          plotnonfinite=True, edgecolors="none")
    for label, mask, colour in paint.groups:
        sel = mask & finite
        ax.scatter(x[sel], y[sel], s=14, color=colour, alpha=0.8, label=label, edgecolors="none")
    return None


def _diagonal(ax: "Axes", values: "np.ndarray", ok: "np.ndarray", paint: Colour) -> None:
    """The column's histogram on a twin axes (the panel's own y axis stays its row's variable), stacked by
    colour category."""
    import numpy as np

    finite = ok & np.isfinite(values)
    twin = ax.twinx()
    twin.set_yticks([])
    if not finite.any():
        return
    bins = np.histogram_bin_edges(values[finite], bins=min(30, max(5, int(np.sqrt(finite.sum()))))).tolist()
    if paint.values is not None:
        twin.hist(values[finite], bins=bins, color="0.45", alpha=0.8)
    else:
        parts = [values[mask & finite] for _, mask, _ in paint.groups]
        twin.hist(parts, bins=bins, stacked=True, color=[c for _, _, c in paint.groups], alpha=0.8)


def _finish_colour(fig: "Figure", axes: Any, paint: Colour, mappable: Any) -> None:
    if paint.values is not None:
        if mappable is not None:
            fig.colorbar(mappable, ax=axes, label=column_label(paint.name), shrink=0.6)
    elif len(paint.groups) > 1 or paint.name:
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], marker="o", linestyle="none", color=c, label=f"{label} ({int(m.sum())})")
                   for label, m, c in paint.groups]
        fig.legend(handles=handles, loc="outside upper right", fontsize=8)


# --------------------------------------------------------------------------- parallel coordinates
@table_units
def parallel_coordinates(table: "pd.DataFrame", columns: Sequence[str], *, color: str | None = None) -> "Figure":
    """One line per succeeded variant through one vertical axis per column, each column scaled to its own range
    (its minimum at the bottom, its maximum at the top, both written); a text or bool column is an axis of
    categories. ``color`` as in :func:`scatter_matrix`. Raises ``ModelError`` on an unknown column."""
    import numpy as np
    from matplotlib.collections import LineCollection

    what = "parallel coordinates"
    cols = check_columns(table, columns, what)
    ok = succeeded(table)
    paint = colour_groups(table, color, ok, what)
    k = len(cols)
    fig = new_figure(figsize=(max(6.0, 1.9 * k + 2.0), 5.0))
    ax = fig.subplots()
    y = np.full((len(table), k), np.nan)
    for j, c in enumerate(cols):
        y[:, j] = _scaled_axis(ax, j, c, table[c], ok)
    segments = np.stack([np.broadcast_to(np.arange(k, dtype=float), y.shape), y], axis=-1)
    alpha = float(np.clip(40.0 / max(int(ok.sum()), 1), 0.15, 0.9))
    if paint.values is not None:
        lines = LineCollection(list(segments[ok]), array=paint.values[ok], cmap=colormap(), linewidths=1.2,
                               alpha=alpha)
        ax.add_collection(lines)
        fig.colorbar(lines, ax=ax, label=column_label(paint.name), shrink=0.8)
    else:
        for label, mask, colour in paint.groups:
            ax.add_collection(LineCollection(list(segments[mask]), colors=colour, linewidths=1.2, alpha=alpha,
                                             label=f"{label} ({int(mask.sum())})"))
        if len(paint.groups) > 1 or paint.name:
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlim(-0.3, k - 0.7)
    ax.set_ylim(-0.12, 1.12)
    ax.set_yticks([])
    ax.set_xticks(range(k), [column_label(c) for c in cols], fontsize=8)
    for side in ("left", "right", "top"):
        ax.spines[side].set_visible(False)
    ax.set_title(f"parallel coordinates of {counts(ok)}; each axis spans its own range", fontsize=10)
    return fig


def _scaled_axis(ax: "Axes", j: int, column: str, series: "pd.Series", ok: "np.ndarray") -> "np.ndarray":
    """Draw column ``j``'s axis with its range (or categories) written; its values scaled to [0, 1] (NaN where
    undefined or infinite: the line is broken there)."""
    import numpy as np
    import pandas as pd

    ax.axvline(j, color="0.3", linewidth=0.8, zorder=0)
    numbers = as_numbers(series)
    text: dict[str, Any] = dict(fontsize=7, ha="center", color="0.15", clip_on=False, zorder=5,
                                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))
    if numbers is not None:
        finite = numbers[ok & np.isfinite(numbers)]
        if finite.size == 0:
            return np.full(numbers.shape, np.nan)
        lo, hi = float(finite.min()), float(finite.max())
        with np.errstate(invalid="ignore"):
            scaled = (numbers - lo) / (hi - lo) if hi > lo else np.full(numbers.shape, 0.5)
        scaled[~np.isfinite(numbers)] = np.nan
        ax.text(j, -0.025, format_value(lo, unit_of(column)), va="top", gid=f"min-{j}", **text)
        ax.text(j, 1.025, format_value(hi, unit_of(column)), va="bottom", gid=f"max-{j}", **text)
        return scaled
    raw = series.to_numpy(dtype=object)
    defined = ~pd.isna(series).to_numpy(dtype=bool)
    cats = sorted({str(v) for v, keep in zip(raw, ok & defined) if keep})
    where = {cat: (0.5 if len(cats) == 1 else i / (len(cats) - 1)) for i, cat in enumerate(cats)}
    for cat, pos in where.items():
        ax.text(j + 0.04, pos, cat, va="center", fontsize=7, ha="left", color="0.15",
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8), zorder=5)
    return np.array([where.get(str(v), np.nan) if d else np.nan for v, d in zip(raw, defined)])


# --------------------------------------------------------------------------- histograms
@table_units
def histograms(table: "pd.DataFrame", columns: Sequence[str], *,
               thresholds: Mapping[str, tuple[str, float]] | None = None) -> "Figure":
    """One histogram per column with its 5 %, 50 % and 95 % quantiles marked (numpy's linear definition), and,
    for a column in ``thresholds`` (``{"margins.velocity.phase_margin_deg": (">=", 40.0)}``), the threshold
    and the share of the variants with a value that meet it. Raises ``ModelError`` on an unknown or
    non-numeric column, or a threshold that is not ``(op, number)`` with op one of ``>=``, ``>``, ``<=``, ``<``."""
    import math

    import numpy as np

    what = "histograms"
    cols = check_columns(table, columns, what)
    data = [numbers(table, c, what) for c in cols]
    limits = _check_thresholds(thresholds or {}, cols)
    ok = succeeded(table)
    k = len(cols)
    ncols = min(k, 3)
    nrows = math.ceil(k / ncols)
    fig = new_figure(figsize=(4.4 * ncols, 3.4 * nrows + 0.4))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False).ravel())
    for ax, c, values in zip(axes, cols, data):
        _histogram(ax, c, values[ok], limits.get(c))
    for ax in axes[k:]:
        ax.set_visible(False)
    fig.suptitle(f"histograms of {counts(ok)}", fontsize=10)
    return fig


def _check_thresholds(thresholds: Mapping[str, tuple[str, float]], cols: list[str]) -> dict[str, tuple[str, float]]:
    import math

    out = {}
    for c, limit in thresholds.items():
        if c not in cols:
            raise refuse(f"histograms: a threshold for {c!r}, which is not among the plotted columns "
                          f"({', '.join(cols)})", c)
        try:
            op, value = limit
            value = float(value)
        except (TypeError, ValueError):
            raise refuse(f"histograms: the threshold of {c!r} must be (op, number), e.g. ('>=', 40.0)",
                          limit) from None
        if op not in THRESHOLD_OPS or not math.isfinite(value):
            raise refuse(f"histograms: the threshold of {c!r} must be (op, finite number) with op one of "
                          f"{', '.join(THRESHOLD_OPS)}", limit)
        out[c] = (op, value)
    return out


def _histogram(ax: "Axes", column: str, values: "np.ndarray", limit: tuple[str, float] | None) -> None:
    import operator

    import numpy as np

    defined = values[~np.isnan(values)]                # ±inf count (an infinite gain margin meets any limit)
    finite = defined[np.isfinite(defined)]
    undefined, infinite = values.size - defined.size, defined.size - finite.size
    unit = unit_of(column)
    ax.set_xlabel(column_label(column, wrap=False) if len(column) < 40 else column_label(column), fontsize=8)
    ax.set_ylabel("variants", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.25)
    lines = []
    if finite.size == 0:
        ax.text(0.5, 0.5, "no value", transform=ax.transAxes, ha="center", va="center", color="0.4")
    else:
        heights, _, _ = ax.hist(finite, bins=min(30, max(5, int(np.sqrt(finite.size)))), color="tab:blue",
                                alpha=0.7)
        for bar in ax.patches:                          # only the bars so far
            bar.set_gid("bar")
        ax.set_ylim(0.0, 1.5 * float(np.max(heights)))    # head room for the legend above the bars
        for q, style in zip((5, 50, 95), (":", "-", ":")):
            with np.errstate(invalid="ignore"):
                at = float(np.quantile(defined, q / 100.0))
            if np.isnan(at):                            # between two infinities: inf - inf
                at = float(np.quantile(defined, q / 100.0, method="nearest"))
            name = "median" if q == 50 else f"{q} %"
            if np.isfinite(at):
                lines.append(ax.axvline(at, color="0.15", linestyle=style, linewidth=1.2, gid=f"quantile-{q}",
                                        label=f"{name}: {format_value(at, unit)}"))
            else:
                lines.append(ax.plot([], [], linestyle="none", label=f"{name}: {at}")[0])
    head = f"{defined.size} values" + (f" ({infinite} infinite)" if infinite else "") + \
        (f", {undefined} undefined" if undefined else "")
    if limit is not None:
        op, value = limit
        test = {">=": operator.ge, ">": operator.gt, "<=": operator.le, "<": operator.lt}[op]
        met = int(np.count_nonzero(test(defined, value)))
        share = 100.0 * met / defined.size if defined.size else float("nan")
        lines.append(ax.axvline(value, color="tab:red", linewidth=1.6, gid="threshold",
                                label=f"threshold {_SHOWN[op]} {format_value(value, unit)}"))
        lo, hi = ax.get_xlim()
        if op in (">=", ">"):
            ax.axvspan(min(lo, value), value, color="tab:red", alpha=0.08, zorder=0, gid="fails")
        else:
            ax.axvspan(value, max(hi, value), color="tab:red", alpha=0.08, zorder=0, gid="fails")
        ax.set_xlim(min(lo, value), max(hi, value))
        head = f"{_SHOWN[op]} {format_value(value, unit)}: {share:.1f} % meet it ({met} of {head})"
    engineering_ticks(ax.xaxis, column, finite)
    ax.set_title(head, fontsize=9)
    if lines:
        ax.legend(handles=lines, fontsize=7, loc="best")


# --------------------------------------------------------------------------- Pareto plot
@table_units
def pareto_plot(table: "pd.DataFrame", x: str, y: str, *, senses: Sequence[str] = ("min", "max"),
                front: Sequence[int] | "np.ndarray", feasible: "np.ndarray | None" = None,
                objectives: int = 2) -> "Figure":
    """Every succeeded variant of ``y`` against ``x``, the non-dominated ones (``front``: row positions in
    ``table``, as :func:`sicomat.studies.pareto.pareto_front` returns them for ``table[[x, y]]``) highlighted,
    joined as a staircase (the edge of the region they dominate) and labelled with their variant number (at most
    15, spread along the front). ``senses``: ``"min"`` or ``"max"`` for ``x`` and ``y``. Computing the front is
    the caller's (``plots/`` never computes). ``feasible`` (bool per row): the variants that meet the study's
    constraints, among which the front was taken; the others are drawn faded. ``objectives``: how many the
    front is non-dominated in; beyond the two drawn its points are not joined (in this plane they need not
    form a staircase). Raises ``ModelError`` on an unknown or non-numeric column, bad senses, or a front row
    that is not a succeeded variant."""
    import numpy as np

    from matplotlib import patheffects

    what = "Pareto plot"
    check_columns(table, [x, y], what)
    xs, ys = numbers(table, x, what), numbers(table, y, what)
    if isinstance(senses, str) or len(senses) != 2 or any(s not in ("min", "max") for s in senses):
        raise refuse(f"{what}: senses must be two of 'min'/'max', one for {x!r} and one for {y!r}", senses)
    ok = succeeded(table)
    rows = _front_rows(front, ok, len(table), what)
    variant = table["variant"].to_numpy() if "variant" in table.columns else np.arange(len(table))
    shown = ok & np.isfinite(xs) & np.isfinite(ys)
    fig = new_figure(figsize=(7.2, 5.0))
    ax = fig.subplots()
    meets = shown if feasible is None else shown & np.asarray(feasible, dtype=bool)
    fails = shown & ~meets
    ax.scatter(xs[meets], ys[meets], s=16, color="0.45", edgecolors="none",
               label=f"variants ({int(meets.sum())})" if feasible is None else f"meet the constraints ({int(meets.sum())})",
               gid="variants")
    if fails.any():
        ax.scatter(xs[fails], ys[fails], s=14, facecolors="none", edgecolors="0.75", linewidths=0.6,
                   label=f"constraints not met ({int(fails.sum())})", gid="infeasible")
    on = rows[np.isfinite(xs[rows]) & np.isfinite(ys[rows])]
    on = on[np.lexsort((ys[on] if senses[1] == "min" else -ys[on], xs[on]))]
    if objectives <= 2:
        ax.plot(xs[on], ys[on], drawstyle="steps-post" if senses[0] == "min" else "steps-pre", color="tab:red",
                linewidth=1.4, gid="staircase")
    ax.scatter(xs[on], ys[on], s=40, color="tab:red", edgecolors="black", linewidths=0.6, zorder=3,
               label=f"non-dominated ({len(on)})", gid="front")
    picked = np.unique(np.round(np.linspace(0, len(on) - 1, min(len(on), _MAX_LABELS))).astype(int)) \
        if len(on) else np.empty(0, dtype=int)
    # each number towards the better side of its point: no variant lies there (it would dominate the point)
    sx, sy = (-1 if senses[0] == "min" else 1), (1 if senses[1] == "max" else -1)
    halo = [patheffects.withStroke(linewidth=2.5, foreground="white")]      # readable over the staircase
    for i in picked:
        ax.annotate(str(variant[on[i]]), (xs[on[i]], ys[on[i]]), xytext=(3 * sx, 3 * sy), textcoords="offset points",
                    ha="left" if sx > 0 else "right", va="bottom" if sy > 0 else "top",
                    fontsize=7, color="darkred", gid="variant-label", zorder=4, path_effects=halo)
    if len(picked) < len(on):
        ax.plot([], [], linestyle="none", label=f"numbers on {len(picked)} of {len(on)}")
    better = {"min": "smaller is better", "max": "larger is better"}
    ax.set_xlabel(f"{column_label(x, wrap=False)}, {better[senses[0]]}", fontsize=9)
    ax.set_ylabel(f"{column_label(y, wrap=False)}, {better[senses[1]]}", fontsize=9)
    engineering_ticks(ax.xaxis, x, xs[shown])
    engineering_ticks(ax.yaxis, y, ys[shown])
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    hidden = int((ok & ~(np.isfinite(xs) & np.isfinite(ys))).sum())
    note = f"\n{hidden} with an undefined or infinite value not drawn" if hidden else ""
    among = f" in {objectives} objectives (two drawn)" if objectives > 2 else ""
    ax.set_title(f"Pareto front: {len(rows)} non-dominated{among} of {counts(ok)}{note}", fontsize=10)
    return fig


def _front_rows(front: Any, ok: "np.ndarray", n: int, what: str) -> "np.ndarray":
    import numpy as np

    rows = np.asarray(front)
    if rows.ndim != 1 or (rows.size and not np.issubdtype(rows.dtype, np.integer)):
        raise refuse(f"{what}: front must be row positions in the table (integers), as pareto_front returns",
                      front)
    bad = [int(r) for r in rows if not 0 <= r < n or not ok[r]]
    if bad:
        raise refuse(f"{what}: front row {bad[0]} is not a succeeded variant of the table ({n} rows)", bad[0])
    return rows.astype(int)
