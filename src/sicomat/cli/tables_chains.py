"""Tables of the drive-chain commands (issue 12): what a chain lowers to (``check --lumped``), the mode map
(``modemap``; over a robot's workspace too, issue 13), the margins over the stroke (``tune --all-positions``)
and the sizing checks (``size``)."""

from __future__ import annotations

import math
from typing import Any

from .layout import print_table

__all__ = ["print_drive_chain", "print_sizing", "print_mode_map", "print_workspace_map", "print_stroke_tuning"]


def print_drive_chain(axis: str, chain: dict[str, Any]) -> None:
    """Print what a drive-chain axis is lowered to (``sicomat check --lumped``): one table per group."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    if not chain["derived"]:
        console.print(f"axis {axis}: {chain['note']}")
        return
    stroke = f" of a {chain['stroke']:.6g} m stroke" if chain["stroke"] is not None else ""
    console.print(f"[bold]axis {axis}: drive chain[/] at position {chain['position']:.6g} m{stroke}, "
                  f"detail {chain['detail']!r}")

    def table(title: str, columns: tuple[str, ...], rows: list[tuple[str, ...]]) -> None:
        if not rows:
            return
        t = Table(title=f"axis {axis}: {title}", title_justify="left")
        for col in columns:
            t.add_column(col, justify="right" if col in _NUMERIC else "left")
        for row in rows:
            t.add_row(*row)
        print_table(console, t)

    table("bodies", ("body", "kind", "mass or inertia", "carries"),
          [(b["name"], b["kind"], f"{b.get('mass', b.get('inertia')):.6g} "
            + ("kg" if b["kind"] == "translational" else "kg*m^2"), "\n".join(b["parts"])) for b in chain["bodies"]])
    table("springs", ("spring", "between", "ratio", "stiffness", "damping", "own f (Hz)", "rule"),
          [(s["name"], f"{s['between'][0]} - {s['between'][1]}", f"{s['ratio']:.6g}", f"{s['stiffness']:.6g}",
            "-" if s["damping"] is None else f"{s['damping']:.4g}",
            "-" if s["frequency_hz"] is None else f"{s['frequency_hz']:.5g}", s["rule"]) for s in chain["springs"]])
    table("frictions", ("friction", "between", "coulomb (SI)", "viscous (SI)", "rule"),
          [(n, " - ".join(f["between"]), f"{f['coulomb']:.6g}", f"{f['viscous']:.6g}", f.get("rule", ""))
           for n, f in chain["frictions"].items()])
    table("sensors and actuator", ("element", "name", "on body", "details"),
          [("sensor", n, s["body"], ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                                              for k, v in s.items() if k != "body"))
           for n, s in chain["sensors"].items()]
          + [("actuator", "motor", chain["actuator"]["body"],
              ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in chain["actuator"].items() if k != "body"))])
    drive = chain["drive"]
    table("drive constants from the motor (SI, per phase, rms)", ("key", "motor implies", "drive uses", "from"),
          [(k, f"{v:.6g}", "-" if drive is None else f"{drive[k]:.6g}",
            "no drive table" if drive is None else ("the file" if k in chain["drive_overrides"] else "the motor"))
           for k, v in chain["drive_from_motor"].items()])
    for note in chain["notes"]:
        console.print(f"  note: {note}")
    for warning in chain.get("datasheet_warnings", []):
        console.print(f"  [yellow]warning[/]: {warning}")


_NUMERIC = ("mass or inertia", "ratio", "stiffness", "damping", "own f (Hz)", "coulomb (SI)", "viscous (SI)",
            "motor implies", "drive uses")

def print_sizing(payload: dict[str, Any]) -> None:
    """Print the checks of ``sicomat size``: failing first, then passing, then unknown (the payload's order),
    the notes of the failing and unknown checks below the table."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    def cell(value: Any, unit: str) -> str:
        if value is None:
            return "-"
        text = f"{value:.4g}"
        return text + (f" ({value * 30.0 / 3.141592653589793:.4g} rpm)" if unit == "rad/s" else "")

    console = Console(highlight=False)
    verdict = {False: "[bold red]FAILED[/]", True: "[bold green]passed[/]", None: "[yellow]not all known[/]"}
    move = payload.get("move", {})
    what = {"trajectory": "its trajectory", "move": "the --move", "gcode": f"the G-code path {move.get('file', '')}"}
    title = f"axis {payload['axis']}: sizing over {what.get(move.get('source', ''), 'the move')}"
    table = Table(title=title, title_justify="left")
    for col, justify in (("check", "left"), ("result", "left"), ("value", "right"), ("limit", "right"),
                         ("unit", "left")):
        table.add_column(col, justify=justify)  # type: ignore[arg-type]
    words = {False: "[bold red]FAIL[/]", True: "[green]ok[/]", None: "[yellow]unknown[/]"}
    for c in payload["checks"]:
        table.add_row(c["name"], words[c["ok"]], cell(c["value"], c["unit"]), cell(c["limit"], c["unit"]), c["unit"])
    if payload["checks"]:
        print_table(console, table)
    for c in payload["checks"]:      # the formulas of the passing checks are in --json and docs/components.md
        if c["note"] and c["ok"] is not True:
            console.print(f"  {c['name']}: {escape(c['note'])}")
    for note in payload.get("notes", []):
        console.print(f"  note: {escape(note)}")
    console.print(f"sizing: {verdict[payload['ok']]}")


def print_mode_map(payload: dict[str, Any]) -> None:
    """Print the mode map of ``sicomat modemap``: one row per position, the worst one marked."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    table = Table(title=f"axis {payload['axis']}: flexible modes over the stroke "
                        f"({payload['stroke'] * 1e3:.6g} mm)", title_justify="left")
    table.add_column("position (mm)", justify="right")
    for k in range(payload["modes"]):
        table.add_column(f"f{k + 1} (Hz)", justify="right")
    table.add_column("")
    worst = payload["worst_position"]
    for x, row in zip(payload["position"], payload["frequencies_hz"]):
        mark = "worst (lowest f1)" if x == worst else ""
        cells = ["-" if f is None else f"{f:.4f}" for f in row]
        table.add_row(f"{x * 1e3:.6g}", *cells, mark, style="bold red" if mark else None)
    print_table(console, table)
    if worst is not None:
        console.print(f"lowest first mode {payload['lowest_first_mode_hz']:.4g} Hz at {worst * 1e3:.6g} mm")
    for note in payload.get("notes", []):
        console.print(f"note: {note}", markup=False)


def print_workspace_map(payload: dict[str, Any]) -> None:
    """Print the mode map of ``sicomat modemap --joint``: one row per configuration (joint values in mm or
    deg), the worst one marked, a failed one with its reason."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    scales = [(1e3, "mm") if unit == "m" else (180.0 / math.pi, "deg") for unit in payload["units"]]
    table = Table(title=f"{payload['machine'] or 'robot'}: {_what_is_mapped(payload)}", title_justify="left")
    for name, (_, unit) in zip(payload["joints"], scales):
        table.add_column(f"{name} ({unit})", justify="right")
    for k in range(payload["modes"]):
        table.add_column(f"f{k + 1} (Hz)", justify="right")
    table.add_column("")
    one = len(payload["joints"]) == 1
    worst = payload["worst_position"]
    distinct = list(dict.fromkeys(f["reason"] for f in payload["failed"]))     # each reason printed once, below
    reasons = {_json_key(f["position"]): distinct.index(f["reason"]) + 1 for f in payload["failed"]}
    for x, row in zip(payload["position"], payload["frequencies_hz"]):
        values = [x] if one else x
        reason = reasons.get(_json_key(x))
        mark = "worst (lowest f1)" if x == worst else (f"failed [{reason}]" if reason is not None else "")
        cells = ["-" if f is None else f"{f:.4f}" for f in row]
        table.add_row(*(f"{v * scale:.6g}" for v, (scale, _) in zip(values, scales)), *cells, mark,
                      style="bold red" if x == worst else ("dim" if reason is not None else None))
    print_table(console, table)
    if worst is not None:
        at = ", ".join(f"{name} = {v * scale:.6g} {unit}" for name, v, (scale, unit)
                       in zip(payload["joints"], [worst] if one else worst, scales))
        console.print(f"lowest first mode {payload['lowest_first_mode_hz']:.4g} Hz at {at}", markup=False)
    for note in payload.get("notes", []):
        console.print(f"note: {note}", markup=False)
    for i, reason in enumerate(distinct, start=1):
        console.print(f"failed [{i}]: {reason}", markup=False)


def _what_is_mapped(payload: dict[str, Any]) -> str:
    locked = ", ".join(payload["locked"]) or "none"
    joints = " and ".join(payload["joints"])
    if payload["axis"] is None:
        return f"modes over {joints}, motors locked ({locked})"
    return f"axis {payload['axis']}'s model over {joints} (motor {payload['axis']} free, locked: {locked})"


def _json_key(position: Any) -> Any:
    """A map position (a value, or a list of two) as a dictionary key."""
    return tuple(position) if isinstance(position, list) else position


def print_stroke_tuning(payload: dict[str, Any]) -> None:
    """Print the margins of ``sicomat tune --all-positions`` at every position, the worst marked."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    table = Table(title=f"tuned at {payload['tuned_position'] * 1e3:.6g} mm; margins over the stroke",
                  title_justify="left")
    for col in ("position (mm)", "f1 (Hz)", "vel. PM (°)", "vel. GM (dB)", "pos. PM (°)", "pos. GM (dB)",
                "stable", "smallest"):
        table.add_column(col, justify="right")

    def cell(value: Any, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    for p in payload["positions"]:
        marks = [m for m, at in (("PM", payload["worst_position"]), ("GM", payload["min_gain_margin_position"]))
                 if p["position"] == at]
        stable = {True: "yes", False: "NO", None: "?"}[p["stable"]]
        table.add_row(f"{p['position'] * 1e3:.6g}", cell(p["first_mode_hz"], ".4g"),
                      cell(p["velocity_phase_margin_deg"], ".2f"), cell(p["velocity_gain_margin_db"], ".2f"),
                      cell(p["position_phase_margin_deg"], ".2f"), cell(p["position_gain_margin_db"], ".2f"),
                      stable, ", ".join(marks), style="bold" if marks else None)
    print_table(console, table)
    attempts = payload.get("attempts", [])
    if len(attempts) > 1:
        words = []
        for a in attempts:
            verdict = "unstable" if a["stable"] is False else f"{a['unmet']} unmet" if a["unmet"] else "all met"
            words.append(f"{a['tuned_position'] * 1e3:.6g} mm ({verdict}{', kept' if a['chosen'] else ''})")
        console.print("  tuned at " + ", then ".join(words), markup=False)
    console.print(f"  smallest velocity phase margin {cell(payload['min_phase_margin_deg'], '.2f')}° at "
                  f"{payload['worst_position'] * 1e3:.6g} mm; smallest gain margin "
                  f"{cell(payload['min_gain_margin_db'], '.2f')} dB at {payload['min_gain_margin_position'] * 1e3:.6g} mm")
