"""Helpers of ``sicomat bode``, ``margins`` and ``tune``: payloads and writing tuned models."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["bode_payload", "margins_payload", "write_tuned"]


def bode_payload(frf, margins) -> dict[str, Any]:
    """The ``sicomat bode --json`` object: the response and, for an open loop, its margins."""
    out = {"loop": frf.name, **frf.to_dict(), "info": frf.info}
    if margins is not None:
        out["margins"] = margins.to_dict()
    return out


def margins_payload(velocity, position) -> dict[str, Any]:
    """The ``sicomat margins --json`` object: both loops' margins (worst over all crossovers)."""
    return {"velocity": velocity.to_dict(), "position": position.to_dict()}


def write_tuned(machine, axis: str, gains: dict[str, float], notch: dict[str, float] | None, path: Path) -> Path:
    """Save a copy of the model with the tuned gains (in the units the file used) and the notch."""
    from ..modelfile import save_model
    from ..servo_spec import FilterSpec

    spec = machine.axes[axis]
    ctrl = spec.controller
    update: dict[str, Any] = {"Ti": gains["Ti"], "Kv": gains["Kv"]}
    if ctrl.Kp_normalized is not None:
        update["Kp_normalized"] = gains["Kp_normalized"]
    else:
        update["Kp"] = gains["Kp"]
    if notch is not None:
        update["current_filters"] = [*ctrl.current_filters,
                                     FilterSpec(type="notch", frequency=notch["frequency_hz"], width=notch["width"],
                                                depth=notch["depth"])]
    axis_spec = spec.model_copy(update={"controller": ctrl.model_copy(update=update)})
    tuned = machine.model_copy(update={"axes": {**machine.axes, axis: axis_spec}})
    from ..modelfile import dump_data, machine_from_dict

    machine_from_dict(dump_data(tuned), source=str(path))  # validate what is written
    return save_model(tuned, path)
