"""``sicomat robot``: the models of a machine described by the robotics formalism (a ``[robot]`` section)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ._common import JsonOption, SetOption, emit_json, guarded, load

__all__ = ["robot"]


def robot(model: Path = typer.Argument(..., help="Model file (TOML) with a [robot] section.", dir_okay=False),
          set_: Optional[List[str]] = SetOption,
          base_parameters: bool = typer.Option(False, "--base-parameters",
                                               help="The base inertial parameters (numerical method): count, "
                                                    "names (R where regrouped), regrouping relations, values."),
          inertial_only: bool = typer.Option(False, "--inertial-only",
                                             help="With --base-parameters: XX..M only (without IA, FV, FS)."),
          inverse_dynamics: bool = typer.Option(False, "--inverse-dynamics",
                                                help="Joint torques/forces by Newton-Euler at --q, --qd, --qdd."),
          q: Optional[str] = typer.Option(None, "--q", metavar="Q1,Q2,..",
                                          help="Joint positions, every joint in frame order (m or rad, or with "
                                               "units: 150mm,30deg)."),
          qd: Optional[str] = typer.Option(None, "--qd", metavar="QD1,..", help="Joint velocities (default 0)."),
          qdd: Optional[str] = typer.Option(None, "--qdd", metavar="QDD1,..",
                                            help="Joint accelerations (default 0)."),
          export_symbolic: Optional[Path] = typer.Option(None, "--export-symbolic", metavar="DIR", file_okay=False,
                                                         help="Write the symbolic models (Python, C, text) into "
                                                              "this folder."),
          json_: bool = JsonOption) -> None:
    """Models of a [robot] machine: base parameters, inverse dynamics, symbolic export."""
    with guarded(model):
        from ..errors import ModelError
        from ..tasks.robot import base_parameters_payload, inverse_dynamics_payload, robot_of

        chosen = [name for name, on in (("--base-parameters", base_parameters), ("--inverse-dynamics", inverse_dynamics),
                                        ("--export-symbolic", export_symbolic is not None)) if on]
        if len(chosen) != 1:
            raise ModelError("give one of --base-parameters, --inverse-dynamics, --export-symbolic",
                             source="options", value=" ".join(chosen) or None)
        if not inverse_dynamics and any(v is not None for v in (q, qd, qdd)):
            raise ModelError("--q, --qd and --qdd go with --inverse-dynamics", source="options")
        machine = load(model, set_)
        spec = robot_of(machine)
        if base_parameters:
            payload = base_parameters_payload(machine, inertial_only=inertial_only)
        elif inverse_dynamics:
            if q is None:
                raise ModelError("--inverse-dynamics needs --q (every joint in frame order: "
                                 f"{', '.join(spec.joint_names)})", source="--q")
            zeros = ",".join("0" for _ in spec.joint_names)
            payload = inverse_dynamics_payload(machine, q, qd if qd is not None else zeros,
                                               qdd if qdd is not None else zeros)
        else:
            from ..tasks.robot import export_symbolic_models

            assert export_symbolic is not None
            payload = export_symbolic_models(machine, export_symbolic, name=model.stem)
        if json_:
            emit_json(payload)
        else:
            _print(payload)


def _print(payload: dict) -> None:
    if "tau" in payload:
        for name, tau, unit in zip(payload["joints"], payload["tau"], payload["units"]):
            typer.echo(f"{name:>12}  {tau: .9g} {unit}")
    elif "count" in payload:
        typer.echo(f"{payload['count']} base parameters: {' '.join(payload['names'])}")
        for relation in payload.get("relations", []):
            left, _, right = relation.partition(" = ")
            if left != right:                       # only the regrouped ones: the others keep their value
                typer.echo(f"  {relation}")
    else:
        for path in payload.get("written", []):
            typer.echo(f"wrote {path}")
