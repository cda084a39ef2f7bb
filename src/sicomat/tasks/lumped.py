"""The drive-chain builder's verbs (issue 12, §3 and §6): what a ``components`` axis lowers to (``sicomat
check --lumped``), its plain ``type = "lumped"`` equivalent (``check --write-lumped``), and saving a validated
model with its overrides applied (``check --write``). ``docs/components.md``, "The drive-chain builder"."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine

__all__ = ["drive_chain_payload", "lumped_machine", "write_lumped", "write_checked"]

def drive_chain_payload(machine: "Machine", axis: str) -> dict[str, Any]:
    """What ``axis``'s mechanics is built from, for ``check --lumped`` (SI values).

    A ``components`` axis: ``{"derived": true, "position", "stroke", "detail", "bodies", "springs",
    "frictions", "sensors", "actuator", "notes"}`` (:meth:`~sicomat.description.chain.ChainModel.to_dict`)
    and ``"drive_from_motor"``: the drive's constants the motor implies
    (:func:`~sicomat.description.components.drive_defaults`), ``"drive"``: the value of each of them the
    axis's drive uses (``null`` without a drive table), ``"drive_overrides"``: the keys where the
    drive's value is not the motor's (the file's drive key wins), ``"datasheet_warnings"``: the motor's
    values that disagree beyond half the datasheet tolerance (but within it). Another mechanics type:
    ``{"derived": false, "mechanics_type", "note"}``: it is already lumped.
    """
    from ..description.components import ComponentsSpec, drive_defaults

    spec = machine.axes[axis]
    mech = spec.mechanics
    if not isinstance(mech, ComponentsSpec):
        kind = mech.type if mech is not None else "robot"
        return {"derived": False, "mechanics_type": kind,
                "note": f"mechanics type {kind!r} is not a drive chain: it is already lumped (its bodies "
                        "and couplings are the ones listed above)"}
    implied = drive_defaults(mech)
    drive = spec.drive
    used = None if drive is None else {k: getattr(drive, k) for k in implied}
    overrides = [] if used is None else [k for k, v in implied.items() if used[k] != v]
    return {"derived": True, **mech.chain.to_dict(), "drive_from_motor": implied, "drive": used,
            "drive_overrides": overrides, "datasheet_warnings": mech.warnings}


def lumped_machine(machine: "Machine") -> "Machine":
    """``machine`` with each ``components`` axis's mechanics replaced by the ``LumpedSpec`` it lowers to;
    the drive (with the constants it took from the motor), controller, trajectory and tool unchanged."""
    from ..description.components import ComponentsSpec
    from ..io.modelfile import dump_data, machine_from_dict

    axes = {}
    for name, axis in machine.axes.items():
        mech = axis.mechanics
        axes[name] = axis.model_copy(update={"mechanics": mech.to_lumped()}) if isinstance(mech, ComponentsSpec) \
            else axis
    lumped = machine.model_copy(update={"axes": axes})
    return machine_from_dict(dump_data(lumped), source="the lumped equivalent")   # validated as a file


def write_lumped(machine: "Machine", path: "str | os.PathLike", based_on: "str | os.PathLike | None" = None) -> Path:
    """Write :func:`lumped_machine` of ``machine`` (``check --write-lumped``) through
    :func:`~sicomat.io.modelfile.save_model`: with ``based_on`` the other blocks keep their text, the
    drive-chain axes' mechanics tables are replaced by plain SI bodies and couplings, and the drive's
    constants that came from the motor are written out (the lumped file has no motor to take them from)."""
    from ..description.components import ComponentsSpec
    from ..io.modelfile import save_model

    chains = {name: axis.mechanics for name, axis in machine.axes.items() if isinstance(axis.mechanics, ComponentsSpec)}
    lines = ["Written by `sicomat check --write-lumped`" + (f" from {based_on}" if based_on is not None else "")
             + ":", "each drive-chain axis (type = \"components\") replaced by its lumped bodies and couplings;"]
    for name, mech in chains.items():
        chain = mech.chain
        lines.append(f"axis {name}: detail {chain.detail!r}, position {chain.position:.6g} m"
                     + (f" of a {chain.stroke:.6g} m stroke" if chain.stroke is not None else "")
                     + "; the drive's constants taken from the motor are written out.")
    if not chains:
        lines.append("(no axis is a drive chain: the model is written as it is)")
    return save_model(lumped_machine(machine), path, based_on=based_on, header="\n".join(lines))


def write_checked(machine: "Machine", path: "str | os.PathLike", based_on: "str | os.PathLike | None" = None,
                  overrides: "list[str] | None" = None) -> Path:
    """Save the validated ``machine`` (``check --write``): with ``based_on`` the file's text with the
    ``--set`` overrides written in (comments and units kept, changed values marked ``# was``); catalogue
    parts record their ids and values (``recorded = true``), so the file loads unchanged when the
    catalogue changes."""
    from ..description.components import ComponentsSpec
    from ..io.modelfile import save_model

    catalogued = any(part.id for axis in machine.axes.values() if isinstance(axis.mechanics, ComponentsSpec)
                     for part in axis.mechanics.parts)
    header = ("Written by `sicomat check --write`" + (f" from {based_on}" if based_on is not None else "")
              + ": the validated model"
              + (" with " + " ".join(f"--set {item}" for item in overrides) + " applied" if overrides else "")
              + "." + ("\nCatalogue parts record their values at save time (recorded = true)." if catalogued else ""))
    return save_model(machine, path, based_on=based_on, header=header)
