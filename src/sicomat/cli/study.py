"""``sicomat study``: a parameter study of a model on Dask (``docs/studies.md``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer

from ._common import JsonOption, emit_json, guarded

__all__ = ["study"]

EXIT_INTERRUPTED = 130
"""Exit status of a study stopped by Ctrl-C (128 + SIGINT, the shell's convention); its finished chunks
are on disk and ``--resume`` computes the rest."""


def study(study_file: Path = typer.Argument(..., metavar="STUDY", help="Study file (TOML).", dir_okay=False),
          out: Optional[Path] = typer.Option(None, "--out", metavar="DIR", file_okay=False,
                                             help="Folder of the results (default: STUDY's name + .results, "
                                                  "beside it)."),
          workers: Optional[int] = typer.Option(None, "--workers", min=1, max=4096, metavar="N",
                                                help="Worker processes of the embedded local cluster "
                                                     "(default: one per core)."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT",
                                                  help="Run on an existing Dask cluster instead of a local one."),
          resume: bool = typer.Option(False, "--resume",
                                      help="Keep the chunks already in DIR and compute only the missing ones."),
          csv: bool = typer.Option(False, "--csv", help="Write the table as CSV instead of Parquet."),
          figures: bool = typer.Option(True, "--figures/--no-figures",
                                       help="Save the scatter matrix, parallel coordinates, histograms and "
                                            "Pareto front as PNG in DIR."),
          dry_run: bool = typer.Option(False, "--dry-run",
                                       help="Check the study and show its variants and metrics; compute nothing."),
          json_: bool = JsonOption) -> None:
    """Run a parameter study: variants of a model (grids, tolerance spreads, catalogue lists) analysed on
    Dask, one table of inputs and metrics, constraints and the Pareto front."""
    with guarded(study_file):
        from ..errors import ModelError
        from ..studies import Study

        if workers is not None and scheduler is not None:
            raise ModelError("--workers sizes the local cluster; an existing cluster (--scheduler) has its own",
                             source="--workers", value=workers)
        if scheduler is not None and not scheduler.strip():
            raise ModelError("expected a scheduler address such as tcp://10.0.0.5:8786", source="--scheduler",
                             value=scheduler)
        plan = Study(study_file, out=out)
        if dry_run:
            _dry_run(plan, json_)
            return
        from .progress import progress_bar

        try:
            with progress_bar() as progress:
                results = plan.run(scheduler=scheduler, workers=workers, resume=resume, csv=csv or None,
                                   figures=figures, progress=progress)
        except KeyboardInterrupt:
            from rich.console import Console

            done = len(list((plan.out / "chunks").glob("chunk-*.parquet")))
            Console(stderr=True, highlight=False, soft_wrap=True).print(
                f"interrupted: {done} chunks are in {plan.out / 'chunks'}; run the same command with --resume "
                "to compute the rest", markup=False)
            raise typer.Exit(code=EXIT_INTERRUPTED) from None
        payload = results.summary()
        if json_:
            emit_json(payload)
        else:
            _print(payload)


def _dry_run(plan: Any, json_: bool) -> None:
    from ..studies.analyses import UNITS
    from ..studies.engine import chunk_size_for

    p = plan.plan
    chunk = p.spec.chunk_size or chunk_size_for(p.variants)
    payload = {"variants": p.variants, "chunk_size": chunk, "chunks": -(-p.variants // chunk),
               "samples": p.samples, "grid": list(p.grid_shape), "out": str(plan.out),
               "parameters": [{"path": q.path, "way": p.spec.parameters[q.index].way, "levels": len(q.settings),
                               "first": str(q.settings[0]), "last": str(q.settings[-1])} for q in p.parameters],
               "metrics": list(p.metrics), "units": {m: UNITS[m] for m in p.metrics if m in UNITS},
               # as the study judges them: a bound written with a unit converted to its column's
               "constraints": [{"text": c.text, "metric": c.metric, "operator": c.operator, "bound": c.bound,
                                "unit": p.column_unit(c.metric) if isinstance(c.bound, float) else None}
                               for c in p.constraints],
               "first_variant": p.settings(0)}
    if json_:
        emit_json(payload)
        return
    from rich.console import Console

    console = Console(highlight=False, soft_wrap=True)
    console.print(f"{p.variants} variants ({' x '.join(map(str, p.grid_shape)) or '1'} grid"
                  f"{f' x {p.samples} draws' if p.samples > 1 else ''}), {payload['chunks']} chunks of "
                  f"{chunk}; results in {plan.out}", markup=False)
    for q in payload["parameters"]:
        console.print(f"  {q['path']}: {q['way']}, {q['levels']} values, {q['first']} ... {q['last']}", markup=False)
    console.print("metrics: " + ", ".join(p.metrics), markup=False)
    for c in payload["constraints"]:
        bound = f"{c['bound']:.6g}" if isinstance(c["bound"], float) else str(c["bound"]).lower()
        unit = f" {c['unit']}" if c["unit"] not in (None, "1") else ""
        console.print(f"constraint: {c['metric']} {c['operator']} {bound}{unit}"
                      f"   (written {c['text']!r})", markup=False)
    console.print("variant 0: --set " + " --set ".join(payload["first_variant"]), markup=False)


def _print(payload: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    from .layout import print_table

    console = Console(highlight=False, soft_wrap=True)
    chunks = payload["chunks"]
    where = f", on {payload['workers']} workers" if chunks["computed"] else ""
    console.print(f"{payload['variants']} variants: {payload['failed']} failed, {payload['constraints_met']} meet "
                  f"every constraint" + (f", {payload['diverged']} diverged" if payload.get("diverged") else "")
                  + f"; {chunks['computed']} chunks computed, {chunks['reused']} reused{where}, in "
                  f"{payload['elapsed_s']:.1f} s", markup=False)
    console.print(f"table: {payload['results']}", markup=False)
    for path in payload.get("figures", []):
        console.print(f"figure: {path}", markup=False)
    for error in payload["errors"]:
        console.print(f"variant {error['variant']} failed: {error['error']}", markup=False)
    pareto = payload["pareto"]
    if pareto and pareto["variants"]:
        names = list(pareto["variants"][0])
        table = Table(title="Pareto front (" + ", ".join(f"{s} {n}" for n, s in pareto["objectives"]) + ")")
        for name in names:
            table.add_column(name, justify="right")
        for row in pareto["variants"][:20]:
            table.add_row(*[f"{v:.6g}" if isinstance(v, float) else str(v) for v in row.values()])
        print_table(console, table)
        if len(pareto["variants"]) > 20:
            console.print(f"... {len(pareto['variants']) - 20} more on the front (--json lists them all)",
                          markup=False)
