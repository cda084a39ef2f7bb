"""Edit a model file's text: rewrite only the values that changed, keep comments, layout and units.

Used by :func:`sicomat.io.modelfile.save_model` with ``based_on=`` (``tune --write``, ``reduce --write``).
The edit compares two dumps of plain SI data, ``old`` (the file as read) and ``new`` (the machine to
write), and touches the TOML document (tomlkit) only where they differ:

- a changed number keeps the unit its line used (``Ti = "9 ms"`` becomes ``Ti = "8.85 ms"``; the
  factor is the one the loader applied to the old value) and its line's comment becomes
  ``# was "9 ms": <old comment>``; a plain number stays a plain SI number;
- a key the file did not write (a default) is added as a plain SI value; a key the new machine no
  longer has is removed with its line;
- a list that grew at its end (a notch added to ``current_filters``) keeps its old entries.

The caller checks that the edited text loads back to ``new`` (:func:`sicomat.io.modelfile.save_model`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, MutableMapping, MutableSequence
from typing import Any

__all__ = ["edited_model_text", "comment_lines"]

_MISSING = object()
_NUMBER_THEN_UNIT = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S.*?)\s*")
"""``"<number> <unit>"``: the value is the number times the unit (the loader's rule; a unit that is
not a plain factor, e.g. degC, makes the caller's read-back check fail and fall back)."""


def edited_model_text(text: str, old: Mapping[str, Any], new: Mapping[str, Any], *, header: str | None = None,
                      keep_units: bool = True) -> str:
    """``text`` (a model file whose data is ``old``) edited so that it reads as ``new``.

    Parameters
    ----------
    text : str
        The original TOML text.
    old, new : mapping
        Plain SI data (:func:`sicomat.io.modelfile.dump_data`) of the file as read and of the machine
        to write.
    header : str, optional
        Comment lines put at the top of the file (without ``#``).
    keep_units : bool
        Write a changed number in the unit its line used (default), or as a plain SI number.

    Examples
    --------
    >>> text = 'Ti = "9 ms"   # Table I\\nKv = 24.8\\n'
    >>> print(edited_model_text(text, {"Ti": 0.009, "Kv": 24.8}, {"Ti": 0.0085, "Kv": 30.0}), end="")
    Ti = "8.5 ms"  # was "9 ms": Table I
    Kv = 30.0  # was 24.8
    """
    import tomlkit

    doc = tomlkit.parse(text)
    _merge(doc, old, new, keep_units)
    return (comment_lines(header) if header else "") + tomlkit.dumps(doc)


def comment_lines(text: str) -> str:
    """``text`` as TOML comment lines, then a blank line."""
    return "".join(f"# {line}".rstrip() + "\n" for line in text.splitlines()) + "\n"


def _merge(node: MutableMapping, old: Mapping, new: Mapping, keep_units: bool) -> None:
    for key, value in new.items():
        before = old.get(key, _MISSING)
        if _equal(before, value):
            continue
        if key not in node:
            node[key] = _fresh(value, inline=_inline(node))
            continue
        written = node[key]
        if isinstance(value, Mapping) and isinstance(before, Mapping) and isinstance(written, MutableMapping) \
                and value.get("type") == before.get("type"):
            _merge(written, before, value, keep_units)
        elif _is_list(value) and _is_list(before) and _is_list(written) and len(written) == len(before) \
                and len(value) >= len(before):
            for i in range(len(before)):
                if _equal(before[i], value[i]):
                    continue
                if isinstance(value[i], Mapping) and isinstance(before[i], Mapping) \
                        and isinstance(written[i], MutableMapping) and value[i].get("type") == before[i].get("type"):
                    _merge(written[i], before[i], value[i], keep_units)
                else:
                    written[i] = _like(written[i], before[i], value[i], keep_units, comment=False,
                                       inline=_inline(written))
            for item in value[len(before):]:
                written.append(_fresh(item, inline=_inline(written)))
        else:
            node[key] = _like(written, before, value, keep_units, comment=True, inline=_inline(node))
    for key in old:
        if key not in new and key in node:
            del node[key]


def _like(written: Any, before: Any, value: Any, keep_units: bool, comment: bool, inline: bool) -> Any:
    """``value`` as a TOML item in the style of ``written`` (the old item, which had ``before`` in SI)."""
    import tomlkit

    if not _is_number(value):  # a name, a type, a list or a table: replaced, its line's comment kept
        item = _fresh(value, inline=inline)
        old_comment = _comment(written)
        if old_comment and hasattr(item, "comment"):
            item.comment(old_comment)
            item.trivia.comment_ws = written.trivia.comment_ws
        return item
    item = tomlkit.item(value)
    if keep_units and isinstance(written, str) and _is_number(before) and before != 0:
        match = _NUMBER_THEN_UNIT.fullmatch(written)
        if match and float(match.group(1)) != 0:
            factor = before / float(match.group(1))  # SI per unit, as the loader applied it
            item = tomlkit.item(f"{value / factor:.15g} {match.group(2)}")
    if comment and not inline and hasattr(written, "as_string"):  # no comment inside an inline table
        old_comment = _comment(written)
        item.comment(f"was {written.as_string()}" + (f": {old_comment}" if old_comment else ""))
        # the comment stays in its column when the old line had one, else two spaces after the value
        column = len(written.trivia.comment_ws) + len(written.as_string()) if old_comment else 0
        item.trivia.comment_ws = " " * max(2, column - len(item.as_string()))
    return item


def _fresh(value: Any, inline: bool = False) -> Any:
    """A new TOML item for plain data; a new table ends with a blank line, like a hand-written one.
    Inside an inline table or an array (``inline``) a table is written inline."""
    import tomlkit

    if inline and isinstance(value, Mapping):
        table = tomlkit.inline_table()
        table.update({key: _fresh(item, inline=True) for key, item in value.items()})
        return table
    if inline and isinstance(value, list):
        array = tomlkit.array()
        for item in value:
            array.append(_fresh(item, inline=True))
        return array
    item = tomlkit.item(value)
    tables = item if isinstance(item, tomlkit.items.AoT) else [item] if isinstance(item, tomlkit.items.Table) else []
    for block in tables:
        block.add(tomlkit.nl())
    return item


def _inline(container: Any) -> bool:
    """Whether a value put in ``container`` must be written inline (an inline table or an array)."""
    import tomlkit

    return isinstance(container, (tomlkit.items.InlineTable, tomlkit.items.Array))


def _comment(item: Any) -> str:
    trivia = getattr(item, "trivia", None)
    return (trivia.comment.lstrip("#").strip() if trivia is not None and trivia.comment else "")


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_list(value: Any) -> bool:
    return isinstance(value, (list, MutableSequence))


def _equal(a: Any, b: Any) -> bool:
    return a is not _MISSING and type(a) is type(b) and a == b
