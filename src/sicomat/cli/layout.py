"""Printing Rich tables without ever cutting a number: columns as wide as their longest word, headers
wrapped at spaces, and one record per row (``header  value`` lines) when even that does not fit."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from rich.console import Console
    from rich.table import Table

__all__ = ["print_table"]


def _plain(renderable) -> str:
    return renderable.plain if hasattr(renderable, "plain") else str(renderable)


def _longest_word(text: str) -> int:
    return max((len(word) for word in text.split()), default=0)


def _longest_line(text: str) -> int:
    return max((len(line) for line in text.splitlines()), default=0)


_HEADER_WORD = 8  # a header word longer than this may be folded; a cell never is


def print_table(console: "Console", table: "Table") -> None:
    """Print ``table`` on ``console`` so that no cell is cut (the table is modified in place).

    Each column gets a fixed width between the one its longest cell word needs (a number is one word) and
    the one its longest line needs (spare width unfolds header words first, then unwraps lines). When that
    does not fit in the console with the table's box, a compact box (no vertical rules, then no padding)
    is tried; when it still does not fit, the rows are printed one after the other as ``header  value``
    records.
    """
    from rich import box
    from rich.markup import render

    columns = table.columns
    cells = [[render(c).plain if isinstance(c, str) else _plain(c) for c in col.cells] for col in columns]
    headers = [render(h).plain if isinstance(h, str) else _plain(h) for h in (c.header for c in columns)]
    need = [max([min(_longest_word(h), _HEADER_WORD)] + [_longest_word(c) for c in cs])
            for h, cs in zip(headers, cells)]
    natural = [max([_longest_line(h)] + [_longest_line(c) for c in cs]) for h, cs in zip(headers, cells)]
    header_word = [_longest_word(h) for h in headers]
    folded = sum(max(w - n, 0) for w, n in zip(header_word, need))
    candidates = ((None, None), (box.SIMPLE_HEAD, (0, 1)), (box.SIMPLE_HEAD, (0, 0)))
    original = (table.box, table.pad_edge, table.show_edge, table.padding)
    spares = []
    for style, padding in candidates:
        if style is not None and padding is not None:
            table.box, table.pad_edge, table.show_edge, table.padding = style, False, False, padding
        spares.append(console.width - _rendered_width(table, need))
    # the first layout where header words are whole, else the first where the cells fit
    choice = next((k for k, sp in enumerate(spares) if sp >= folded), None)
    if choice is None:
        choice = next((k for k, sp in enumerate(spares) if sp >= 0), None)
    if choice is None:
        _print_records(console, table, headers, cells)
        return
    style, padding = candidates[choice]
    if style is None or padding is None:
        table.box, table.pad_edge, table.show_edge, table.padding = original
    else:
        table.box, table.pad_edge, table.show_edge, table.padding = style, False, False, padding
    spare = spares[choice]
    widths = list(need)
    for target in (header_word, natural):  # unfold header words first, then unwrap lines
        for i in sorted(range(len(columns)), key=lambda i: target[i] - widths[i]):
            grow = min(max(target[i] - widths[i], 0), spare)
            widths[i] += grow
            spare -= grow
    _fix_widths(table, widths)
    console.print(table)


def _fix_widths(table: "Table", widths: list[int]) -> None:
    for column, width in zip(table.columns, widths):
        column.width = width
        column.min_width = width
        column.overflow = "fold"


def _rendered_width(table: "Table", widths: list[int]) -> int:
    """The width ``table`` takes with these column widths (rendered off screen, title aside)."""
    import copy
    import io

    from rich.console import Console

    probe = copy.copy(table)
    probe.columns = [copy.copy(c) for c in table.columns]
    probe.title = None
    _fix_widths(probe, widths)
    console = Console(width=100_000, file=io.StringIO(), color_system=None)
    with console.capture() as capture:
        console.print(probe)
    from rich.cells import cell_len

    return max((cell_len(line) for line in capture.get().splitlines()), default=0)


def _print_records(console: "Console", table: "Table", headers: list[str], cells: list[list[str]]) -> None:
    """One block per row: the first cell as its heading, then one ``header  value`` line per column."""
    from rich.text import Text

    if table.title:
        console.print(table.title if isinstance(table.title, Text) else Text.from_markup(str(table.title)))
    label = max(len(h) for h in headers[1:]) if len(headers) > 1 else 0
    rows = len(cells[0]) if cells else 0
    for r in range(rows):
        console.print(Text(f"{headers[0]} {cells[0][r]}", style="bold"), soft_wrap=True)
        for header, column in zip(headers[1:], cells[1:]):
            console.print(Text(f"  {header.ljust(label)}  {column[r]}"), soft_wrap=True)
