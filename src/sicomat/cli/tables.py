"""Rich tables for the terminal, read from result objects."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from ..mechanics.lumped import Mechanics
    from ..mechanics.modal import ModalResult
    from ..description.machine import Machine

from .layout import print_table

__all__ = ["check_payload", "print_check", "print_modal", "print_verdict"]


def check_payload(machine: "Machine", mechanics: dict[str, "Mechanics"]) -> dict[str, Any]:
    """The ``sicomat check --json`` object: the machine's axes as lumped models (SI units)."""
    axes: dict[str, dict[str, Any]] = {}
    for name, mech in mechanics.items():
        axes[name] = {
            "mechanics_type": _mechanics_type(machine, name),
            "n_dofs": mech.n,
            "n_states": 2 * mech.n,
            "dofs": [{"name": d.name, "kind": d.kind, "mass": float(mech.mass[i, i])}
                     for i, d in enumerate(mech.dofs)],
            "couplings": [{"name": c.name, "kind": c.kind, "stiffness": c.stiffness, "damping": c.damping,
                           "stretch": _stretch(mech, c.g)} for c in mech.couplings],
            "frictions": [{"name": f.name, "viscous": f.damping, "coulomb": f.coulomb, "static": f.static,
                           "stretch": _stretch(mech, f.g)} for f in mech.frictions],
            "actuators": [{"name": a.name, "kind": "force" if a.kind == "translational" else "torque",
                           "applies": _stretch(mech, a.vector)} for a in mech.actuators],
            "sensors": [{"name": s.name, "kind": s.kind, "reads": _stretch(mech, s.vector)}
                        for s in mech.sensors],
        }
        spec = machine.axes[name]
        for block in ("drive", "controller", "trajectory"):
            value = getattr(spec, block)
            axes[name][block] = _with_hz(value.model_dump(mode="json", exclude_none=True)) if value is not None else None
    return {"valid": True, "name": machine.name, "axes": axes}


def _mechanics_type(machine: "Machine", axis: str) -> str:
    mechanics = machine.axes[axis].mechanics
    return mechanics.type if mechanics is not None else "robot"


# the model file's frequency-typed keys: values in Hz under a name without a suffix
_MODEL_FILE_HZ = ("bandwidth", "frequency")


def _with_hz(block: Any) -> Any:
    """A model-file block as ``check --json`` echoes it: its own keys, and ``<key>_hz`` beside each
    frequency the file holds in Hz (the JSON unit rule: an unsuffixed key is SI)."""
    if isinstance(block, dict):
        out = {}
        for key, value in block.items():
            out[key] = _with_hz(value)
            if key in _MODEL_FILE_HZ and isinstance(value, (int, float)):
                out[f"{key}_hz"] = value
        return out
    if isinstance(block, list):
        return [_with_hz(v) for v in block]
    return block


def _stretch(mech: "Mechanics", vector) -> str:
    terms = []
    for d, v in sorted(zip(mech.dofs, vector), key=lambda dv: dv[1] < 0):
        if v == 0:
            continue
        sign = "-" if v < 0 else "+"
        coef = "" if abs(v) == 1 else f"{abs(v):.6g}*"
        terms.append(f"{sign} {coef}{d.position}")
    text = " ".join(terms)
    return text[2:] if text.startswith("+ ") else text


def print_check(source: str, payload: dict[str, Any]) -> None:
    """Print the summary of ``sicomat check``."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    console.print(f"[bold green]valid[/] {source}  {payload['name']}")
    for name, axis in payload["axes"].items():
        table = Table(title=f"axis {name} ({axis['mechanics_type']}): {axis['n_dofs']} dofs, "
                            f"{axis['n_states']} states", title_justify="left")
        table.add_column("element")
        table.add_column("name")
        table.add_column("acts on")
        table.add_column("values (SI)", justify="right")
        for d in axis["dofs"]:
            unit = "kg" if d["kind"] == "translational" else "kg*m^2"
            table.add_row("body", d["name"], d["kind"], f"{d['mass']:.6g} {unit}")
        for c in axis["couplings"]:
            table.add_row("coupling", c["name"], c["stretch"], f"k={c['stiffness']:.4g} d={c['damping']:.4g}")
        for f in axis["frictions"]:
            table.add_row("friction", f["name"], f["stretch"], f"viscous={f['viscous']:.4g} coulomb={f['coulomb']:.4g}")
        for a in axis["actuators"]:
            table.add_row("actuator", a["name"], a["applies"], a["kind"])
        for s in axis["sensors"]:
            table.add_row("sensor", s["name"], s["reads"], s["kind"])
        print_table(console, table)
        blocks = [f"{block}: {axis[block]['type']}" for block in ("drive", "controller", "trajectory")
                  if axis.get(block)]
        ctrl = axis.get("controller") or {}
        analog = [loop for loop in ("velocity", "position") if ctrl.get(f"{loop}_loop") == "continuous"]
        if analog:
            blocks[[b.split(":")[0] for b in blocks].index("controller")] += f" ({' and '.join(analog)} loop continuous)"
        if blocks:
            console.print("  servo blocks: " + ", ".join(blocks))


def print_modal(axis: str | None, result: "ModalResult") -> None:
    """Print the modes of ``sicomat modal`` (``axis`` None: a robot's structure, its motors locked)."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    title = f"axis {axis}: modes" if axis is not None else "robot, motors locked: modes"
    table = Table(title=title, title_justify="left")
    for col in ("mode", "f (Hz)", "zeta", "f damped (Hz)", "f undamped (Hz)", "dominant dof", "participation"):
        table.add_column(col, justify="right")
    for k, m in enumerate(result.modes, 1):
        if m.rigid:
            table.add_row(str(k), "0 (rigid)", "-", "-", "0", m.dominant_dof, "-")
        else:
            table.add_row(str(k), f"{m.frequency_hz:.4f}", f"{m.damping_ratio:.3g}",
                          f"{m.damped_frequency_hz:.4f}", f"{m.undamped_hz:.4f}", m.dominant_dof,
                          f"{100 * m.participation:.1f} %")
    print_table(console, table)
    shapes = Table(title="mode shapes (largest component = 1)", title_justify="left")
    shapes.add_column("dof")
    for k in range(len(result.modes)):
        shapes.add_column(f"{k + 1}", justify="right")
    for d in result.dofs:
        shapes.add_row(d, *(f"{m.shape[d]:+.3f}" for m in result.modes))
    print_table(console, shapes)
    if result.f_meca_hz is not None:
        console.print(f"suggested f_meca = {result.f_meca_hz:.4g} Hz (first flexible mode the loop sees)")


def print_verdict(payload: dict[str, Any], what: str = "loop") -> None:
    """Print the stability verdict (``"stable"``) and the warnings of a payload, as ``--json`` has them."""
    from rich.console import Console

    console = Console(highlight=False)
    stable = payload.get("stable")
    if stable is True:
        console.print(f"{what}: [bold green]stable[/]")
    elif stable is False:
        console.print(f"{what}: [bold red]UNSTABLE[/] (the figures are not meaningful)")
    else:
        console.print(f"{what}: stability unknown")
    from rich.markup import escape

    for warning in payload.get("warnings", []):
        console.print(f"[yellow]warning:[/] {escape(warning)}")


def print_metrics(axis: str, payload: dict[str, Any]) -> None:
    """Print the figures of ``sicomat simulate``."""
    from rich.console import Console
    from rich.table import Table

    wall = "" if payload.get("wall_time_s") is None else f", {payload['wall_time_s'] * 1e3:.1f} ms"
    table = Table(title=f"axis {axis}: simulation ({payload['samples']} steps of {payload['step_s'] * 1e6:g} µs"
                        f"{wall})", title_justify="left")
    table.add_column("figure")
    table.add_column("value", justify="right")
    for key, scale, unit in (("max_following_error", 1e6, "µm"), ("rms_following_error", 1e6, "µm"),
                             ("final_error", 1e6, "µm"), ("overshoot_percent", 1, "%"),
                             ("rise_time", 1e3, "ms"), ("settling_time", 1e3, "ms")):
        value = payload[key]
        table.add_row(key, "-" if value is None else f"{value * scale:.4g} {unit}")
    console = Console(highlight=False)
    print_table(console, table)
    for note in payload.get("notes", []):
        console.print(f"note: {note}")
    print_verdict(payload)


def print_margins(axis: str, margins: dict[str, Any], note: str | None = None) -> None:
    """Print stability margins of one or more loops."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    if note:
        console.print(note)
    if not margins:
        return
    table = Table(title=f"axis {axis}: stability margins, worst over all crossovers (DM: delay margin, "
                        f"MM: modulus margin 1/max|S|, BW: closed-loop -3 dB, n: gain crossovers)",
                  title_justify="left")
    table.add_column("loop")
    for col in ("PM °", "at rad/s", "GM dB", "at rad/s", "DM ms", "MM", "BW rad/s", "n"):
        table.add_column(col, justify="right")

    def f(x, fmt="{:.3g}"):
        return "-" if x is None or x != x or x in (float("inf"), float("-inf")) else fmt.format(x)

    for name, m in margins.items():
        table.add_row(name, f(m.phase_margin_deg, "{:.1f}"), f(m.gain_crossover_rad_s, "{:.4g}"),
                      f(m.gain_margin_db, "{:.1f}"), f(m.phase_crossover_rad_s, "{:.4g}"),
                      f(m.delay_margin_s * 1e3), f(m.modulus_margin), f(m.bandwidth_rad_s, "{:.4g}"),
                      str(len(m.gain_crossovers)))
    print_table(console, table)


def print_tuning(axis: str, payload: dict[str, Any]) -> None:
    """Print the result of ``sicomat tune``."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    table = Table(title=f"axis {axis}: {payload.get('method', 'frequency')} tuning", title_justify="left")
    table.add_column("gain")
    if "initial" in payload:
        table.add_column("initial (rigid)", justify="right")
    table.add_column("tuned", justify="right")
    rows = (("Kp_normalized (1/s)", ("velocity", "Kp_normalized")), ("Kp (SI)", ("velocity", "Kp")),
            ("Ti (s)", ("velocity", "Ti")), ("Kv (1/s)", ("position", "Kv")))
    for label, (group, key) in rows:
        cells = [f"{payload['initial'][group][key]:.5g}"] if "initial" in payload else []
        table.add_row(label, *cells, f"{payload[group][key]:.5g}")
    print_table(console, table)
    achieved = payload.get("achieved", {})
    for key, value in achieved.items():
        if key in ("unmet",) or value is None:
            continue
        if isinstance(value, dict):      # e.g. the suggested notch: one "key value" pair per field
            value = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in value.items())
        console.print(f"  {key}: {value:.4g}" if isinstance(value, float) else f"  {key}: {value}")
    # the unmet targets are among the warnings, printed with the verdict (print_verdict)
    if "equivalent_delay_s" in payload:
        console.print(f"  equivalent delay of the rigid tuning: {payload['equivalent_delay_s'] * 1e3:.3f} ms")
    console.print(f"  tuning time: {payload['wall_time_s'] * 1e3:.1f} ms")


def print_circle(payload: dict[str, Any]) -> None:
    """Print the figures of ``sicomat circle``."""
    from rich.console import Console
    from rich.table import Table

    direction = "CW" if payload["clockwise"] else "CCW"
    table = Table(title=f"circle test R = {payload['radius'] * 1e3:g} mm, {direction}, "
                        f"F = {payload['feed'] * 6e4:g} mm/min, feedforward {payload['feedforward']}",
                  title_justify="left")
    table.add_column("figure")
    table.add_column("value", justify="right")
    for key in ("circular_deviation", "radial_deviation_min", "radial_deviation_max", "mean_radial_deviation",
                "max_contour_error", "servo_mismatch"):
        table.add_row(key, f"{payload[key] * 1e6:.3f} µm")
    table.add_row("servo_mismatch_angle", f"{payload['servo_mismatch_angle_deg']:.1f}°")
    for spike in payload["reversal_spikes"]:
        table.add_row(f"reversal spike {spike['quadrant_deg']:g}° ({spike['axis']})", f"{spike['height'] * 1e6:.3f} µm")
    print_table(Console(highlight=False), table)


def print_circle_coupling(payload: dict[str, Any]) -> None:
    """Print the comparison of the models of ``sicomat circle`` on a robot machine."""
    from rich.console import Console
    from rich.table import Table

    coupling = payload["coupling"]
    table = Table(title="what the coupling of the axes adds (tool point; decoupled: each axis alone on its own "
                        "linearisation)", title_justify="left")
    table.add_column("model")
    for col in ("circular deviation (µm)", "max contour error (µm)"):
        table.add_column(col, justify="right")

    def cell(value: Any, sign: str = "") -> str:
        return "—" if value is None else f"{value * 1e6:{sign}.4g}"

    for name in ("decoupled", "coupled", "nonlinear"):
        line = coupling[name]
        chosen = " (reported)" if name == payload.get("model") else ""
        table.add_row(name + chosen, cell(line["circular_deviation"]), cell(line["max_contour_error"]))
    for key, label in (("added_by_linear_coupling", "added: linear coupling"),
                       ("added_by_large_motion", "added: large motion"),
                       ("added_by_coupling", "added: coupling in all")):
        table.add_row(label, cell(coupling[key]["circular_deviation"], "+"), cell(coupling[key]["max_contour_error"], "+"))
    print_table(Console(highlight=False), table)


def print_path(payload: dict[str, Any]) -> None:
    """Print the figures of ``sicomat simulate --gcode``."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"path of {payload['path_length'] * 1e3:.4g} mm in {payload['duration_s']:.3g} s: "
                        f"max contour error {payload['max_contour_error'] * 1e6:.3g} µm", title_justify="left")
    table.add_column("axis")
    for col in ("max following error (µm)", "rms (µm)", "final (µm)"):
        table.add_column(col, justify="right")
    for name, axis in payload["axes"].items():
        table.add_row(f"{name} ({axis['machine_axis']})", f"{axis['max_following_error'] * 1e6:.4g}",
                      f"{axis['rms_following_error'] * 1e6:.4g}", f"{axis['final_error'] * 1e6:.4g}")
    print_table(Console(highlight=False), table)


def print_reduction(payload: dict[str, Any]) -> None:
    """Print the report of ``sicomat reduce``."""
    from rich.console import Console

    console = Console(highlight=False)
    console.print(f"[bold]{payload['method']}[/]: {payload['order_before']} → {payload['order_after']} states")
    console.print(f"  transfer: {', '.join(payload['inputs'])} → {', '.join(payload['outputs'])}")
    for warning in payload.get("warnings") or []:
        console.print(f"  [bold yellow]warning:[/] {warning}")
    for note in payload.get("notes") or []:
        console.print(f"  note: {note}")
    if payload.get("band_hz"):
        console.print(f"  band of interest: {payload['band_hz'][0]:.6g}-{payload['band_hz'][1]:.6g} Hz")
    for key in ("hinf_error", "dc_gain_error", "error_bound"):
        if payload.get(key) is not None:
            console.print(f"  {key}: {payload[key]:.4g}")
    freqs = payload.get("frequencies_hz") or []
    console.print("  frequencies of the reduced model (Hz): " + ", ".join(f"{f:.4g}" for f in freqs))
    if payload.get("written"):
        console.print(f"  written: {payload['written']}")


def print_coupled_axes(payload: dict[str, Any]) -> None:
    """Print each axis's figures of ``sicomat simulate --coupled`` (the moving one and those holding)."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"coupled axes: axis {payload['axis']} moves, the others hold their position",
                  title_justify="left")
    table.add_column("axis")
    for col in ("max following error µm", "rms µm", "final µm"):
        table.add_column(col, justify="right")
    for axis, figures in payload["axes"].items():
        table.add_row(axis, *("-" if figures[key] is None else f"{figures[key] * 1e6:.4g}"
                              for key in ("max_following_error", "rms_following_error", "final_error")))
    print_table(Console(highlight=False), table)
