"""The mode map over the stroke (issue 12, §4): how the first flexible modes of a ``components`` drive
chain move as the table travels.

Each position is the machine with ``axes.X.mechanics.position`` set (:func:`machine_at`, validated like a
file), its mechanics analysed as ``sicomat modal`` does; the map keeps the undamped frequencies of the
free mechanics, rigid modes left out. The decisions (ends of the stroke, axes without a stroke) are in
``docs/components.md``, "Mode map".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import AnalysisError, ModelError
from ..progress import notify

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..description.machine import Machine
    from ..progress import ProgressCallback

__all__ = ["ModeMap", "mode_map", "machine_at", "map_stroke", "MAX_POINTS"]

MAX_POINTS = 2001
"""Most positions a map takes (each is one validated model and one modal analysis, ~2-30 ms)."""


@dataclass(frozen=True, eq=False)
class ModeMap:
    """The first flexible modes at evenly spaced positions over the stroke.

    ``position`` (m, from the motor-side end, both ends included), ``frequencies_hz`` one row per
    position, the first ``modes`` undamped flexible frequencies ascending, NaN (JSON ``null``) where a
    position has fewer (at an end where a spring becomes infinite, the chain loses a body and its mode).
    """

    axis: str
    stroke: float
    position: np.ndarray
    frequencies_hz: np.ndarray
    notes: tuple[str, ...] = ()

    @property
    def modes(self) -> int:
        """Columns of :attr:`frequencies_hz` (the flexible modes mapped)."""
        return int(self.frequencies_hz.shape[1])

    @property
    def _worst_index(self) -> int | None:
        first = self.frequencies_hz[:, 0]
        return None if np.all(np.isnan(first)) else int(np.nanargmin(first))

    @property
    def worst_position(self) -> float | None:
        """Where the first flexible mode is lowest (m); the first such position on a tie."""
        i = self._worst_index
        return None if i is None else float(self.position[i])

    @property
    def lowest_first_mode_hz(self) -> float | None:
        """The first flexible mode at :attr:`worst_position` (Hz)."""
        i = self._worst_index
        return None if i is None else float(self.frequencies_hz[i, 0])

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat modemap --json`` contract: ``position``, ``frequencies_hz``, ``worst_position``,
        ``lowest_first_mode_hz``; besides them ``axis``, ``stroke``, ``modes`` and ``notes``."""
        return {"axis": self.axis, "stroke": self.stroke, "modes": self.modes,
                "position": [float(x) for x in self.position],
                "frequencies_hz": [[_finite(f) for f in row] for row in self.frequencies_hz],
                "worst_position": self.worst_position, "lowest_first_mode_hz": self.lowest_first_mode_hz,
                "notes": list(self.notes)}

    def plot(self) -> "Figure":
        """f1…fn against the position (mm), the worst position marked; the matplotlib ``Figure``."""
        from ..plots.modemap import plot_mode_map

        return plot_mode_map(self)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


# --------------------------------------------------------------------------- the axis and its stroke
def map_stroke(machine: "Machine", axis: str | None = None) -> tuple[str, float]:
    """The axis's name and the stroke (m) its table travels over; a located :class:`ModelError` when the
    axis has no position to vary: not a ``components`` chain, a linear motor, a rack and pinion (the
    mesh travels with the pinion: the modes are the same everywhere, ``sicomat modal`` gives them), a
    belt without ``length``, or detail ``rigid`` (no compliance, no mode)."""
    from ..description.components import ComponentsSpec

    name = machine.axis_name(axis)
    spec = machine.axes[name].mechanics
    where = f"axes.{name}.mechanics"
    if not isinstance(spec, ComponentsSpec):
        raise ModelError("a mode map moves the table of a 'components' drive chain over its stroke; this axis's "
                         "mechanics has no position to vary (its modes: sicomat modal)", path=f"{where}.type",
                         value=spec.type if spec is not None else "robot")
    if spec.detail == "rigid":
        raise ModelError("detail 'rigid' keeps no compliance, so there is no mode to map; choose 'full', "
                         "'2-mass' or 'auto'", path=f"{where}.detail", value=spec.detail)
    motor = spec.parts[0]
    if motor.kind == "linear-motor":
        raise ModelError("a linear motor drives the table directly: no part's stiffness depends on the position, "
                         "so the modes are the same over the stroke (sicomat modal gives them)",
                         path=f"{where}.parts.0.kind", value=motor.kind)
    index, part = next((i, p) for i, p in enumerate(spec.parts) if p.kind in ("ball-screw", "belt", "rack-pinion"))
    if part.kind == "rack-pinion":
        raise ModelError("a rack and pinion meshes at the pinion wherever the table is: no stiffness depends on "
                         "the position, so the modes are the same over the stroke (sicomat modal gives them)",
                         path=f"{where}.parts.{index}.kind", value=part.kind)
    stroke = spec.stroke()
    if stroke is None:
        raise ModelError("the belt has no length, so its spans (and the position) are not defined; give the "
                         "belt's 'length' (centre distance, or clamp distance of an omega drive)",
                         path=f"{where}.parts.{index}.length", value=None)
    return name, stroke


def machine_at(machine: "Machine", axis: str, position: float) -> "Machine":
    """The machine with the axis's table at ``position`` (m): ``axes.<axis>.mechanics.position`` set and
    the whole model validated again, as ``--set`` does (:func:`sicomat.io.modelfile.with_overrides`)."""
    from ..io.modelfile import with_overrides

    return with_overrides(machine, {f"axes.{axis}.mechanics.position": float(position)})


def _check_count(value: Any, name: str, least: int, most: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not least <= value <= most:
        raise ModelError(f"expected a whole number from {least} to {most}", path=name, value=value)
    return int(value)


def map_positions(stroke: float, points: int) -> np.ndarray:
    """``points`` evenly spaced positions from 0 to ``stroke``, both ends exactly, each rounded to 12
    significant digits (``0.9``, not ``0.8999999999999999``: the numbers a user types in ``--set``; 1e-12
    relative moves nothing physical).

    >>> map_positions(1.2, 5).tolist()
    [0.0, 0.3, 0.6, 0.9, 1.2]
    """
    positions = np.array([float(f"{x:.12g}") for x in np.linspace(0.0, stroke, points)])
    positions[-1] = stroke
    return positions


# --------------------------------------------------------------------------- the map
def mode_map(machine: "Machine", axis: str | None = None, points: int = 21, modes: int = 3, *,
             progress: "ProgressCallback | None" = None) -> ModeMap:
    """The first ``modes`` flexible modes of the axis at ``points`` positions over its stroke.

    Raises
    ------
    ModelError
        ``points`` below 2 (or above :data:`MAX_POINTS`), ``modes`` below 1, or an axis without a position
        to vary (:func:`map_stroke`); a model that cannot be built at an inner position.
    AnalysisError
        No position has a flexible mode.
    """
    points = _check_count(points, "points", 2, MAX_POINTS)
    modes = _check_count(modes, "modes", 1, 1000)
    name, stroke = map_stroke(machine, axis)
    positions = map_positions(stroke, points)
    rows: list[list[float]] = []
    notes: list[str] = []
    task = f"mode map, {points} positions"
    notify(progress, task, 0, points)
    for i, x in enumerate(positions):
        rows.append(_flexible_at(machine, name, float(x), end=i in (0, points - 1))[:modes])
        notify(progress, task, i + 1, points)
    width = max(len(r) for r in rows)
    if width == 0:
        raise AnalysisError(f"axis {name}: no flexible mode at any position (every compliance of the chain is "
                            "merged: detail 'auto' with a bandwidth too low?); nothing to map")
    table = np.full((points, width), np.nan)
    for i, row in enumerate(rows):
        table[i, :len(row)] = row
    why = ("a spring of infinite stiffness there, e.g. a screw segment or belt span of zero length, or one that "
           "detail 'auto' made rigid there" if getattr(machine.axes[name].mechanics, "detail", None) == "auto" else
           "a spring of infinite stiffness there, e.g. a screw segment or belt span of zero length")
    for x, row in zip(positions, rows):
        if 0 < len(row) < width:
            notes.append(f"position {x:g} m: {len(row)} of {width} flexible modes ({why}: the chain has a body "
                         "less; the missing frequencies are null)")
        elif not row:
            notes.append(f"position {x:g} m: no flexible mode (every compliance of the chain is infinite there; "
                         "the frequencies are null)")
    return ModeMap(name, stroke, positions, table, tuple(notes))


def _flexible_at(machine: "Machine", axis: str, x: float, *, end: bool) -> list[float]:
    """The undamped flexible frequencies (Hz, ascending) of the axis's mechanics at position ``x``."""
    from ..mechanics.lumped import check_axis_mechanics
    from ..mechanics.modal import modal_analysis

    try:
        moved = machine_at(machine, axis, x)
    except ModelError:
        if end and _rigid_at(machine, axis, x):
            return []
        raise
    result = modal_analysis(check_axis_mechanics(axis, moved.axes[axis].mechanics))
    return sorted(float(m.undamped_hz) for m in result.modes if not m.rigid)


def _rigid_at(machine: "Machine", axis: str, x: float) -> bool:
    """Whether the chain keeps no spring at ``x`` in detail ``full`` (then detail '2-mass' refuses it:
    an end where the one compliance, a belt span, has zero length)."""
    from ..description.components import ComponentsSpec
    from ..io.modelfile import with_overrides

    try:
        full = with_overrides(machine, {f"axes.{axis}.mechanics.position": x,
                                        f"axes.{axis}.mechanics.detail": "full"})
    except ModelError:
        return False
    spec = full.axes[axis].mechanics
    return isinstance(spec, ComponentsSpec) and not spec.chain.springs
