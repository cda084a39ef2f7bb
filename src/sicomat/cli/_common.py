"""Shared plumbing of the CLI commands: options, model loading, error reporting, JSON output."""

from __future__ import annotations

import json
import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, List, Optional

import typer

__all__ = ["SetOption", "JsonOption", "AxisOption", "PlotOption", "guarded", "emit_json", "load", "EXIT_UNSTABLE",
           "exit_for"]

EXIT_UNSTABLE = 3
"""Exit status when the result is meaningless: the loop is unstable or its simulation diverged (the
payload is still printed, with ``"stable": false``); 2 is bad input; warnings alone keep 0."""

SetOption = typer.Option(
    None, "--set", metavar="KEY=VALUE",
    help="Override a model parameter by key path for this run, units allowed "
         "(e.g. --set axes.X.controller.Kv=30, --set 'axes.X.drive.bandwidth=1.2 kHz'). Repeatable.")
JsonOption = typer.Option(False, "--json", help="Print one JSON object on stdout instead of tables.")
AxisOption = typer.Option(None, "--axis", help="Axis name (default: the first axis of the model).")
PlotOption = typer.Option(None, "--plot", help="Write a figure to this file (.png, .svg or .pdf).",
                          dir_okay=False)


@contextmanager
def guarded(source: Path | None = None) -> Iterator[None]:
    """Turn SICOMAT errors (and output-file errors) into one line on stderr and exit status 2.

    A model error raised without a location (e.g. an unknown ``--axis``) is located in ``source``.
    """
    from ..errors import ModelError, SicomatError

    try:
        yield
    except ModelError as exc:
        _fail(str(exc.with_source(str(source)) if exc.source is None and source is not None else exc))
    except SicomatError as exc:
        _fail(str(exc))
    except OSError as exc:  # e.g. writing a plot into a folder that does not exist
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        _fail(f"{where}{exc.strerror or exc}")


def _fail(message: str) -> None:
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(f"error: {message}", markup=False)
    raise typer.Exit(code=2)


def exit_for(payload: dict[str, Any]) -> None:
    """End the command with :data:`EXIT_UNSTABLE` when its payload says ``"stable": false``."""
    if payload.get("stable") is False:
        raise typer.Exit(code=EXIT_UNSTABLE)


def load(model: Path, overrides: Optional[List[str]]):
    """Load a model file with its ``--set`` overrides."""
    from ..modelfile import load_model

    return load_model(model, overrides or [])


def emit_json(payload: dict[str, Any]) -> None:
    """Write one JSON object to stdout; a non-finite number (an unstable loop's overshoot, a
    missing margin) is written as ``null``: JSON has no infinity. Keys follow the unit rule of
    :mod:`.jsonkeys` (the SI name beside every deprecated SI-suffixed key)."""
    from .jsonkeys import with_si_names

    sys.stdout.write(json.dumps(_finite(with_si_names(payload)), indent=2, allow_nan=False) + "\n")


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value
