"""``sicomat tune --all-positions`` (issue 12, §4): tune where the axis is softest, then check the margins
at every position of the mode map.

The frequency approach (:func:`sicomat.tuning.frequency.tune_frequency`) tunes the loop with the table at
the mode map's worst position (lowest first flexible mode); the tuned gains (and the notch, if applied)
are then analysed at every mapped position exactly as ``sicomat margins`` does with those gains
(:func:`sicomat.tasks.analysis.margins_payload`), and every margin below its target is reported with its
position. The decisions are in ``docs/components.md``, "Mode map".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from ..progress import notify
from .modemap import ModeMap, machine_at, mode_map

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from ..progress import ProgressCallback
    from ..servo.loop import ServoLoop
    from ..tuning.frequency import TuningResult, TuningTargets

__all__ = ["PositionMargins", "StrokeTuning", "tune_over_stroke", "position_margins"]


@dataclass(frozen=True)
class PositionMargins:
    """The tuned loop's margins with the table at ``position`` (m), as ``sicomat margins`` reports them:
    each loop's worst phase margin over all its gain crossovers and its gain margin (smallest |GM|), the
    stability verdict of the cascade, and the first flexible mode there."""

    position: float
    first_mode_hz: float | None
    velocity_phase_margin_deg: float
    velocity_gain_margin_db: float
    position_phase_margin_deg: float
    position_gain_margin_db: float
    stable: bool | None
    warnings: tuple[str, ...] = ()

    @property
    def phase_margin_deg(self) -> float:
        """The velocity loop's phase margin: the one a resonance erodes and ``--velocity-phase-margin`` sets."""
        return self.velocity_phase_margin_deg

    @property
    def gain_margin_db(self) -> float:
        """The smaller gain margin of the two loops (as ``tune``'s ``achieved.gain_margin_db``)."""
        return min(self.velocity_gain_margin_db, self.position_gain_margin_db)

    def to_dict(self) -> dict[str, Any]:
        """One entry of ``"positions"``."""
        return {"position": self.position, "first_mode_hz": self.first_mode_hz,
                "phase_margin_deg": _finite(self.phase_margin_deg), "gain_margin_db": _finite(self.gain_margin_db),
                "velocity_phase_margin_deg": _finite(self.velocity_phase_margin_deg),
                "velocity_gain_margin_db": _finite(self.velocity_gain_margin_db),
                "position_phase_margin_deg": _finite(self.position_phase_margin_deg),
                "position_gain_margin_db": _finite(self.position_gain_margin_db),
                "stable": self.stable, "warnings": list(self.warnings)}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True, eq=False)
class StrokeTuning:
    """A tuning that holds over the stroke: the tuning at :attr:`tuned_position` (``result``; ``chosen`` the
    one whose gains are reported, with the notch when it was applied), the mode map, and the margins at
    every mapped position."""

    result: "TuningResult"
    chosen: "TuningResult"
    map: ModeMap
    tuned_position: float
    positions: tuple[PositionMargins, ...]

    def _lowest(self, key) -> PositionMargins:
        values = [p for p in self.positions if math.isfinite(key(p))]
        return min(values, key=key) if values else self.positions[0]

    @property
    def worst(self) -> PositionMargins:
        """The position with the smallest phase margin of the velocity loop."""
        return self._lowest(lambda p: p.phase_margin_deg)

    @property
    def lowest_gain_margin(self) -> PositionMargins:
        """The position with the smallest gain margin (of either loop)."""
        return self._lowest(lambda p: p.gain_margin_db)

    @property
    def unmet(self) -> tuple[str, ...]:
        """Each margin below its target (the tolerance of the tuning: ``tolerance_deg``, 0.05 dB), with
        its position; an unstable position."""
        t = self.chosen.targets
        out = []
        for p in self.positions:
            where = f"at position {p.position:g} m"
            if p.stable is False:
                out.append(f"{where}: the tuned loop is unstable")
            if not p.velocity_phase_margin_deg >= t.velocity_phase_margin - t.tolerance_deg:
                out.append(f"{where}: velocity phase margin {p.velocity_phase_margin_deg:.1f}° below "
                           f"{t.velocity_phase_margin:g}°")
            if t.position_phase_margin is not None and \
                    not p.position_phase_margin_deg >= t.position_phase_margin - t.tolerance_deg:
                out.append(f"{where}: position phase margin {p.position_phase_margin_deg:.1f}° below "
                           f"{t.position_phase_margin:g}°")
            if not p.gain_margin_db >= t.min_gain_margin - 0.05:
                out.append(f"{where}: gain margin {p.gain_margin_db:.1f} dB below {t.min_gain_margin:g} dB")
        return tuple(out)

    @property
    def stable(self) -> bool | None:
        """False if the tuned loop is unstable at some position, None if unknown somewhere, else True."""
        verdicts = [p.stable for p in self.positions]
        if False in verdicts:
            return False
        return None if None in verdicts else True

    def to_dict(self) -> dict[str, Any]:
        """The keys ``tune --all-positions`` adds to the ``tune`` payload."""
        worst, low_gm = self.worst, self.lowest_gain_margin
        return {"tuned_position": self.tuned_position, "positions": [p.to_dict() for p in self.positions],
                "worst_position": worst.position, "min_phase_margin_deg": _finite(worst.phase_margin_deg),
                "min_gain_margin_db": _finite(low_gm.gain_margin_db), "min_gain_margin_position": low_gm.position,
                "lowest_first_mode_hz": self.map.lowest_first_mode_hz,
                "targets_met_all_positions": not self.unmet, "unmet_positions": list(self.unmet)}

    def update_payload(self, payload: dict[str, Any]) -> dict[str, Any]:
        """``payload`` (the ``tune`` JSON of :attr:`chosen`) with these keys, the unmet margins among its
        warnings and ``stable`` false when a position is unstable."""
        payload.update(self.to_dict())
        payload["warnings"] = [*payload.get("warnings", []), *(f"not met {u}" for u in self.unmet)]
        if self.stable is False or payload.get("stable") is False:
            payload["stable"] = False
        elif self.stable is None:
            payload["stable"] = None
        return payload


def position_margins(loop: "ServoLoop", position: float, first_mode_hz: float | None) -> PositionMargins:
    """The margins of ``loop`` (its gains and controller as they are), as ``sicomat margins`` computes them."""
    from ..frequency.loops import LoopAnalysis
    from ..frequency.margins import stability_margins
    from .analysis import margins_payload

    an = LoopAnalysis.of(loop)
    velocity = stability_margins(an.response("velocity-open"))
    position_loop = stability_margins(an.response("position-open"))
    payload = margins_payload(loop, an, velocity, position_loop)
    return PositionMargins(position, first_mode_hz, velocity.phase_margin_deg, velocity.gain_margin_db,
                           position_loop.phase_margin_deg, position_loop.gain_margin_db, payload["stable"],
                           tuple(payload["warnings"]))


def tune_over_stroke(machine: "Machine", axis: str | None, targets: "TuningTargets | None" = None, *,
                     points: int = 21, apply_notch: bool = False,
                     progress: "ProgressCallback | None" = None) -> StrokeTuning:
    """Tune the axis (frequency approach) at its mode map's worst position, then analyse the tuned loop at
    every mapped position.

    ``apply_notch``: when the tuning suggests a notch, check (and report) the tuning with it, as
    ``tune --apply-notch`` does.
    """
    from ..servo.loop import build_servo_loop
    from ..tuning.frequency import tune_frequency

    modes = mode_map(machine, axis, points, progress=progress)
    name = modes.axis
    tuned_at = modes.worst_position
    if tuned_at is None:  # pragma: no cover - mode_map raises when no position has a flexible mode
        tuned_at = float(modes.position[0])
    result = tune_frequency(build_servo_loop(machine_at(machine, name, tuned_at), name), targets, progress=progress)
    chosen = result.with_notch if apply_notch and result.with_notch is not None else result
    gains, controller = chosen.tuned, chosen.loop.controller
    checked = []
    task = f"margins at {len(modes.position)} positions"
    notify(progress, task, 0, len(modes.position))
    for i, (x, row) in enumerate(zip(modes.position, modes.frequencies_hz)):
        loop = build_servo_loop(machine_at(machine, name, float(x)), name)
        loop = replace(loop, controller=controller).with_gains(Kp=gains.Kp, Ti=gains.Ti, Kv=gains.Kv)
        checked.append(position_margins(loop, float(x), _finite(float(row[0]))))
        notify(progress, task, i + 1, len(modes.position))
    return StrokeTuning(result, chosen, modes, tuned_at, tuple(checked))
