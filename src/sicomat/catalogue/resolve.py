"""Catalogue ids in model files: fill each ``components`` part that names an ``id`` with the entry's values
the file does not give (the file's own values win: they are overrides, or the values a saved model
recorded). A part with ``recorded = true`` (its entry's values beside its id: Save Model writes it so, and
every part filled here is marked so, read once) is left as it is: it loads unchanged when the entry changes or
is gone. Runs on the plain data, before validation (:func:`sicomat.io.modelfile.machine_from_dict`).
"""

from __future__ import annotations

import os
from typing import Any, Callable, Mapping, Sequence

from ..description.parts import KINDS
from ..errors import ModelError
from .store import Catalogue, load_catalogue

__all__ = ["resolve_parts", "use_folders", "default_catalogue"]

_FOLDERS: list[str] = []


def use_folders(folders: "list[str] | tuple[str, ...]") -> None:
    """User catalogue folders that model files read after the shipped catalogue and ``SICOMAT_CATALOG``
    (the CLI's ``sicomat --catalog DIR``): later folders shadow earlier ones, as in :func:`load_catalogue`."""
    _FOLDERS[:] = [str(f) for f in folders]


def user_folders() -> tuple[str, ...]:
    """The folders given by :func:`use_folders` (a study passes them to its workers, other processes)."""
    return tuple(_FOLDERS)


def default_catalogue(extra: "Sequence[str | os.PathLike[str]]" = ()) -> Catalogue:
    """The catalogue model files' ids are looked up in: shipped, ``SICOMAT_CATALOG``, :func:`use_folders`
    (then ``extra``: ``sicomat catalog list --catalog DIR``)."""
    return load_catalogue([*_FOLDERS, *extra])


def _component_parts(data: Mapping[str, Any]):
    axes = data.get("axes")
    if not isinstance(axes, dict):
        return
    for axis, spec in axes.items():
        mech = spec.get("mechanics") if isinstance(spec, dict) else None
        if not (isinstance(mech, dict) and mech.get("type") == "components" and isinstance(mech.get("parts"), list)):
            continue
        for i, part in enumerate(mech["parts"]):
            if isinstance(part, dict) and "id" in part and part.get("recorded") is not True:
                yield axis, i, part   # a recorded part holds the entry's values as saved: not read again


def resolve_parts(data: Mapping[str, Any], catalogue: Catalogue | Callable[[], Catalogue] | None = None, *,
                  source: str | None = None) -> dict[str, Any]:
    """A copy of ``data`` whose catalogue parts carry the entry's values under the file's.

    Parameters
    ----------
    data : mapping
        A model file as read (plain TOML data).
    catalogue : Catalogue or callable, optional
        Where ids are looked up (default: :func:`default_catalogue`, the shipped catalogue, the folders of
        ``SICOMAT_CATALOG`` and those of ``sicomat --catalog``);
        a callable is called only if some part names an id.

    Raises
    ------
    ModelError
        An unknown id (the closest ids named), an id of another kind than the part's, or an id that is not
        a string, located at ``axes.<axis>.mechanics.parts.<i>.id``; an unknown part kind, at ``...kind``.
    """
    found = list(_component_parts(data))
    if not found:
        return dict(data)
    if catalogue is None:
        catalogue = default_catalogue
    try:
        cat = catalogue() if callable(catalogue) else catalogue
    except ModelError as exc:   # e.g. a duplicate id in a user folder: name the model that read it too
        axis, i, _ = found[0]
        reader = f"{source}, " if source else ""
        raise ModelError(f"{exc.message}; the catalogue was read for {reader}axes.{axis}.mechanics.parts.{i}.id",
                         source=exc.source, path=exc.path, value=exc.value, has_value=exc.has_value) from None
    out = dict(data)
    out["axes"] = dict(out["axes"])
    for axis, i, part in found:
        where = f"axes.{axis}.mechanics.parts.{i}.id"
        ident, kind = part["id"], part.get("kind")
        if kind is not None and kind not in KINDS:
            raise ModelError(f"unknown part kind; expected one of {', '.join(KINDS)}", source=source,
                             path=f"axes.{axis}.mechanics.parts.{i}.kind", value=kind)
        if not isinstance(ident, str):
            raise ModelError("expected a catalogue id (a string)", source=source, path=where, value=ident)
        try:
            entry = cat.get(ident, kind if isinstance(kind, str) else None)
        except ModelError as exc:
            raise ModelError(exc.message, source=source, path=where, value=ident) from None
        axis_data = out["axes"][axis] = dict(out["axes"][axis])
        mech = axis_data["mechanics"] = dict(axis_data["mechanics"])
        parts = mech["parts"] = list(mech["parts"])
        parts[i] = {"kind": entry.kind, **entry.parameter_values(), **part, "recorded": True}   # read once
    return out
