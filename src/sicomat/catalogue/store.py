"""Load the catalogue: the shipped data files plus the user's folders; look entries up; filter them.

Layout: one TOML file per part, ``<kind>/<id>.toml`` (a user folder may use any sub-folders: the id is
the file's name without ``.toml``, the kind its ``kind`` key). A file holds ``kind``, an optional
``description``, a ``[parameters]`` table (:mod:`.kinds`) and a ``[provenance]`` table. Later folders
extend the earlier ones and shadow them by id: shipped < ``SICOMAT_CATALOG`` (folders separated by
``os.pathsep``) < the folders given explicitly (``--catalog DIR``). Within one folder an id is unique.
"""

from __future__ import annotations

import difflib
import os
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

from pydantic import TypeAdapter, ValidationError

from ..description.base import Spec
from ..description.units import parse_quantity
from ..errors import ModelError
from ..description.parts import KINDS, Provenance, unit_of

__all__ = ["Entry", "Catalogue", "load_catalogue", "shipped_folder", "Condition", "parse_condition", "ENV"]

ENV = "SICOMAT_CATALOG"
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")
MAX_FILE_BYTES = 1 << 20
_PROVENANCE: TypeAdapter[Any] = TypeAdapter(Provenance)


@dataclass(frozen=True)
class Entry:
    """One catalogue part: its id and kind, validated parameters (SI), provenance, where it was read."""

    id: str
    kind: str
    parameters: Spec
    provenance: Any
    source: str
    description: str = ""

    def parameter_values(self) -> dict[str, Any]:
        """The parameters that are set (SI values), in schema order."""
        return {k: v for k, v in self.parameters.model_dump().items() if v is not None}

    def to_dict(self) -> dict[str, Any]:
        """``{"id", "kind", "parameters", "provenance"}`` (+ ``description`` and ``source``)."""
        return {"id": self.id, "kind": self.kind, "description": self.description,
                "parameters": self.parameter_values(),
                "provenance": self.provenance.model_dump(exclude_none=True), "source": self.source}


@dataclass(frozen=True)
class Catalogue:
    """The entries by id (user folders' entries already shadowing shipped ones)."""

    entries: dict[str, Entry] = field(default_factory=dict)

    def __iter__(self) -> Iterator[Entry]:
        return iter(sorted(self.entries.values(), key=lambda e: (e.kind, e.id)))

    def __len__(self) -> int:
        return len(self.entries)

    def get(self, id: str, kind: str | None = None) -> Entry:
        """The entry ``id``; an unknown id names the closest ids; a ``kind`` given must match."""
        entry = self.entries.get(id)
        if entry is None:
            pool = [e.id for e in self.entries.values() if kind is None or e.kind == kind]
            close = difflib.get_close_matches(id, pool, n=3, cutoff=0.5)
            hint = f"; closest: {', '.join(close)}" if close else " (see 'sicomat catalog list')"
            raise ModelError(f"unknown catalogue id{hint}", value=id)
        if kind is not None and entry.kind != kind:
            raise ModelError(f"catalogue entry is a {entry.kind}, not a {kind}", value=id)
        return entry

    def select(self, kind: str | None = None, where: Iterable[str] = ()) -> list[Entry]:
        """The entries of ``kind`` (all when None) meeting every condition of ``where``, sorted by kind, id."""
        if kind is not None and kind not in KINDS:
            raise ModelError(f"unknown kind; expected one of {', '.join(KINDS)}", source="KIND", value=kind)
        kinds = [kind] if kind is not None else list(KINDS)
        conditions = [parse_condition(text, kinds) for text in where]
        return [e for e in self if (kind is None or e.kind == kind) and all(c.holds(e) for c in conditions)]


_OPERATORS = {">=": float.__ge__, "<=": float.__le__, "!=": float.__ne__, "==": float.__eq__,
              ">": float.__gt__, "<": float.__lt__}
_CONDITION = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(>=|<=|!=|==|=|>|<)\s*(.*?)\s*$")


@dataclass(frozen=True)
class Condition:
    """``parameter operator value``: compared in SI; an entry without the parameter does not match."""

    name: str
    operator: str
    values: dict[str, Any]   # kind -> the value in that kind's unit (SI float, int or word)

    def holds(self, entry: Entry) -> bool:
        if entry.kind not in self.values:
            return False
        actual = getattr(entry.parameters, self.name)
        if actual is None:
            return False
        wanted = self.values[entry.kind]
        if isinstance(wanted, str):
            return (actual == wanted) == (self.operator == "==")
        return bool(_OPERATORS[self.operator](float(actual), float(wanted)))


def parse_condition(text: str, kinds: Sequence[str]) -> Condition:
    """A ``--where`` filter such as ``"peak_torque >= 10 N*m"``, its value read in the unit of the
    parameter (pint, as model files); the parameter must belong to one of ``kinds``.

    >>> parse_condition("peak_torque >= 10 N*m", ["motor"]).values
    {'motor': 10.0}
    """
    def bad(problem: str) -> ModelError:
        return ModelError(problem, source="--where", value=text)

    match = _CONDITION.match(text)
    if not match:
        raise bad("expected 'PARAMETER OPERATOR VALUE', e.g. 'peak_torque >= 10 N*m', with an operator among "
                  + ", ".join(_OPERATORS))
    name, operator, raw = match.groups()
    operator = "==" if operator == "=" else operator
    if not raw:
        raise bad("missing the value after the operator")
    owners = [k for k in kinds if name in KINDS[k].model_fields]
    if not owners:
        known = sorted({n for k in kinds for n in KINDS[k].model_fields})
        close = difflib.get_close_matches(name, known, n=3)
        hint = f"; closest: {', '.join(close)}" if close else f"; the parameters are {', '.join(known)}"
        raise bad(f"unknown parameter {name!r} for {'kind ' + kinds[0] if len(kinds) == 1 else 'any kind'}{hint}")
    values: dict[str, Any] = {}
    for kind in owners:
        unit = unit_of(kind, name)
        if unit is not None:
            try:
                values[kind] = parse_quantity(_number_or_text(raw), unit)
            except ValueError as exc:
                raise bad(f"{name}: {exc}") from None
            continue
        annotation = str(KINDS[kind].model_fields[name].annotation)
        if "int" in annotation and "Literal" not in annotation:
            try:
                values[kind] = float(raw)
            except ValueError:
                raise bad(f"{name} is a plain number (no unit); cannot read the value") from None
        else:
            if operator not in ("==", "!="):
                raise bad(f"{name} is a word: compare it with == or !=")
            values[kind] = raw.strip("'\"")
    return Condition(name, operator, values)


def _number_or_text(raw: str) -> Any:
    try:
        return float(raw)
    except ValueError:
        return raw


# --------------------------------------------------------------------------- loading
def shipped_folder() -> Traversable:
    """The catalogue's data folder inside the installed package."""
    return resources.files("sicomat.catalogue") / "data"


def load_catalogue(folders: Sequence[str | os.PathLike[str]] = (), *, environment: bool = True) -> Catalogue:
    """The shipped catalogue extended (and shadowed, by id) by ``$SICOMAT_CATALOG`` and then ``folders``."""
    entries: dict[str, Entry] = {}
    for entry in _read_folder(shipped_folder(), "the shipped catalogue"):
        entries[entry.id] = entry
    users: list[tuple[str, str]] = []
    if environment and os.environ.get(ENV):
        users += [(p, ENV) for p in os.environ[ENV].split(os.pathsep) if p]
    users += [(os.fspath(p), "--catalog") for p in folders]
    for path, option in users:
        folder = Path(path)
        if not folder.is_dir():
            raise ModelError("not a folder of catalogue files", source=option, value=str(path))
        for entry in _read_folder(folder, str(folder)):
            entries[entry.id] = entry
    return Catalogue(entries)


MAX_DEPTH = 8
"""Deepest sub-folder read in a catalogue folder (the shipped one uses 1): a deeper tree is a mistake, or
a symbolic link looping back."""


def _walk(folder: Traversable, depth: int = 0) -> Iterator[Traversable]:
    for item in sorted(folder.iterdir(), key=lambda t: t.name):
        if item.is_dir():
            if depth >= MAX_DEPTH:
                raise ModelError(f"catalogue folders nest more than {MAX_DEPTH} levels deep (a link loop?)",
                                 source=str(item))
            yield from _walk(item, depth + 1)
        elif item.name.endswith(".toml"):
            yield item


def _read_folder(folder: Traversable, label: str) -> list[Entry]:
    seen: dict[str, str] = {}
    found = []
    for item in _walk(folder):
        source = str(item)
        entry = read_entry(item, source)
        if entry.id in seen:
            raise ModelError(f"duplicate catalogue id in {label} (also in {seen[entry.id]})", source=source,
                             value=entry.id)
        seen[entry.id] = source
        found.append(entry)
    return found


def read_entry(item: Traversable, source: str) -> Entry:
    """One catalogue file, validated; every error names the file, the key path and the value."""
    id = item.name.removesuffix(".toml")
    if not ID_PATTERN.match(id):
        raise ModelError("a catalogue file's name (its id) must be letters, digits, '_', '-' or '.', starting "
                         "with a letter or digit", source=source, value=id)
    data = item.read_bytes()
    if len(data) > MAX_FILE_BYTES:
        raise ModelError(f"a catalogue file is larger than {MAX_FILE_BYTES} bytes", source=source)
    try:
        table = tomllib.loads(data.decode("utf-8-sig"))    # a leading byte-order mark dropped, as for model files
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        raise ModelError(f"not a valid TOML file: {exc}", source=source) from None
    unknown = sorted(set(table) - {"kind", "description", "parameters", "provenance"})
    if unknown:
        raise ModelError("unknown key (a catalogue file has kind, description, [parameters], [provenance])",
                         source=source, path=unknown[0])
    kind = table.get("kind")
    if kind not in KINDS:
        raise ModelError(f"expected a kind among {', '.join(KINDS)}" if "kind" in table else
                         "missing required key", source=source, path="kind", value=kind)
    parent = getattr(item, "parent", None)
    folder_name = parent.name if isinstance(parent, Path) else None
    if folder_name in KINDS and folder_name != kind:
        raise ModelError(f"the file is in the folder of kind {folder_name}", source=source, path="kind",
                         value=kind)
    description = table.get("description", "")
    if not isinstance(description, str):
        raise ModelError("expected a string", source=source, path="description", value=description)
    for key in ("parameters", "provenance"):
        if not isinstance(table.get(key), dict):
            raise ModelError("missing required table" if key not in table else "expected a table",
                             source=source, path=key, value=table.get(key))
    try:
        parameters = KINDS[kind].model_validate(table["parameters"])
    except ValidationError as exc:
        raise located(exc, source, "parameters") from None
    try:
        provenance = _PROVENANCE.validate_python(table["provenance"])
    except ValidationError as exc:
        raise located(exc, source, "provenance") from None
    return Entry(id, kind, parameters, provenance, source, description)


def located(exc: ValidationError, source: str | None, prefix: str) -> ModelError:
    """The first problem of a validation error as a :class:`ModelError` at ``prefix.<its key path>``."""
    first = exc.errors()[0]
    loc = [str(p) for p in first["loc"] if str(p) not in ("datasheet", "typical")]
    kind = first["type"]
    value, has_value = first.get("input"), True
    if kind == "missing":
        message, has_value = "missing required key", False
    elif kind == "extra_forbidden":
        message = "unknown key (not a parameter of this kind; check its spelling, see docs/catalogue.md)"
    elif kind in ("union_tag_invalid", "union_tag_not_found"):
        message = "expected source = \"datasheet\" or \"typical\""
        value = (first.get("ctx") or {}).get("tag", value)
        loc.append("source")
    else:
        message = first["msg"].removeprefix("Value error, ").replace("Input should be", "expected")
    if isinstance(value, (dict, list)):
        has_value = False
    more = len(exc.errors()) - 1
    if more:
        message += f" (and {more} more problem{'s' if more > 1 else ''})"
    return ModelError(message, source=source, path=".".join([prefix, *loc]), value=value if has_value else None,
                      has_value=has_value)
