"""Helpers of ``sicomat bode``, ``margins`` and ``tune``: payloads and writing tuned models."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["bode_payload", "margins_payload", "write_tuned", "tuned_machine", "response_verdict", "verdict_subject"]


def bode_payload(frf, margins) -> dict[str, Any]:
    """The ``sicomat bode --json`` object: the response and, for an open loop, its margins."""
    out = {"loop": frf.name, **frf.to_dict(), "info": frf.info}
    if margins is not None:
        out["margins"] = margins.to_dict()
    return out


def _judged_loops(which: str) -> tuple[str, ...]:
    """The closed loops a transfer depends on: none for the plant, the velocity loop for its own
    transfers, the whole cascade for the others."""
    if which == "plant":
        return ()
    return ("velocity",) if which.startswith("velocity") else ("velocity", "position")


def verdict_subject(which: str) -> str:
    """What the verdict of ``bode --loop which`` is about, for the table."""
    return {(): "plant", ("velocity",): "velocity loop"}.get(_judged_loops(which), "position loop")


def response_verdict(servo, an, which: str, margins):
    """The verdict of ``bode --loop which``: the poles of the closed loops the transfer depends on
    (unknown, None, for the plant alone) and, for an open loop, what its margins say."""
    from ..frequency.margins import margins_warnings
    from ..servo.stability import Verdict, loop_verdict

    loops = _judged_loops(which)
    if not loops:
        return Verdict(None)
    verdict = loop_verdict(servo, an=an, loops=loops)
    if margins is not None:
        name = "velocity" if which.startswith("velocity") else "position"
        verdict = verdict.with_warnings(margins_warnings(
            margins, name, verdict.loops.get(name, verdict.stable),
            open_loop_unstable=name == "position" and verdict.loops.get("velocity") is False))
    return verdict


def margins_payload(servo, an, velocity, position) -> dict[str, Any]:
    """The ``sicomat margins --json`` object: both loops' margins (worst over all crossovers), each
    with its ``stable`` verdict (the closed loop's poles) beside the deprecated ``stable_hint``, and
    the verdict of the whole cascade with the warnings."""
    from ..frequency.margins import margins_warnings
    from ..servo.stability import loop_verdict

    verdict = loop_verdict(servo, an=an)
    warnings = []
    out: dict[str, Any] = {}
    for name, margins in (("velocity", velocity), ("position", position)):
        stable = verdict.loops.get(name)
        out[name] = {**margins.to_dict(), "stable": stable}
        warnings += margins_warnings(margins, name, stable,
                                     open_loop_unstable=name == "position" and verdict.loops.get("velocity") is False)
    return {**out, **verdict.with_warnings(warnings).to_dict()}


def write_tuned(machine, axis: str, gains: dict[str, float], notch: dict[str, float] | None, path: Path,
                based_on: Path | None = None, method: str = "frequency") -> Path:
    """Save a copy of the model with the tuned gains and the notch.

    With ``based_on`` (the model file that was tuned) the copy is that file's text with only the
    tuned keys changed: comments and units kept, a tuned value in the unit its line used and
    marked ``# was <old value>`` (``docs/outputs.md``).
    """
    from ..io.modelfile import dump_data, machine_from_dict, save_model

    tuned = tuned_machine(machine, axis, gains, notch)
    machine_from_dict(dump_data(tuned), source=str(path))  # validate what is written
    header = None
    if based_on is not None:
        header = (f"Tuned by `sicomat tune --method {method}` from {based_on}, axis {axis}"
                  + (", with a notch filter added" if notch is not None else "")
                  + ".\nThe changed values are marked '# was'; everything else is the original's text.")
    return save_model(tuned, path, based_on=based_on, header=header)


def tuned_machine(machine, axis: str, gains: dict[str, float], notch: dict[str, float] | None = None):
    """``machine`` with ``axis``'s controller given the tuned ``gains`` (``Kp`` or ``Kp_normalized`` as the
    model gives it, ``Ti``, ``Kv``) and, when given, the ``notch`` appended to its current filters."""
    from ..description.servo import FilterSpec

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
    return machine.model_copy(update={"axes": {**machine.axes, axis: axis_spec}})
