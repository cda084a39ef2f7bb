"""Rich tables for the terminal, read from result objects."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from ..mechanics import Mechanics
    from ..modal import ModalResult
    from ..model import Machine

__all__ = ["check_payload", "print_check", "print_modal"]


def check_payload(machine: "Machine", mechanics: dict[str, "Mechanics"]) -> dict[str, Any]:
    """The ``sicomat check --json`` object: the machine's axes as lumped models (SI units)."""
    axes = {}
    for name, mech in mechanics.items():
        axes[name] = {
            "mechanics_type": machine.axes[name].mechanics.type,
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
    return {"valid": True, "name": machine.name, "axes": axes}


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
        console.print(table)


def print_modal(axis: str, result: "ModalResult") -> None:
    """Print the modes of ``sicomat modal``."""
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
    table = Table(title=f"axis {axis}: modes", title_justify="left")
    for col in ("mode", "f (Hz)", "zeta", "f damped (Hz)", "f undamped (Hz)", "dominant dof", "participation"):
        table.add_column(col, justify="right")
    for k, m in enumerate(result.modes, 1):
        if m.rigid:
            table.add_row(str(k), "0 (rigid)", "-", "-", "0", m.dominant_dof, "-")
        else:
            table.add_row(str(k), f"{m.frequency_hz:.4f}", f"{m.damping_ratio:.3g}",
                          f"{m.damped_frequency_hz:.4f}", f"{m.undamped_hz:.4f}", m.dominant_dof,
                          f"{100 * m.participation:.1f} %")
    console.print(table)
    shapes = Table(title="mode shapes (largest component = 1)", title_justify="left")
    shapes.add_column("dof")
    for k in range(len(result.modes)):
        shapes.add_column(f"{k + 1}", justify="right")
    for d in result.dofs:
        shapes.add_row(d, *(f"{m.shape[d]:+.3f}" for m in result.modes))
    console.print(shapes)
    if result.f_meca_hz is not None:
        console.print(f"suggested f_meca = {result.f_meca_hz:.4g} Hz (first flexible mode the loop sees)")
