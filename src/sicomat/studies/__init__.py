"""Parameter studies: variants of a machine model run at scale on Dask (``docs/studies.md``)::

    from sicomat.studies import Study
    results = Study("examples/studies/ballscrew_design.toml").run()   # checked against its base model, then run
    results.to_pandas(); results.pareto(); results.plot("pareto")

A study is a base model, parameters varied by the key paths of ``--set`` (grids, distributions, catalogue
lists), the analyses run on every variant and optional constraints and Pareto objectives. :class:`Study`
checks all of it against the base model when it is made (nothing is computed before); :meth:`Study.run`
computes the variants in chunks on a Dask cluster (an embedded ``LocalCluster`` unless given a client or a
scheduler's address), writing each chunk as it finishes, and returns :class:`StudyResults`.
"""

from __future__ import annotations

import time
from pathlib import Path
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from .results import StudyResults
from .spec import StudySpec, load_study, study_from_dict

if TYPE_CHECKING:  # pragma: no cover
    from ..progress import ProgressCallback
    from .variants import StudyPlan

__all__ = ["Study", "StudyResults", "StudySpec", "load_study", "default_out"]


def default_out(study_path: Path) -> Path:
    """Where a study's results go by default: ``<study name>.results/`` beside the study file."""
    return study_path.parent / f"{study_path.stem}.results"


class Study:
    """A study file checked against its base model, ready to run.

    Parameters
    ----------
    path : path-like
        The study file (TOML; its ``base`` is relative to the file's folder).
    out : path-like, optional
        The folder that receives the table, the chunks and the figures (default :func:`default_out`).

    Raises
    ------
    ModelError
        The study file or its base model is wrong (the file and key named); nothing has been computed.
    """

    def __init__(self, path: str | Path, out: str | Path | None = None) -> None:
        from .variants import plan_study

        self.path: Path | None = Path(path)
        spec, base = load_study(self.path)
        self.plan: "StudyPlan" = plan_study(spec, base, str(self.path))
        self.out = Path(out) if out is not None else default_out(self.path)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, folder: str | Path = ".", out: str | Path | None = None) -> "Study":
        """A study from the data of a study file (a mapping with the same keys, as ``tomllib`` would read it),
        without writing the file: ``base`` is relative to ``folder``; the results go to ``out`` (default
        ``<folder>/<name, else "study">.results``). Checked as a file is; a refusal names ``<study data>``.

        >>> Study.from_dict({"base": "paper_5m4s.toml", "analyses": ["modal"], "parameters": [
        ...     {"path": "axes.X.mechanics.bodies.load.mass", "values": ["200 kg", "300 kg"]}]},
        ...     folder="examples").variants
        2
        """
        from .variants import plan_study

        source = "<study data>"
        spec = study_from_dict(dict(data), source)
        study = cls.__new__(cls)
        study.path = None
        study.plan = plan_study(spec, Path(folder) / spec.base, source)
        study.out = Path(out) if out is not None else Path(folder) / f"{spec.name or 'study'}.results"
        return study

    @property
    def variants(self) -> int:
        """The number of variants."""
        return self.plan.variants

    def settings(self, variant: int) -> list[str]:
        """``variant``'s ``--set`` overrides of the base model (``sicomat <command> BASE --set ...``)."""
        return self.plan.settings(variant)

    def run(self, client: Any = None, *, scheduler: str | None = None, workers: int | None = None,
            resume: bool = False, csv: bool | None = None, figures: bool = False,
            progress: "ProgressCallback | None" = None) -> StudyResults:
        """Compute the variants (only the missing chunks with ``resume``) and write the table.

        ``client``: a ``distributed.Client`` (kept open); ``scheduler``: a scheduler's address; else an
        embedded local cluster of ``workers`` processes (default one per core). ``csv``: write the table as
        CSV instead of Parquet (default: the study's ``format``). ``figures``: also save the figures as PNG.
        """
        from ..io.atomic import atomic_write
        from .engine import run_plan

        from ..errors import ModelError

        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ModelError("expected a number of workers >= 1", path="workers", value=workers)
        if workers is not None and (client is not None or scheduler is not None):
            raise ModelError("workers sizes the embedded local cluster; a given client or scheduler has its own",
                             path="workers", value=workers)
        if client is not None and scheduler is not None:
            raise ModelError("give a client or a scheduler's address, not both", path="scheduler", value=scheduler)
        start = time.perf_counter()
        as_csv = csv if csv is not None else self.plan.spec.format == "csv"
        path = self.out / ("results.csv" if as_csv else "results.parquet")
        self._check_outputs(path, figures)
        engine = run_plan(self.plan, self.out, client=client, scheduler=scheduler, workers=workers, resume=resume,
                          progress=progress)
        table = engine.table
        table.attrs["units"] = self.plan.units()
        if as_csv:
            atomic_write(path, lambda tmp: table.to_csv(tmp, index=False), kind="csv")
        else:
            atomic_write(path, lambda tmp: table.to_parquet(tmp, index=False), kind="parquet")
        info = {"chunks": {"total": engine.chunks, "computed": engine.computed, "reused": engine.reused},
                "workers": engine.workers, "scheduler": engine.scheduler, "compute_time": engine.compute_s,
                "out": str(self.out)}
        results = StudyResults(table, self.plan, time.perf_counter() - start, path, info)
        if figures:
            written = results.write_figures(self.out)
            info["figures"] = [str(p) for p in written]
        return results

    def _check_outputs(self, table: Path, figures: bool) -> None:
        """Before any work: the output folder made, and every file the run will write there allowed by the
        output policy (``docs/outputs.md``: a regular file or a new name, never the study or its base model)."""
        from ..io.atomic import check_output
        from .engine import make_folders
        from .results import FIGURES

        make_folders(self.out)
        inputs: dict[str, Path | None] = {"the study file": self.path, "the base model": self.plan.base_path}
        check_output(table, "parquet" if table.suffix == ".parquet" else "csv", inputs=inputs)
        check_output(self.out / "manifest.json", "json", inputs=inputs)
        for kind in FIGURES if figures else ():
            check_output(self.out / f"{kind}.png", "figure", inputs=inputs)
