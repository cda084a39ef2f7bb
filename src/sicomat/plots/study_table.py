"""How the study figures (:mod:`.study`) read a parameter study's results table: columns checked by name, a
column as numbers or as categories, the unit its name ends with, failed variants, colour categories.

The table (issue 14, ``docs/studies.md``) is a pandas ``DataFrame``, one row per variant: ``variant``, one column
per study parameter (its key path), metrics ``<analysis>.<metric>`` (NaN when undefined), bool columns, and
``error`` (null when the variant succeeded)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    import pandas as pd
    from matplotlib.axis import Axis
    from matplotlib.figure import Figure

__all__ = ["UNIT_SUFFIXES", "table_units", "unit_of", "suffix_unit", "column_label", "format_value", "engineering_ticks", "refuse",
           "check_columns", "check_column", "numeric_columns", "as_numbers", "numbers", "succeeded", "counts",
           "Colour", "colour_groups", "colormap"]

UNIT_SUFFIXES: dict[str, str] = {
    "_m_s2": "m/s²", "_m_s": "m/s", "_hz": "Hz", "_deg": "°", "_rad": "rad", "_db": "dB", "_mm": "mm",
    "_um": "µm", "_ms": "ms", "_m": "m", "_s": "s", "_kg": "kg", "_rpm": "rpm", "_pct": "%", "_percent": "%",
    "_a": "A",
    "_v": "V", "_w": "W",
}
"""The unit a column's name ends with (``modal.f1_hz`` → Hz); the longest matching suffix wins."""

_SI = {"m", "s", "Hz", "kg", "A", "V", "W", "m/s", "m/s²", "rad"}   # units written with an SI prefix when apt
_PREFIXES = {-12: "p", -9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M", 9: "G", 12: "T"}
_WRAP = 24                # a label longer than this is broken at a dot
_BOOL_COLOURS = {False: "tab:red", True: "tab:green"}


_TABLE_UNITS: "ContextVar[Mapping[str, str]]" = ContextVar("study_table_units", default={})
"""The units the table being drawn gives its columns (``table.attrs["units"]``), set by :func:`table_units`
for the length of one figure's drawing."""


def table_units(draw: "Callable[..., Figure]") -> "Callable[..., Figure]":
    """Decorate a figure function of a table: while it draws, :func:`unit_of` reads the units the table's
    ``attrs["units"]`` gives (a study's SI metrics and inputs, whose names carry no unit suffix)."""
    import functools

    @functools.wraps(draw)
    def drawn(table: "pd.DataFrame", *args: Any, **kwargs: Any) -> "Figure":
        token = _TABLE_UNITS.set(dict(getattr(table, "attrs", {}).get("units", {}) or {}))
        try:
            return draw(table, *args, **kwargs)
        finally:
            _TABLE_UNITS.reset(token)

    return drawn


def unit_of(column: str) -> str | None:
    """The unit the table being drawn gives the column (:func:`table_units`), else the one its name ends
    with (``UNIT_SUFFIXES``), else None."""
    return _TABLE_UNITS.get().get(column) or suffix_unit(column)


def suffix_unit(column: str) -> str | None:
    """The unit the column's name ends with (``UNIT_SUFFIXES``, the longest matching suffix), else None."""
    name = column.lower()
    for suffix in sorted(UNIT_SUFFIXES, key=len, reverse=True):
        if name.endswith(suffix):
            return UNIT_SUFFIXES[suffix]
    return None


def column_label(column: str, *, wrap: bool = True) -> str:
    """The column's name (broken at a dot near its middle when long) and its unit in brackets."""
    name = column
    if wrap and len(name) > _WRAP and "." in name:
        dots = [i for i, ch in enumerate(name) if ch == "."]
        cut = min(dots, key=lambda i: abs(i - len(name) / 2)) + 1
        name = name[:cut] + "\n" + name[cut:]
    unit = unit_of(column)
    return name if unit is None else f"{name} ({unit})"


def _prefixed(unit: str | None, magnitude: float) -> bool:
    """Whether values of this size in this unit read better with an SI prefix (2 µm rather than 2e-06 m)."""
    return unit in _SI and math.isfinite(magnitude) and magnitude > 0.0 and not 0.1 <= magnitude < 1e4


def format_value(value: float, unit: str | None) -> str:
    """``value`` to 4 significant digits with its unit, with an SI prefix when the unit takes one and the value
    is small or large (``format_value(1.595e-6, "m")`` → ``"1.595 µm"``)."""
    if not math.isfinite(value):
        return f"{value} {unit or ''}".rstrip()
    if _prefixed(unit, abs(value)):
        exp = min(12, max(-12, 3 * math.floor(math.log10(abs(value)) / 3)))
        return f"{value / 10.0 ** exp:.4g} {_PREFIXES[exp]}{unit}"
    return f"{value:.4g} {unit or ''}".rstrip()


def engineering_ticks(axis: "Axis", column: str, values: "np.ndarray") -> None:
    """Ticks with an SI prefix (2 µm, 12 kHz) on an axis whose column has such a unit and small or large values,
    rather than matplotlib's offset text (a lone "1e-6" under the axis)."""
    import numpy as np

    unit = unit_of(column)
    finite = np.abs(values[np.isfinite(values)])
    if finite.size and _prefixed(unit, float(finite.max())):
        from matplotlib.ticker import EngFormatter

        axis.set_major_formatter(EngFormatter(unit=unit or "", sep=" "))


def refuse(message: str, value: object) -> ModelError:
    """The one error of a figure asked for something the table cannot give (``path="plot"``)."""
    return ModelError(message, path="plot", value=value)


def check_columns(table: "pd.DataFrame", columns: Sequence[str] | str, what: str) -> list[str]:
    """``columns`` as a list, each one in the table (else a ``ModelError`` listing the table's columns)."""
    cols = [columns] if isinstance(columns, str) else list(columns)
    if not cols:
        raise refuse(f"{what}: no column given; the table has: {', '.join(map(str, table.columns))}", columns)
    for c in cols:
        check_column(table, c, what)
    return cols


def check_column(table: "pd.DataFrame", column: str, what: str) -> None:
    """A ``ModelError`` naming ``column`` and listing the table's columns when it has no such column."""
    if column not in table.columns:
        raise refuse(f"{what}: no column {column!r} in the results table; the table has: "
                      f"{', '.join(map(str, table.columns))}", column)


def numeric_columns(table: "pd.DataFrame") -> list[str]:
    """The columns a figure can read as numbers (``variant`` left out)."""
    return [str(c) for c in table.columns if as_numbers(table[c]) is not None and c not in ("variant", "error")]


def as_numbers(series: "pd.Series") -> "np.ndarray | None":
    """The column as floats, or None when it holds text or bools."""
    import numpy as np
    import pandas as pd

    if pd.api.types.is_bool_dtype(series.dtype):
        return None
    if pd.api.types.is_numeric_dtype(series.dtype):
        return series.to_numpy(dtype=float, na_value=np.nan)
    present = series.dropna()
    if any(isinstance(v, (bool, np.bool_)) for v in present):
        return None
    try:
        return pd.to_numeric(series, errors="raise").to_numpy(dtype=float, na_value=np.nan)
    except (TypeError, ValueError):
        return None


def numbers(table: "pd.DataFrame", column: str, what: str) -> "np.ndarray":
    """The column as floats (NaN where undefined), else a ``ModelError`` naming it and the numeric columns."""
    import numpy as np

    values = as_numbers(table[column])
    if values is None:
        sample = table[column].dropna()
        first = sample.iloc[0] if len(sample) else None
        kind = "true/false values" if isinstance(first, (bool, np.bool_)) else "text"
        found = repr(first.item() if isinstance(first, np.generic) else first)
        raise refuse(f"{what}: column {column!r} holds {kind} (e.g. {found}), not numbers; the numeric columns "
                      f"are: {', '.join(numeric_columns(table)) or 'none'}", column)
    return values


def succeeded(table: "pd.DataFrame") -> "np.ndarray":
    """Mask of the variants that succeeded (a null or empty ``error``; every row when there is no such column)."""
    import numpy as np

    if "error" not in table.columns:
        return np.ones(len(table), dtype=bool)
    err = table["error"]
    return (err.isna() | (err.astype(str) == "")).to_numpy()


def counts(ok: "np.ndarray") -> str:
    """"36 of 40 variants (4 failed, left out)", or "40 variants" when none failed, for a figure's title."""
    failed = int((~ok).sum())
    return f"{int(ok.sum())} of {ok.size} variants ({failed} failed, left out)" if failed else f"{ok.size} variants"


@dataclass(frozen=True)
class Colour:
    """How lines or points are coloured: categories (label, mask, colour) or a continuous column."""

    groups: tuple[tuple[str, "np.ndarray", Any], ...]
    values: "np.ndarray | None" = None        # continuous: the colour column's values
    name: str = ""


def colour_groups(table: "pd.DataFrame", color: str | None, ok: "np.ndarray", what: str) -> Colour:
    """Categories of a text or bool column (by their text, sorted; bools red/green) or a numeric column's values."""
    import numpy as np

    if color is None:
        return Colour((("variants", ok, "tab:blue"),))
    import pandas as pd

    check_column(table, color, what)
    values = as_numbers(table[color])
    if values is not None:
        return Colour((), values, color)
    raw = table[color].to_numpy(dtype=object)
    defined = ~pd.isna(table[color]).to_numpy(dtype=bool)                   # None, NaN, pd.NA
    keys = np.array([str(v) for v in raw], dtype=object)
    present = [v for v, keep in zip(raw, ok & defined) if keep]
    boolean = bool(present) and all(isinstance(v, (bool, np.bool_)) for v in present)
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink",
               "tab:olive", "tab:cyan", "tab:gray"]
    groups: list[tuple[str, np.ndarray, Any]] = []
    for i, key in enumerate(sorted({str(v) for v in present})):
        colour = _BOOL_COLOURS[key == "True"] if boolean else palette[i % len(palette)]
        groups.append((f"{color} = {key}", ok & defined & (keys == key), colour))
    if (ok & ~defined).any():
        groups.append((f"{color} undefined", ok & ~defined, "0.55"))
    return Colour(tuple(groups), None, color)


def colormap() -> Any:
    """The colour map of a numeric colour column; an undefined value is grey."""
    import matplotlib

    return matplotlib.colormaps["viridis"].with_extremes(bad="0.6")
