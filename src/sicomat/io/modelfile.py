"""Model files: read TOML into a :class:`~sicomat.description.machine.Machine`, apply ``--set`` overrides, save atomically."""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from pydantic import ValidationError

from ..errors import ModelError
from ..description.machine import Machine
from ..description.registry import union_tags
from ..description.components import PART_CLASSES, closest_parameters
from ..catalogue.resolve import resolve_parts

if TYPE_CHECKING:  # pragma: no cover
    from ..catalogue.store import Catalogue

__all__ = ["load_model", "model_from_data", "value_at", "machine_from_dict", "save_model", "model_text", "dump_model", "parse_override",
           "with_overrides"]

_UNION_TAGS = union_tags()  # key of a block table → its registered types (description/registry.py)


def load_model(path: str | os.PathLike, overrides: Iterable[str] = (), *,
               catalogue: "Catalogue | None" = None) -> Machine:
    """Read and validate a model file, then apply ``KEY=VALUE`` overrides.

    Parameters
    ----------
    path : path-like
        A TOML model file (schema in ``docs/model-file.md``).
    overrides : iterable of str
        ``"axes.X.mechanics.bodies.load.mass=300 kg"``-style settings; values are read as TOML
        values when they parse as such (numbers, arrays, booleans), as strings otherwise.

    Raises
    ------
    ModelError
        The file cannot be read, is not TOML, or does not describe a valid machine; the message
        names the file (or the override), the key path, the value and what was expected.
    """
    source = str(path)
    text = _read_text(path)
    return model_from_data(_read_toml(text, source), overrides, source=source, catalogue=catalogue)


def model_from_data(data: Mapping[str, Any], overrides: Iterable[str] = (), *, source: str | None = None,
                    catalogue: "Catalogue | None" = None, base_valid: bool = False) -> Machine:
    """:func:`load_model` on data already read; ``base_valid``: ``data`` alone validates, check only the result."""
    _check_depth(data, source)
    data = resolve_parts(data, catalogue, source=source)
    settings = [(item, *parse_override(item)) for item in overrides]
    if not (settings and base_valid):
        machine = _validate(data, source)
    if not settings:
        return machine
    data = _apply_settings(data, [(key, value, f"--set {item}") for item, key, value in settings])
    swapped = [item for item, key, _ in settings if _PART_ID.match(key)]
    if swapped:   # a part given another catalogue id takes that entry's values
        data = resolve_parts(data, catalogue, source=f"--set {swapped[0]}")
    # validated together, so that settings that only make sense together can come in any order
    # (velocity_delay = 0 with velocity_loop = "continuous"); an error names the override closest to it
    try:
        return Machine.model_validate(data)
    except ValidationError as exc:
        where = (_translate(exc, None).path or "").split(".")
        closest = max(settings, key=lambda s: (len(os.path.commonprefix([s[1].split("."), where])),
                                               settings.index(s)))
        raise _translate(exc, f"--set {closest[0]}") from None


def machine_from_dict(data: Mapping[str, Any], source: str | None = None, *,
                      catalogue: "Catalogue | None" = None) -> Machine:
    """Validate a plain mapping (as read from TOML) into a :class:`Machine`.

    Parts of a ``components`` mechanics that name a catalogue ``id`` get the entry's values that the
    data does not give (:func:`sicomat.catalogue.resolve.resolve_parts`), looked up in ``catalogue``
    (default: the shipped catalogue and the folders of ``SICOMAT_CATALOG``).
    """
    _check_depth(data, source)
    return _validate(resolve_parts(data, catalogue, source=source), source)


def _validate(data: Mapping[str, Any], source: str | None) -> Machine:
    try:
        return Machine.model_validate(data)
    except ValidationError as exc:
        raise _translate(exc, source) from None


def with_overrides(machine: Machine, settings: Mapping[str, Any]) -> Machine:
    """A new machine with values set by key path, validated like a file.

    Examples
    --------
    >>> m = machine_from_dict({"axes": {"X": {"mechanics": {"type": "chain", "masses": [1, 2],
    ...                                                      "stiffnesses": [10]}}}})
    >>> with_overrides(m, {"axes.X.mechanics.masses.1": "3 kg"}).axes["X"].mechanics.masses
    [1.0, 3.0]
    """
    data = _apply_settings(dump_data(machine), [(key, value, f"--set {key}") for key, value in settings.items()])
    return machine_from_dict(data, source="override")


_PART_ID = re.compile(r"^axes\.[^.]+\.mechanics\.parts\.\d+\.id$")


def _apply_settings(data: Mapping[str, Any], settings: list[tuple[str, Any, str]]) -> dict[str, Any]:
    """``data`` with each ``(key, value, source)`` set, catalogue-id settings first: a part given a new
    ``id`` keeps only its ``kind``, ``name`` and the id (the new entry's values then fill it), so the
    other settings of that part apply on top of the new entry."""
    out = dict(data)
    ordered = sorted(settings, key=lambda s: not _PART_ID.match(s[0]))
    for key, value, source in ordered:
        if _PART_ID.match(key):
            path = key.rsplit(".", 1)[0]
            part = value_at(out, path)
            if isinstance(part, dict):
                out = _set_path(out, path, {k: v for k, v in part.items() if k in ("kind", "name")}, source)
        out = _set_path(out, key, value, source)
    return out


def value_at(data: Any, key: str) -> Any:
    """The value at a dotted key path of model-file data (a ``--set`` key), None when there is none."""
    node = data
    for part in key.split("."):
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


def parse_override(item: str) -> tuple[str, Any]:
    """Split ``"KEY=VALUE"`` and read VALUE as a TOML value when it is one, else as a string."""
    key, sep, raw = item.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ModelError("expected KEY=VALUE, e.g. axes.X.mechanics.bodies.load.mass='300 kg'",
                         source="--set", value=item)
    if key.count(".") >= MAX_DEPTH:
        raise ModelError(f"the key path is more than {MAX_DEPTH} levels deep; no model key is", source="--set",
                         value=key)
    raw = raw.strip()
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except (RecursionError, ValueError) as exc:   # nesting too deep, an integer of > 4300 digits
        raise ModelError(_toml_limit(exc), source=f"--set {key}") from None
    _check_depth(value, f"--set {key}", key)
    return key, value


MAX_FILE_BYTES = 16 * 1024 ** 2
"""Largest model file read (16 MiB): a machine is a few kilobytes of TOML; a bound keeps ``/dev/zero``
or a mistaken multi-gigabyte file from being read into memory whole."""


def read_text_bounded(path: str | os.PathLike, limit: int, what: str) -> str:
    """The UTF-8 text of ``path``, refused (:class:`ModelError`) beyond ``limit`` bytes, which are
    never all read: at most ``limit + 1`` bytes are (a device such as ``/dev/zero`` never ends). A leading
    byte-order mark (which some Windows editors write) is dropped: TOML's parser refuses it at line 1."""
    with open(path, "rb") as stream:
        data = stream.read(limit + 1)
    if len(data) > limit:
        raise ModelError(f"{what} larger than {limit // 1024 ** 2} MiB; expected a text file", source=str(path))
    return data.decode("utf-8-sig")


MAX_DEPTH = 32
"""Deepest nesting of tables and arrays accepted in a model file or a ``--set`` value: the schema
nests about 8 levels (``axes.X.mechanics.couplings.k.between.0``); far deeper input is a mistake (or
an attack) and would otherwise exhaust Python's recursion limit in the validators."""


def _read_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError(f"not a valid TOML file: {exc}", source=source) from None
    except (RecursionError, ValueError) as exc:   # the TOML parser's own limits
        raise ModelError(_toml_limit(exc), source=source) from None


def _toml_limit(exc: BaseException) -> str:
    if isinstance(exc, RecursionError):
        return f"values are nested too deeply to read (at most {MAX_DEPTH} levels of tables and arrays)"
    if "digits" in str(exc):
        return "a number has more than 4300 digits; write it in floating-point form (e.g. 1e30)"
    return f"cannot read the value ({exc})"


def _check_depth(data: Any, source: str | None, prefix: str = "") -> None:
    """Refuse tables and arrays nested deeper than :data:`MAX_DEPTH`, naming the key path (iterative: no recursion
    on the user's nesting; only tables and arrays visited, as it runs on every variant of a study)."""
    stack = [(data, prefix, 0)]
    while stack:
        node, where, depth = stack.pop()
        if not node or not isinstance(node, (dict, list)):
            continue
        if depth >= MAX_DEPTH:
            raise ModelError(f"nested too deeply (more than {MAX_DEPTH} levels of tables and arrays)",
                             source=source, path=where or None)
        for k, child in (node.items() if isinstance(node, dict) else enumerate(node)):
            if isinstance(child, (dict, list)):
                stack.append((child, f"{where}.{k}" if where else str(k), depth + 1))


def _set_path(data: Mapping[str, Any], key: str, value: Any, source: str) -> dict[str, Any]:
    """A copy of ``data`` with ``value`` at ``key``; ``data`` is left unchanged.

    Only the tables and arrays on the key's path are copied (the rest is shared with ``data``):
    a deep copy of a whole machine cost more than validating it.
    """
    root = dict(data)
    parts = key.split(".")
    node: Any = root
    for depth, part in enumerate(parts[:-1]):
        where = ".".join(parts[: depth + 1])
        if isinstance(node, dict):
            child = node.get(part, {})
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            part, child = int(part), node[int(part)]  # type: ignore[assignment]
        else:
            raise ModelError("this key path goes through a value that is not a table", source=source,
                             path=where)
        if isinstance(child, (dict, list)):
            child = type(child)(child)
        node[part] = child
        node = child
    last = parts[-1]
    if isinstance(node, dict):
        node[last] = value
    elif isinstance(node, list) and last.isdigit() and int(last) < len(node):
        node[int(last)] = value
    else:
        raise ModelError("cannot set this key: its parent is not a table (or the index is out of range)",
                         source=source, path=key)
    return root


def dump_data(machine: Machine) -> dict[str, Any]:
    """The machine as plain data (SI numbers), ready for TOML."""
    return machine.model_dump(mode="json", exclude_none=True)


def dump_model(machine: Machine) -> str:
    """The machine as TOML text (SI numbers; catalogue parts with their values, ``recorded = true``)."""
    import tomli_w

    from .implied import recorded

    return tomli_w.dumps(recorded(dump_data(machine)))


def save_model(machine: Machine, path: str | os.PathLike, *, based_on: str | os.PathLike | None = None,
               header: str | None = None) -> Path:
    """Write the machine to ``path`` atomically, under the output policy (``docs/outputs.md``).

    Parameters
    ----------
    machine : Machine
        The model to write.
    path : path-like
        A ``.toml`` file: a new name or a regular file (never ``based_on``).
    based_on : path-like, optional
        The model file ``machine`` was derived from: its text is kept (comments, layout, the unit
        of every value) and only the values that differ are rewritten (:mod:`sicomat.io.modeltext`).
        Without it, or if the edited text would not read back as ``machine``, the model is written
        as plain SI numbers.
    header : str, optional
        Comment lines at the top of the file (e.g. what made it).

    Raises
    ------
    OutputError
        ``path`` is refused (:func:`sicomat.io.atomic.check_output`) or cannot be written.
    ModelError
        ``based_on`` cannot be read as a model file.

    Loading what was saved gives an equal machine (numbers written in a unit: within 1e-13).
    """
    from .atomic import atomic_write, check_output

    inputs = {"the model file it is based on": based_on}
    check_output(path, "model", inputs=inputs)
    text = model_text(machine, based_on=based_on, header=header)
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"), kind="model",
                        inputs=inputs)


def model_text(machine: Machine, *, based_on: str | os.PathLike | None = None, header: str | None = None) -> str:
    """The TOML text :func:`save_model` writes."""
    from .implied import as_written, implied_drive_left_out, recorded
    from .modeltext import comment_lines, edited_model_text

    new = recorded(dump_data(machine))
    if based_on is not None:
        original = _read_text(based_on)
        raw = _read_toml(original, str(based_on))
        before = machine_from_dict(raw, source=str(based_on))
        old = as_written(dump_data(before), raw, before)
        edit = implied_drive_left_out(new, raw, machine)
        for keep_units in (True, False):
            text = edited_model_text(original, old, edit, header=header, keep_units=keep_units)
            if _reads_as(text, new):
                return text
        header = ((header + "\n") if header else "") + \
            f"Written as plain SI numbers: the comments and units of {based_on} could not be kept."
    import tomli_w

    return (comment_lines(header) if header else "") + tomli_w.dumps(new)


def _reads_as(text: str, data: Mapping[str, Any]) -> bool:
    """Whether ``text`` loads as ``data``: a number written in its line's unit reads back within
    1e-13 relative (the loader keeps 15 significant digits of a string quantity, 5e-15, and the
    unit factor carries a few roundings of 1.1e-16 each)."""
    try:
        loaded = dump_data(machine_from_dict(tomllib.loads(text)))
    except (ModelError, tomllib.TOMLDecodeError):
        return False
    return _close(loaded, data)


def _close(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, (int, float)) and not isinstance(b, bool):
        return abs(a - b) <= 1e-13 * max(abs(a), abs(b))
    return type(a) is type(b) and a == b


def _read_text(path: str | os.PathLike) -> str:
    source = str(path)
    try:
        return read_text_bounded(path, MAX_FILE_BYTES, "a model file")
    except FileNotFoundError:
        raise ModelError("no such model file", source=source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read the model file ({exc.__class__.__name__}: {exc})", source=source) from None


# --------------------------------------------------------------------------- errors
def _translate(exc: ValidationError, source: str | None) -> ModelError:
    from .implied import missing_because_of_chain

    everything = exc.errors()
    errors = [e for e in everything if not missing_because_of_chain(e, everything)] or everything
    first = errors[0]
    loc = [str(p) for p in first["loc"]]
    loc = [p for i, p in enumerate(loc) if not (i > 0 and p in _UNION_TAGS.get(loc[i - 1], ()))
           and not (i > 1 and loc[i - 2] == "parts" and p in PART_CLASSES)]   # a part's kind tag
    ctx = first.get("ctx") or {}
    kind = first["type"]
    value, has_value = first.get("input"), True
    if kind == "sicomat":
        if ctx.get("subpath"):
            loc.append(ctx["subpath"])
        value = ctx.get("value")
        has_value = value is not None
        message = first["msg"]
    elif kind == "missing":
        message, has_value = "missing required key", False
    elif kind == "extra_forbidden":
        message = "unknown key (not part of the model-file schema; check its spelling)"
        if len(loc) > 2 and loc[-3] == "parts" and str(first["loc"][-2]) in PART_CLASSES:   # a part's parameter
            message += closest_parameters(str(first["loc"][-2]), loc[-1])
    elif kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        message = "expected a value " + first["msg"].removeprefix("Input should be ")
    elif kind in ("union_tag_invalid", "union_tag_not_found") and len(loc) > 1 and loc[-2] == "parts":
        loc.append("kind")
        if kind == "union_tag_invalid":
            message, value = f"unknown part kind; expected one of {ctx.get('expected_tags')}", ctx.get("tag", value)
        else:
            message, has_value = f"missing key 'kind'; expected one of {', '.join(PART_CLASSES)}", False
    elif kind == "union_tag_invalid":
        message = f"unknown type; expected one of {ctx.get('expected_tags')}"
        value = ctx.get("tag", value)
    elif kind == "union_tag_not_found":
        tags: tuple[str, ...] = _UNION_TAGS.get(loc[-1] if loc else "", ())
        message, has_value = f"missing key 'type'; expected one of {', '.join(sorted(tags))}", False
    elif kind == "string_pattern_mismatch":
        message = "expected a name made of letters, digits, '_' or '-', starting with a letter"
    else:
        message = first["msg"].removeprefix("Value error, ").replace("Input should be", "expected")
    if has_value and isinstance(value, (dict, list)) and len(repr(value)) > 120:
        has_value = False
    if len(errors) > 1:
        message += f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''})"
    path = ".".join(loc)
    return ModelError(message, source=source, path=path or None, value=value if has_value else None,
                      has_value=has_value)
