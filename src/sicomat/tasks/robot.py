"""The verbs of a machine with a ``[robot]`` section (issue 13), shared by the CLI and the other front
ends: joint values read with units, base parameters, inverse dynamics, the modes at a configuration with
the motors locked. Parameters in, results or JSON payloads out; errors name the parameter."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..description.robot import configuration_units
from ..description.units import UNITS, parse_quantity
from ..errors import ModelError

if TYPE_CHECKING:
    from ..description.machine import Machine
    from ..description.robot import RobotSpec
    from ..mechanics.modal import ModalResult

__all__ = ["robot_of", "joint_values", "base_parameters_payload", "inverse_dynamics_payload", "locked_modes",
           "export_symbolic_models"]


def robot_of(machine: "Machine") -> "RobotSpec":
    """The machine's ``[robot]`` section, or a :class:`ModelError` saying it has none."""
    if machine.robot is None:
        raise ModelError("the model has no [robot] section (this needs a machine described by the robotics "
                         "formalism, docs/robotics.md)", path="robot")
    return machine.robot


def joint_values(spec: "RobotSpec", values: str | Sequence[Any], what: str) -> np.ndarray:
    """Every joint's value in frame order, from ``"v1,v2,..."`` or a sequence; each a number (SI: m or rad,
    m/s or rad/s, ...) or a quantity with units (``"150 mm"``, ``"30 deg"``). ``what`` is ``q``, ``qd`` or
    ``qdd`` (its unit follows the joint's type) and names the parameter in errors."""
    items = [v.strip() for v in values.split(",")] if isinstance(values, str) else list(values)
    names = spec.joint_names
    if len(items) != len(names):
        raise ModelError(f"expected {len(names)} values, one per joint in frame order ({', '.join(names)}), "
                         f"got {len(items)}", path=what, value=values if isinstance(values, str) else list(values))
    suffix = {"q": "", "qd": "_rate", "qdd": "_acceleration"}[what]
    out = np.empty(len(names))
    for i, (item, base) in enumerate(zip(items, configuration_units(spec))):
        unit = UNITS[base] if not suffix else _rate_unit(base, suffix)
        try:
            out[i] = float(item) if isinstance(item, str) and _is_number(item) else parse_quantity(item, unit)
        except ValueError as exc:
            raise ModelError(f"joint {names[i]}: {exc}", path=what, value=item) from None
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _rate_unit(base: str, suffix: str):
    from ..description.units import Unit

    if base == "length":
        return UNITS["velocity"] if suffix == "_rate" else UNITS["acceleration"]
    return Unit("rad/s", "an angular velocity (rad/s)") if suffix == "_rate" else \
        Unit("rad/s**2", "an angular acceleration (rad/s^2)")


def base_parameters_payload(machine: "Machine", *, inertial_only: bool = False) -> dict[str, Any]:
    """``sicomat robot --base-parameters``: count, names (with ``R`` where regrouped), relations, values."""
    from ..robotics.lowering import robot_model

    base = robot_model(robot_of(machine)).base_parameters(parameters="inertial" if inertial_only else "all")
    return {"name": machine.name, **base.to_dict()}


def inverse_dynamics_payload(machine: "Machine", q: Any, qd: Any, qdd: Any) -> dict[str, Any]:
    """``sicomat robot --inverse-dynamics``: the joint torques/forces (N or N·m) by Newton–Euler at
    ``(q, q̇, q̈)``, gravity and friction included."""
    from ..robotics.lowering import robot_model

    spec = robot_of(machine)
    values = {key: joint_values(spec, raw, key) for key, raw in (("q", q), ("qd", qd), ("qdd", qdd))}
    tau = robot_model(spec).inverse_dynamics(values["q"], values["qd"], values["qdd"])
    return {"joints": spec.joint_names, **{k: v.tolist() for k, v in values.items()}, "tau": tau.tolist(),
            "units": ["N" if u == "length" else "N*m" for u in configuration_units(spec)]}


def locked_modes(machine: "Machine", q: Any = None) -> tuple["ModalResult", dict[str, Any]]:
    """The modes of the robot at configuration ``q`` (default: the file's) with every motorised joint
    locked: the structure's own modes, those of its elastic joints. Returns the result and what it was
    computed at (``configuration`` by joint name, closed when the robot has loops; ``locked`` joints)."""
    from ..mechanics.conditioning import check_resolvable
    from ..mechanics.modal import modal_analysis
    from ..robotics.lowering import axis_free_joints, closed_configuration, robot_mechanics

    spec = robot_of(machine)
    q0 = closed_configuration(spec, None if q is None else joint_values(spec, q, "q"))
    free = axis_free_joints(spec, None)
    if not free:
        raise ModelError("the robot has no joint left once its motors are locked (no elastic joint): it has no "
                         "modes of its own; give --axis to see an axis's rigid model", path="robot.frames")
    mech = robot_mechanics(spec, q0, free=free, actuators=())
    check_resolvable(mech)
    return modal_analysis(mech), {"configuration": dict(zip(spec.joint_names, q0.tolist())),
                                  "locked": spec.motor_names}


def export_symbolic_models(machine: "Machine", directory: "str | os.PathLike[str]", *, name: str) -> dict[str, Any]:
    """``sicomat robot --export-symbolic DIR``: the symbolic models written into ``directory`` (made when
    its parent exists), every file checked against the output policy before the first is written, each
    written atomically. ``name`` (made a C identifier) prefixes the files and the C functions."""
    import re
    from pathlib import Path

    from ..errors import OutputError
    from ..io.atomic import atomic_write, check_output
    from ..robotics.lowering import robot_model
    from ..robotics.codegen import symbolic_export

    stem = re.sub(r"\W", "_", name) or "robot"
    stem = stem if not stem[0].isdigit() else f"robot_{stem}"
    texts = symbolic_export(robot_model(robot_of(machine)), name=stem)
    folder = Path(directory)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder}: --export-symbolic expects a folder; this is a file")
    if not folder.exists():
        if not folder.parent.is_dir():
            raise OutputError(f"{folder}: cannot be made: the folder '{folder.parent}' does not exist")
        folder.mkdir()
    for file_name in texts:
        check_output(folder / file_name)
    written = []
    for file_name, text in texts.items():
        atomic_write(folder / file_name, _text_writer(text))
        written.append(str(folder / file_name))
    return {"name": stem, "written": written}


def _text_writer(text: str):
    def write(path: str) -> None:
        with open(path, "w", encoding="utf-8") as out:
            out.write(text)
    return write
