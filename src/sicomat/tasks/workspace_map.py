"""The mode map over the workspace of a ``[robot]`` machine (issue 13): how the first frequencies move as one
or two joints sweep a range, the other joints held at a base configuration.

Each point is the robot linearised there (:func:`sicomat.robotics.lowering.robot_mechanics`) and analysed as
``sicomat modal --q`` does: every motor locked and the gravity stiffness kept (the structure's own modes), or,
for an axis, the model its loop sees (that motor free, the others locked, gravity compensated:
:func:`~sicomat.robotics.lowering.axis_free_joints`). A point where the locked structure is unstable is
recorded as failed, not fatal. Decisions: ``docs/robotics.md``, "Workspace mode map".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..errors import AnalysisError, ModelError
from ..progress import notify

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..description.machine import Machine
    from ..description.robot import RobotSpec
    from ..progress import ProgressCallback

__all__ = ["JointSweep", "FailedPoint", "WorkspaceModeMap", "workspace_mode_map", "joint_sweep", "MAX_JOINTS",
           "MAX_GRID_POINTS"]

MAX_JOINTS = 2
"""Joints a map sweeps at most (a line, or a surface shown as a heat map)."""

MAX_GRID_POINTS = 10201
"""Most points a map takes in all (101 × 101; each is one linearisation and one modal analysis, ~2 ms on
the 12-joint robot)."""

_EXAMPLE = {"translational": "Y=0mm:400mm", "rotational": "A2=-90deg:90deg"}
_UNIT = {"translational": "length", "rotational": "angle"}
_SHOWN = {"translational": (1e3, "mm"), "rotational": (180.0 / math.pi, "deg")}


@dataclass(frozen=True)
class JointSweep:
    """One swept joint: its name, ``translational`` (prismatic, m) or ``rotational`` (revolute, rad), and its
    range in SI units, ``low < high``."""

    name: str
    kind: str
    low: float
    high: float


@dataclass(frozen=True)
class FailedPoint:
    """A point of the map without modes: its grid index, the swept joints' values there (SI) and why."""

    index: tuple[int, ...]
    values: tuple[float, ...]
    reason: str


@dataclass(frozen=True, eq=False)
class WorkspaceModeMap:
    """The first undamped modes of a robot machine over a grid of one or two joints.

    ``grid`` holds each swept joint's values (SI, both ends included); ``undamped_hz`` is shaped
    ``(len(grid[0]), [len(grid[1]),] modes)``, ascending along the last axis, NaN (JSON ``null``) at a failed
    point and where a point has fewer modes. ``configuration`` is the base (every joint, SI), ``locked`` the
    motors held, ``axis`` the axis whose model is mapped (``None``: every motor locked).
    """

    machine: str
    axis: str | None
    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    grid: tuple[np.ndarray, ...]
    undamped_hz: np.ndarray
    configuration: dict[str, float]
    locked: tuple[str, ...]
    failed: tuple[FailedPoint, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def modes(self) -> int:
        """Modes per point (the last axis of :attr:`undamped_hz`)."""
        return int(self.undamped_hz.shape[-1])

    @property
    def shape(self) -> tuple[int, ...]:
        """Points per swept joint."""
        return tuple(len(g) for g in self.grid)

    @property
    def position(self) -> np.ndarray:
        """The swept joints' values at every point, row-major, shape ``(points, joints)``."""
        mesh = np.meshgrid(*self.grid, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """:attr:`undamped_hz` flattened to one row per point (the rows of :attr:`position`)."""
        return self.undamped_hz.reshape(-1, self.modes)

    @property
    def _worst_index(self) -> tuple[int, ...] | None:
        first = self.undamped_hz[..., 0]
        if np.all(np.isnan(first)):
            return None
        return tuple(int(i) for i in np.unravel_index(int(np.nanargmin(first)), first.shape))

    @property
    def worst_position(self) -> tuple[float, ...] | None:
        """The swept joints' values where the first mode is lowest (the first such point on a tie)."""
        i = self._worst_index
        return None if i is None else tuple(float(g[k]) for g, k in zip(self.grid, i))

    @property
    def lowest_first_mode_hz(self) -> float | None:
        """The first mode at :attr:`worst_position` (Hz)."""
        i = self._worst_index
        return None if i is None else float(self.undamped_hz[i + (0,)])

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat modemap --joint ... --json`` contract: the keys of the drive-chain map where they mean
        the same (``axis``, ``modes``, ``position``, ``frequencies_hz``, ``worst_position``,
        ``lowest_first_mode_hz``, ``notes``; with one joint a position is its value, with two the pair) and
        ``machine``, ``joints``, ``units``, ``grid``, ``undamped_hz`` (shaped as the grid, then modes),
        ``configuration``, ``locked``, ``failed`` (``position``, ``index``, ``reason`` per failed point)."""
        one = len(self.joints) == 1

        def point(values: Sequence[float]) -> Any:
            return float(values[0]) if one else [float(v) for v in values]

        worst = self.worst_position
        return {"machine": self.machine, "axis": self.axis, "joints": list(self.joints),
                "units": ["m" if k == "translational" else "rad" for k in self.kinds],
                "grid": [[float(v) for v in g] for g in self.grid], "modes": self.modes,
                "configuration": dict(self.configuration), "locked": list(self.locked),
                "position": [point(p) for p in self.position],
                "frequencies_hz": [[_finite(f) for f in row] for row in self.frequencies_hz],
                "undamped_hz": _nested(self.undamped_hz),
                "worst_position": None if worst is None else point(worst),
                "lowest_first_mode_hz": self.lowest_first_mode_hz,
                "failed": [{"position": point(f.values), "index": list(f.index), "reason": f.reason}
                           for f in self.failed],
                "notes": list(self.notes)}

    def plot(self) -> "Figure":
        """One joint: each mode against the joint (mm or deg); two: a heat map of the first mode (and of the
        second beside it) over the grid. The worst point marked, failed points crossed."""
        from ..plots.modemap import plot_workspace_map

        return plot_workspace_map(self)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _nested(values: np.ndarray) -> Any:
    if values.ndim == 1:
        return [_finite(v) for v in values]
    return [_nested(v) for v in values]


# --------------------------------------------------------------------------- the joints and their ranges
def joint_sweep(spec: "RobotSpec", text: str) -> JointSweep:
    """``NAME=LOW:HIGH`` read against the robot: a joint (not a fixed frame) and its range with units
    (``Y=0mm:400mm``, ``A2=-90deg:90deg``), ``LOW < HIGH``. A bare number is refused: ``-90:90`` read in
    SI would sweep 28 turns of a revolute joint. The model file gives a robot's joints no travel limits,
    so the range is required. Errors name the parameter ``joint``."""
    name, sep, span = str(text).partition("=")
    name = name.strip()
    names = spec.joint_names
    if name not in names:
        fixed = [spec.frame_name(row) for row in range(len(spec.frames)) if row not in spec.joint_rows]
        if name in fixed:
            raise ModelError(f"{name!r} is a fixed frame (sigma = 2): it has no joint variable to sweep; "
                             f"expected one of {', '.join(names)}", path="joint", value=text)
        raise ModelError(f"unknown joint {name!r}; expected one of {', '.join(names)}", path="joint", value=text)
    kind = spec.joint_kind(name)
    example = _EXAMPLE[kind].replace(_EXAMPLE[kind].split("=")[0], name, 1)
    if not sep:
        raise ModelError(f"joint {name}: give its range, NAME=LOW:HIGH with units (e.g. {example}); the model "
                         "file gives a robot's joints no travel limits to default to", path="joint", value=text)
    low_text, colon, high_text = span.partition(":")
    if not colon or not low_text.strip() or not high_text.strip():
        raise ModelError(f"joint {name}: expected NAME=LOW:HIGH with units (e.g. {example})", path="joint",
                         value=text)
    ends = [_end(name, kind, part.strip(), example, text) for part in (low_text, high_text)]
    if not ends[0] < ends[1]:
        raise ModelError(f"joint {name}: expected LOW < HIGH (got {ends[0]:g} to {ends[1]:g} in SI)", path="joint",
                         value=text)
    return JointSweep(name, kind, ends[0], ends[1])


def _end(name: str, kind: str, text: str, example: str, raw: str) -> float:
    from ..description.units import UNITS, parse_quantity

    joint = "prismatic" if kind == "translational" else "revolute"
    try:
        float(text)
    except ValueError:
        pass
    else:
        raise ModelError(f"joint {name}: {text!r} has no unit; give LOW and HIGH with units (e.g. {example}): a "
                         f"bare number would be read in SI", path="joint", value=raw)
    try:
        return parse_quantity(text, UNITS[_UNIT[kind]])
    except ValueError as exc:
        raise ModelError(f"joint {name} ({joint}): {text!r}: {exc}", path="joint", value=raw) from None


def _grid(sweep: JointSweep, points: int) -> np.ndarray:
    """``points`` evenly spaced values from ``low`` to ``high``, both ends exactly as given. The inner ones are
    spaced in mm or deg, rounded to 12 significant digits and read as ``"<value> mm"`` / ``"<value> deg"``
    would be (so -60 deg on the grid is the -60 deg of a model file's configuration or of ``--q``, not a
    value 1e-11 away); a rounding-level zero is 0."""
    from ..description.units import UNITS, parse_quantity

    scale, unit = _SHOWN[sweep.kind]
    shown = np.linspace(sweep.low * scale, sweep.high * scale, points)
    tiny = 1e-9 * max(abs(sweep.low), abs(sweep.high)) * scale
    inner = [0.0 if abs(v) < tiny else parse_quantity(f"{v:.12g} {unit}", UNITS[_UNIT[sweep.kind]])
             for v in shown[1:-1]]
    return np.array([sweep.low, *inner, sweep.high])


def _count(value: Any, name: str, least: int, most: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not least <= value <= most:
        raise ModelError(f"expected a whole number from {least} to {most}", path=name, value=value)
    return int(value)


# --------------------------------------------------------------------------- the map
def workspace_mode_map(machine: "Machine", joints: Sequence[str], points: int = 21, modes: int = 3, *,
                       q: Any = None, axis: str | None = None,
                       progress: "ProgressCallback | None" = None) -> WorkspaceModeMap:
    """The first ``modes`` undamped frequencies of a robot machine over a grid of one or two joints.

    Parameters
    ----------
    machine : Machine
        A machine with a ``[robot]`` section.
    joints : sequence of str
        One or two ``NAME=LOW:HIGH`` (:func:`joint_sweep`), distinct joints.
    points : int
        Values per joint, both ends included (at most :data:`MAX_GRID_POINTS` points in all).
    modes : int
        Modes kept per point (fewer columns when no point has that many).
    q : str or sequence, optional
        The base configuration: every joint in frame order, SI numbers or quantities with units
        (:func:`sicomat.tasks.robot.joint_values`); default the model's ``configuration``.
    axis : str, optional
        Map that axis's decoupled model (its motor free, the others locked, gravity compensated) instead of
        the structure with every motor locked (gravity stiffness kept). Rigid modes are left out.

    Raises
    ------
    ModelError
        No ``[robot]`` section, bad joints, ranges, counts or configuration, an unknown axis, a robot with no
        joint left once its motors are locked.
    AnalysisError
        Every point failed (e.g. the locked structure unstable everywhere), or no point has a mode.
    """
    from ..robotics.lowering import axis_free_joints, configuration
    from .robot import joint_values

    if machine.robot is None:
        raise ModelError("a workspace mode map sweeps the joints of a [robot] machine; this model has no [robot] "
                         "section (a drive-chain axis is mapped over its stroke, with no joints given)",
                         path="joint" if joints else "q", value=list(joints) if joints else q)
    spec = machine.robot
    if not joints:
        raise ModelError("a [robot] machine's mode map sweeps its joints over the workspace: give one or two "
                         f"joints with their ranges, NAME=LOW:HIGH (joints: {', '.join(spec.joint_names)})",
                         path="joint", value=None)
    if len(joints) > MAX_JOINTS:
        raise ModelError(f"expected 1 or {MAX_JOINTS} joints to sweep, got {len(joints)}", path="joint",
                         value=list(joints))
    sweeps = [joint_sweep(spec, text) for text in joints]
    if len({s.name for s in sweeps}) < len(sweeps):
        raise ModelError(f"joint {sweeps[0].name} is given twice; sweep two different joints", path="joint",
                         value=list(joints))
    most = MAX_GRID_POINTS if len(sweeps) == 1 else math.isqrt(MAX_GRID_POINTS)
    points = _count(points, "points", 2, min(most, MAX_GRID_POINTS))
    modes = _count(modes, "modes", 1, 1000)
    name = None if axis is None else machine.axis_name(axis)
    base = configuration(spec, None if q is None else joint_values(spec, q, "q"))
    free = axis_free_joints(spec, name)
    if name is None and not free:
        raise ModelError("the robot has no joint left once its motors are locked (no elastic joint): it has no "
                         "modes of its own; give an axis to map its model", path="robot.frames")
    grid = tuple(_grid(s, points) for s in sweeps)
    shape = tuple(len(g) for g in grid)
    index_of = [spec.joint_names.index(s.name) for s in sweeps]
    total = int(np.prod(shape))
    rows: list[list[float]] = []
    failed: list[FailedPoint] = []
    task = f"mode map, {' x '.join(str(n) for n in shape)} configurations"
    notify(progress, task, 0, total)
    for done, index in enumerate(np.ndindex(*shape)):
        q_point = base.copy()
        values = tuple(float(g[k]) for g, k in zip(grid, index))
        q_point[index_of] = values
        try:
            rows.append(_modes_at(spec, q_point, free, name)[:modes])
        except ModelError as exc:
            rows.append([])
            failed.append(FailedPoint(tuple(int(k) for k in index), values, exc.message))
        notify(progress, task, done + 1, total)
    if len(failed) == total:
        raise AnalysisError(f"no point of the map has modes: every configuration failed (the first: "
                            f"{failed[0].reason})")
    width = max(len(r) for r in rows)
    if width == 0:
        raise AnalysisError("no point of the map has a flexible mode (every joint left free is rigid); nothing "
                            "to map")
    table = np.full((total, width), np.nan)
    for i, row in enumerate(rows):
        table[i, :len(row)] = row
    failed_at = {f.index for f in failed}
    notes = [f"{_where(sweeps, values)}: {len(row)} of {width} modes (the free joints have fewer there)"
             for index, values, row in zip(np.ndindex(*shape), _values(grid, shape), rows)
             if 0 < len(row) < width and tuple(index) not in failed_at]
    if failed:
        notes.insert(0, f"{len(failed)} of {total} configurations failed (their frequencies are null; see "
                        "'failed')")
    locked = tuple(m for m in spec.motor_names if m not in free)
    return WorkspaceModeMap(machine.name, name, tuple(s.name for s in sweeps), tuple(s.kind for s in sweeps), grid,
                            table.reshape(shape + (width,)), dict(zip(spec.joint_names, base.tolist())), locked,
                            tuple(failed), tuple(notes))


def _values(grid: tuple[np.ndarray, ...], shape: tuple[int, ...]):
    for index in np.ndindex(*shape):
        yield tuple(float(g[k]) for g, k in zip(grid, index))


def _where(sweeps: list[JointSweep], values: Sequence[float]) -> str:
    return ", ".join(f"{s.name} = {v:g} {'m' if s.kind == 'translational' else 'rad'}" for s, v in zip(sweeps, values))


def _modes_at(spec: "RobotSpec", q: np.ndarray, free: list[str], axis: str | None) -> list[float]:
    """The undamped flexible frequencies (Hz, ascending) at ``q``: the lowering and the analysis of
    ``sicomat modal --q`` (motors locked, gravity stiffness kept) or of ``modal --axis`` (gravity compensated)."""
    from ..mechanics.conditioning import check_resolvable
    from ..mechanics.modal import modal_analysis
    from ..robotics.lowering import robot_mechanics

    mech = robot_mechanics(spec, q, free=free, actuators=() if axis is None else None, gravity=axis is None)
    check_resolvable(mech)
    return sorted(float(m.undamped_hz) for m in modal_analysis(mech).modes if not m.rigid)
