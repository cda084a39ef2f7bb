"""What the loader fills in that a file did not write, and how a saved model records it (Save Model, issue
12 §6; ``docs/components.md``, "The drive-chain builder"): a catalogue part's entry values (written out,
with ``recorded = true``, so the file loads unchanged when the catalogue changes) and a drive-chain axis's
drive constants taken from its motor (left implied while the axis is a drive chain, written out when it
is no longer one: ``check --write-lumped``, ``reduce --write``). Used by
:func:`sicomat.io.modelfile.model_text`."""

from __future__ import annotations

from typing import Any, Mapping

from ..description.components import ComponentsSpec, drive_defaults
from ..description.machine import Machine

__all__ = ["recorded", "as_written", "implied_drive_left_out", "missing_because_of_chain"]


def recorded(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with ``recorded = true`` on each catalogue part: its values (all in ``data``) are the
    entry's at save time, and the loader no longer reads the entry (``docs/components.md``)."""
    for spec in (data.get("axes") or {}).values():
        mech = spec.get("mechanics") or {}
        if mech.get("type") != "components":
            continue
        mech["parts"] = [{"kind": p["kind"], "id": p["id"], "recorded": True,
                          **{k: v for k, v in p.items() if k not in ("kind", "id", "recorded")}}
                         if "id" in p else p for p in mech["parts"]]
    return data


def _motor_drive(machine: Machine, axis: str) -> dict[str, Any]:
    """The drive constants the axis's motor implies (none unless its mechanics is a drive chain)."""
    spec = machine.axes[axis].mechanics if axis in machine.axes else None
    return drive_defaults(spec) if isinstance(spec, ComponentsSpec) else {}


def _raw_drive(raw: Mapping[str, Any], axis: str) -> Mapping[str, Any]:
    spec = (raw.get("axes") or {}).get(axis)
    drive = spec.get("drive") if isinstance(spec, dict) else None
    return drive if isinstance(drive, dict) else {}


def as_written(old: dict[str, Any], raw: Mapping[str, Any], machine: Machine) -> dict[str, Any]:
    """``old`` (the dump of ``machine``, read from ``raw``) cut down to what the file wrote where the
    loader filled values in: each catalogue part to the keys its file wrote, so the entry's values are
    written into the saved file (Save Model records them, so it loads unchanged when the catalogue
    changes); a drive-chain axis's drive without the motor's constants the file did not write, so a
    saved file whose axis is no longer a drive chain (``check --write-lumped``, ``reduce --write``)
    writes them out."""
    for axis, spec in (raw.get("axes") or {}).items():
        parts = (spec.get("mechanics") or {}).get("parts") if isinstance(spec, dict) else None
        if isinstance(parts, list):
            dumped = old["axes"][axis]["mechanics"]["parts"]
            for i, part in enumerate(parts):
                if isinstance(part, dict) and "id" in part and i < len(dumped):
                    dumped[i] = {k: v for k, v in dumped[i].items() if k in part}
        if isinstance(spec, dict) and "tool" not in spec and axis in old["axes"]:
            old["axes"][axis].pop("tool", None)      # a drive chain's implied tool (its table): written out
        drive = old["axes"].get(axis, {}).get("drive")
        if isinstance(drive, dict):
            written = _raw_drive(raw, axis)
            for key in _motor_drive(machine, axis):
                if key not in written:
                    drive.pop(key, None)
    return old


def implied_drive_left_out(new: dict[str, Any], raw: Mapping[str, Any], machine: Machine) -> dict[str, Any]:
    """``new`` for the text edit: a drive-chain axis's drive without the motor's constants that the file
    did not write and the motor still implies (they stay implied: a part swapped later takes its own)."""
    out = dict(new)
    out["axes"] = dict(new.get("axes") or {})
    for axis, spec in out["axes"].items():
        drive, implied = spec.get("drive"), _motor_drive(machine, axis)
        if not (isinstance(drive, dict) and implied):
            continue
        written = _raw_drive(raw, axis)
        out["axes"][axis] = {**spec, "drive": {k: v for k, v in drive.items()
                                               if k in written or k not in implied or implied[k] != v}}
    return out


def missing_because_of_chain(error: Any, errors: list[Any]) -> bool:
    """Whether a validation ``error`` is a drive key missing on an axis whose drive-chain mechanics failed
    (one of ``errors``): the drive takes that key from the chain's motor, so it is missing only because of
    the mechanics' error, which is reported alone."""
    loc = tuple(error["loc"])
    return error["type"] == "missing" and len(loc) > 3 and loc[0] == "axes" and loc[2] == "drive" and \
        any(tuple(e["loc"][:4]) == ("axes", loc[1], "mechanics", "components") for e in errors)
