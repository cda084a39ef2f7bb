"""Shared plumbing of the CLI commands: options, model loading, error reporting, JSON output."""

from __future__ import annotations

import json
import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, List, Optional

import typer
import typer.core

__all__ = ["SetOption", "JsonOption", "AxisOption", "PlotOption", "guarded", "emit_json", "load", "number",
           "OneLineErrors", "EXIT_UNSTABLE", "exit_for", "OPTIONS", "magnification_option"]

OPTIONS = {
    "order": "--order", "keep": "--keep", "band": "--band", "method": "--method", "inputs": "--inputs",
    "outputs": "--outputs", "which": "--loop", "velocity_crossover": "--velocity-crossover",
    "velocity_phase_margin": "--velocity-phase-margin", "position_crossover": "--position-crossover",
    "position_phase_margin": "--position-phase-margin", "radius": "--radius", "feed": "--feed",
    "feed_mm_min": "--feed", "feedforward": "--feedforward", "step_mm": "--step", "move_mm": "--move",
    "q": "--q", "qd": "--qd", "qdd": "--qdd", "model": "--model",
    "joint": "--joint", "points": "--points", "modes": "--modes",
    "scheduler": "--scheduler", "workers": "--workers", "out": "--out", "resume": "--resume",
}
"""The library's parameter (``ModelError.path`` of an error raised without a ``source``) -> the option
that gives it: the core and ``tasks/`` name parameters, never options; :func:`guarded` locates their
errors at the option, so that the message names what the user typed."""

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


def number(*, gt: float | None = None, ge: float | None = None, lt: float | None = None,
           le: float | None = None, nonzero: bool = False, unit: str = ""):
    """A Typer ``callback`` for a numeric option: the value must be finite and within its sense.

    Used in the option's declaration (``typer.Option(None, "--move", callback=number(nonzero=True))``)
    so that every float option of every command is checked the same way, before any work: a bad
    value is one line naming the option, its value and what was expected, and exit status 2.

    Examples
    --------
    >>> check = number(gt=0, unit="dB")
    >>> check.bounds
    '> 0 dB'
    """
    words = [f"{op} {bound:g}" for op, bound in ((">", gt), (">=", ge), ("<", lt), ("<=", le)) if bound is not None]
    bounds = " and ".join(words) + (f" {unit}" if unit and words else "")

    def check(ctx: typer.Context, param: typer.CallbackParam, value: Any) -> Any:
        if value is None or ctx.resilient_parsing:
            return value
        option = param.opts[0] if param.opts else str(param.name)
        if not math.isfinite(value):
            problem = "expected a finite number" + (f" {bounds}" if bounds else "")
        elif value != 0 and not 1e-100 <= abs(value) <= 1e100:   # as sicomat.description.units.MAGNITUDES
            problem = "expected a magnitude from 1e-100 to 1e100 (products of three values must stay finite)"
        elif (gt is not None and not value > gt) or (ge is not None and not value >= ge) or \
                (lt is not None and not value < lt) or (le is not None and not value <= le):
            problem = f"expected a value {bounds}"
        elif nonzero and value == 0:
            problem = "expected a non-zero value"
        else:
            return value
        from ..errors import ModelError

        _fail(str(ModelError(problem, source=option, value=value)))

    check.bounds = bounds  # type: ignore[attr-defined]
    return check


def magnification_option(ctx: typer.Context, param: typer.CallbackParam, value: Any) -> Any:
    """The ``callback`` of ``simulate --magnification``: a finite factor > 0 (or absent: automatic)."""
    if value is not None and not ctx.resilient_parsing and not 0.0 < value < float("inf"):
        from ..errors import ModelError

        _fail(str(ModelError("expected a finite factor > 0 (or leave it out: automatic)", source="--magnification",
                             value=value)))
    return value


class OneLineErrors(typer.core.TyperGroup):
    """The program's command group: a usage error (unknown option, a value that is not a number, a
    missing argument) is one line on stderr and exit status 2, like every other bad input, instead of
    click's usage block."""

    def invoke(self, ctx: Any) -> Any:          # a command's options and arguments
        with _one_line_usage_errors(lambda: ctx.command_path):
            return super().invoke(ctx)

    def make_context(self, info_name: Any, args: Any, parent: Any = None, **extra: Any) -> Any:
        with _one_line_usage_errors(lambda: str(info_name)):   # the program's own options
            return super().make_context(info_name, args, parent=parent, **extra)


@contextmanager
def _one_line_usage_errors(command_path) -> Iterator[None]:
    try:   # recent Typer carries its own copy of click
        from typer._click import exceptions as click
    except ImportError:  # pragma: no cover - older Typer depends on click itself (not installed with new Typer)
        from click import exceptions as click  # type: ignore[no-redef, import-not-found, unused-ignore]

    try:
        yield
    except click.NoArgsIsHelpError:
        raise
    except click.UsageError as exc:
        where = exc.ctx.command_path if exc.ctx is not None else command_path()
        _fail(" ".join(exc.format_message().split()) + f" (see '{where} --help')")


@contextmanager
def guarded(source: Path | None = None) -> Iterator[None]:
    """Turn SICOMAT errors (and output-file errors) into one line on stderr and exit status 2.

    A model error raised without a location (e.g. an unknown ``--axis``) is located in ``source``.
    """
    from ..errors import ModelError, SicomatError

    try:
        yield
    except ModelError as exc:
        if exc.source is None and exc.path in OPTIONS:
            exc = ModelError(exc.message, source=OPTIONS[exc.path], value=exc.value, has_value=exc.has_value)
        _fail(str(exc.with_source(str(source)) if exc.source is None and source is not None else exc))
    except SicomatError as exc:
        _fail(str(exc))
    except OverflowError as exc:  # a finite input whose consequences overflow double precision
        _fail(f"a value is too large to compute with in double precision ({exc})")
    except MemoryError:  # past the estimates of sicomat.budget, e.g. with SICOMAT_MAX_MEMORY raised
        _fail("out of memory: this machine cannot hold the work; lower SICOMAT_MAX_MEMORY (bytes, or e.g. "
              "'8 GiB') below what it has so that SICOMAT refuses such work before starting it")
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
    from ..io.modelfile import load_model

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

# the move limits and the G-code feed, shared by simulate and size
MaxVelocityOption = typer.Option(None, "--max-velocity", metavar="M_S", callback=number(gt=0, unit="m/s"),
                                 help="Velocity limit of --move (m/s).")
MaxAccelerationOption = typer.Option(None, "--max-acceleration", metavar="M_S2",
                                     callback=number(gt=0, unit="m/s^2"), help="Acceleration limit of --move (m/s^2).")
FeedOption = typer.Option(None, "--feed", metavar="MM_PER_MIN", callback=number(gt=0, unit="mm/min"),
                          help="Override the G-code feed rate (mm/min).")
