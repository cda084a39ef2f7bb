"""A study's results: the table, its Pareto front, its figures and the ``--json`` summary."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    import pandas
    from matplotlib.figure import Figure

    from .variants import StudyPlan

__all__ = ["StudyResults", "HEADLINE", "FIGURES"]

HEADLINE = ("modal.f1_hz", "tune.velocity_bandwidth_hz", "margins.velocity.phase_margin_deg",
            "margins.position.phase_margin_deg", "simulate.max_following_error", "circle.circular_deviation")
"""The metrics the default figures show (those of the study's analyses)."""

SPREAD = ("modal.f1_hz", "margins.velocity.phase_margin_deg", "margins.velocity.gain_margin_db",
          "margins.position.phase_margin_deg", "tune.velocity_phase_margin_deg", "tune.velocity_bandwidth_hz",
          "simulate.max_following_error")
"""The histograms' metrics: margins and frequencies over the spreads."""

FIGURES = ("scatter_matrix", "parallel_coordinates", "histograms", "pareto")


@dataclass(frozen=True)
class StudyResults:
    """One row per variant (``variant``, the inputs by key path, the metrics, ``constraints_ok``, ``error``)."""

    table: "pandas.DataFrame"
    plan: "StudyPlan"
    elapsed_s: float = math.nan
    results_path: Path | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def to_pandas(self) -> "pandas.DataFrame":
        """The table (a copy)."""
        return self.table.copy()

    @property
    def inputs(self) -> list[str]:
        """The input columns (the parameters' key paths)."""
        return [p.path for p in self.plan.parameters]

    @property
    def failed(self) -> int:
        """Variants whose analyses failed (a message in ``error``)."""
        return int(self.table["error"].notna().sum())

    def objectives(self, maximize: Sequence[str] | None = None,
                   minimize: Sequence[str] | None = None) -> list[tuple[str, str]]:
        """The Pareto objectives: those given, else the study's ``[pareto]``."""
        if maximize is None and minimize is None:
            if self.plan.spec.pareto is None:
                raise ModelError("no objectives: give maximize=/minimize= or a [pareto] table in the study",
                                 path="pareto")
            return self.plan.spec.pareto.objectives
        out = [(n, "max") for n in maximize or ()] + [(n, "min") for n in minimize or ()]
        if len(out) < 2:
            raise ModelError("give at least two objectives", path="pareto", value=out)
        for name, _ in out:
            self._column(name, numeric=True)
        return out

    def pareto(self, maximize: Sequence[str] | None = None, minimize: Sequence[str] | None = None, *,
               feasible_only: bool = True) -> "pandas.DataFrame":
        """The non-dominated variants for the objectives (default: the study's ``[pareto]``), among those
        that succeeded and, with ``feasible_only``, meet every constraint; sorted by the first objective."""
        import numpy as np

        from .pareto import pareto_front

        objectives = self.objectives(maximize, minimize)
        pool = self.table[self.table["error"].isna()]
        if feasible_only:
            pool = pool[pool["constraints_ok"].fillna(False).astype(bool)]
        values = np.column_stack([pool[name].to_numpy(dtype=float) for name, _ in objectives]) \
            if len(pool) else np.zeros((0, len(objectives)))
        front = pool.iloc[pareto_front(values, [sense for _, sense in objectives])]
        first, sense = objectives[0]
        return front.sort_values(first, ascending=sense == "min", kind="stable")

    def _column(self, name: str, numeric: bool = False) -> str:
        if name not in self.table.columns:
            raise ModelError(f"no column {name!r}; the columns are {', '.join(map(str, self.table.columns))}",
                             path="columns", value=name)
        if numeric and not _numeric(self.table[name]):
            raise ModelError(f"the column {name!r} is not a number", path="columns", value=name)
        return name

    def default_columns(self, categories: bool = False) -> list[str]:
        """The inputs that vary (the numeric ones; with ``categories`` the catalogue ids too: the parallel
        plot's axes of categories) and the headline metrics that vary."""
        names = [c for c in self.inputs if (categories or _numeric(self.table[c])) and self.table[c].nunique() > 1]
        names += [c for c in HEADLINE if c in self.table.columns and _varies(self.table[c])]
        return names

    def plot(self, kind: str = "scatter_matrix", columns: Sequence[str] | None = None, *,
             color: str | None = "constraints_ok") -> "Figure":
        """A figure of the table: ``scatter_matrix``, ``parallel_coordinates``, ``histograms`` (margins and
        frequencies over the spreads) or ``pareto`` (the study's objectives, the front highlighted)."""
        from ..plots import study as plots

        if kind not in FIGURES:
            raise ModelError(f"expected one of {', '.join(FIGURES)}", path="kind", value=kind)
        if kind == "pareto":
            objectives = self.objectives()
            front = self.pareto()
            (x, sx), (y, sy) = objectives[0], objectives[1]
            feasible = (self.table["constraints_ok"].fillna(False).astype(bool).to_numpy()
                        if self.plan.spec.constraints else None)
            return plots.pareto_plot(self.table, x, y, senses=(sx, sy), front=front["variant"].to_numpy(),
                                     feasible=feasible, objectives=len(objectives))
        if kind == "histograms":
            cols = list(columns) if columns is not None else \
                [c for c in SPREAD if c in self.table.columns and _varies(self.table[c])]
            thresholds = {}
            for c in self.plan.constraints:
                if c.metric in cols and isinstance(c.bound, float) and c.operator in (">=", "<=", ">", "<"):
                    thresholds[c.metric] = (c.operator, c.bound)
            return plots.histograms(self.table, cols, thresholds=thresholds)
        cols = list(columns) if columns is not None else self.default_columns(kind == "parallel_coordinates")
        colour = color if color in self.table.columns else None
        if kind == "scatter_matrix":
            return plots.scatter_matrix(self.table, cols, color=colour)
        return plots.parallel_coordinates(self.table, cols, color=colour)

    def write_figures(self, folder: Path) -> list[Path]:
        """Every figure that has something to show, saved as PNG into ``folder``."""
        from ..plots.base import save_figure

        written = []
        for kind in FIGURES:
            if kind == "pareto" and self.plan.spec.pareto is None:
                continue
            if kind != "pareto" and kind != "histograms" and len(self.default_columns()) < 2:
                continue
            if kind == "histograms" and not any(c in self.table.columns and _varies(self.table[c]) for c in SPREAD):
                continue
            if self.table["error"].notna().all():
                continue
            path = folder / f"{kind}.png"
            save_figure(self.plot(kind), path)
            written.append(path)
        return written

    def summary(self) -> dict[str, Any]:
        """The ``sicomat study --json`` object: ``variants``, ``failed``, ``elapsed_s``, ``results`` (the
        table's path), ``pareto`` (objectives and the non-dominated variants, or None), and beside them
        ``constraints_met``, ``diverged``, ``errors`` (the first few messages) and the engine's figures."""
        table = self.table
        pareto = None
        if self.plan.spec.pareto is not None:
            front = self.pareto()
            keep = ["variant", *self.inputs, *[n for n, _ in self.objectives() if n not in self.inputs]]
            pareto = {"objectives": [[n, s] for n, s in self.objectives()],
                      "variants": [{k: _plain(row[k]) for k in keep} for _, row in front.iterrows()]}
        diverged = int(table["simulate.diverged"].fillna(False).astype(bool).sum()) \
            if "simulate.diverged" in table.columns else None
        errors = table.loc[table["error"].notna(), ["variant", "error"]].head(5)
        return {"variants": int(len(table)), "failed": self.failed, "elapsed_s": self.elapsed_s,
                "results": None if self.results_path is None else str(self.results_path), "pareto": pareto,
                "constraints": list(self.plan.spec.constraints),
                "constraints_met": int(table["constraints_ok"].fillna(False).astype(bool).sum()),
                "diverged": diverged,
                "errors": [{"variant": int(r.variant), "error": str(r.error)} for r in errors.itertuples()],
                **self.info}


def _varies(series: "pandas.Series") -> bool:
    """Whether a metric varies over the study by more than a part in 10^3 of its size: a margin the tuning
    held at its target (80.0000 to 80.0003 degrees) says nothing in a scatter plot but its solver's tolerance."""
    import numpy as np

    values = series.to_numpy(dtype=float, na_value=np.nan)
    values = values[np.isfinite(values)]
    return bool(values.size) and float(np.ptp(values)) > 1e-3 * float(np.max(np.abs(values)))


def _numeric(series: "pandas.Series") -> bool:
    import pandas as pd

    return bool(pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series))


def _plain(value: Any) -> Any:
    """A table value as JSON: numpy scalars to Python, NaN to None."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is not None and not isinstance(value, (int, float, str, bool)):
        return None if str(value) in ("<NA>", "nan") else str(value)
    return value
