"""Entry point of the ``sicomat`` program; each command delegates to the library."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ._common import AxisOption, JsonOption, PlotOption, SetOption, emit_json, guarded, load

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="SICOMAT: simulation and control analysis of machine-tool feed axes.")

ModelArgument = typer.Argument(..., help="Model file (TOML).", dir_okay=False)


@app.command()
def check(model: Path = ModelArgument, set_: Optional[List[str]] = SetOption,
          json_: bool = JsonOption) -> None:
    """Validate a model file and summarise its axes, dofs and couplings."""
    with guarded(model):
        from ..mechanics import build_mechanics
        from .tables import check_payload, print_check

        machine = load(model, set_)
        mechanics = {name: build_mechanics(axis.mechanics) for name, axis in machine.axes.items()}
        payload = check_payload(machine, mechanics)
        if json_:
            emit_json(payload)
        else:
            print_check(str(model), payload)


@app.command()
def modal(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
          set_: Optional[List[str]] = SetOption, json_: bool = JsonOption,
          plot: Optional[Path] = PlotOption) -> None:
    """Natural frequencies, damping ratios and mode shapes of an axis's mechanics."""
    with guarded(model):
        from ..mechanics import build_mechanics
        from ..modal import modal_analysis

        machine = load(model, set_)
        name = machine.axis_name(axis)
        result = modal_analysis(build_mechanics(machine.axes[name].mechanics))
        if plot is not None:
            from ..plotting import save_figure

            save_figure(result.plot(), plot)
        if json_:
            emit_json({"axis": name, **result.to_dict()})
        else:
            from .tables import print_modal

            print_modal(name, result)


def main() -> None:
    """Run the ``sicomat`` program."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
