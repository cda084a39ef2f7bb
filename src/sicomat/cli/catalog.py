"""``sicomat catalog list`` and ``sicomat catalog show``: browse the component catalogue."""

from __future__ import annotations

from pathlib import Path
from typing import Any, List, Optional

import typer

from ._common import JsonOption, OneLineErrors, emit_json, guarded

__all__ = ["catalog_app"]

catalog_app = typer.Typer(no_args_is_help=True, cls=OneLineErrors,
                          help="Browse the component catalogue (shipped parts, $SICOMAT_CATALOG and --catalog DIR).")

CatalogOption = typer.Option(None, "--catalog", metavar="DIR", file_okay=False,
                             help="A folder of your own catalogue files (extends and shadows the shipped ones by "
                                  "id; after $SICOMAT_CATALOG). Repeatable.")


def _catalogue(folders: Optional[List[Path]]):
    from ..catalogue.resolve import default_catalogue

    return default_catalogue(folders or [])   # sicomat --catalog A catalog list --catalog B


@catalog_app.command("list")
def list_(kind: Optional[str] = typer.Argument(None, help="Only this kind (motor, ball-screw, ...)."),
          where: Optional[List[str]] = typer.Option(None, "--where", metavar="EXPR",
                                                    help="Keep entries with PARAMETER OP VALUE, units allowed "
                                                         "(e.g. --where 'peak_torque >= 10 N*m'). Repeatable."),
          catalog: Optional[List[Path]] = CatalogOption, json_: bool = JsonOption) -> None:
    """List the catalogue's entries, optionally of one kind and filtered by their parameters."""
    with guarded():
        entries = _catalogue(catalog).select(kind, where or [])
        items = [{"id": e.id, "kind": e.kind, "description": e.description, "source": e.provenance.source,
                  "parameters": e.parameter_values()} for e in entries]
        if json_:
            emit_json({"items": items})
        else:
            _print_list(items)


@catalog_app.command("show")
def show(id: str = typer.Argument(..., metavar="ID", help="Catalogue id (see 'sicomat catalog list')."),
         catalog: Optional[List[Path]] = CatalogOption, json_: bool = JsonOption) -> None:
    """Show one entry: its parameters (SI units) and where its values come from."""
    with guarded():
        entry = _catalogue(catalog).get(id)
        payload = entry.to_dict()
        if json_:
            emit_json(payload)
        else:
            _print_show(payload)


def _print_list(items: list[dict[str, Any]]) -> None:
    from rich.console import Console
    from rich.table import Table

    from .layout import print_table

    table = Table(title=f"{len(items)} catalogue entr{'y' if len(items) == 1 else 'ies'}")
    for column in ("id", "kind", "source", "description"):
        table.add_column(column)
    for item in items:
        table.add_row(item["id"], item["kind"], item["source"], item["description"])
    print_table(Console(), table)


def _print_show(payload: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    from ..description.parts import unit_of
    from .layout import print_table

    table = Table(title=f"{payload['id']} ({payload['kind']}): {payload['description']}")
    table.add_column("parameter")
    table.add_column("value (SI)", justify="right")
    table.add_column("unit")
    for name, value in payload["parameters"].items():
        unit = unit_of(payload["kind"], name)
        table.add_row(name, f"{value:.6g}" if isinstance(value, float) else str(value), unit.si if unit else "")
    console = Console()
    print_table(console, table)
    provenance = payload["provenance"]
    console.print("provenance: " + "; ".join(f"{k} = {v}" for k, v in provenance.items()), markup=False,
                  highlight=False)
    console.print(f"file: {payload['source']}", markup=False, highlight=False)
