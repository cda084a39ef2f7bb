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

__all__ = ["PositionMargins", "StrokeTuning", "tune_over_stroke", "position_margins", "ROUNDS"]


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

    def shortfall(self, targets: "TuningTargets") -> float:
        """How far the worst margin here falls short of its target, relative to it (``(target − value)/target``,
        the largest over the velocity and position phase margins and the gain margin; negative when every
        margin is above its target; infinite when the loop is unstable)."""
        if self.stable is False:
            return math.inf
        terms = [(targets.velocity_phase_margin - self.velocity_phase_margin_deg) / targets.velocity_phase_margin,
                 (targets.min_gain_margin - self.gain_margin_db) / targets.min_gain_margin]
        if targets.position_phase_margin is not None:
            terms.append((targets.position_phase_margin - self.position_phase_margin_deg) / targets.position_phase_margin)
        terms = [t if not math.isnan(t) else math.inf for t in terms]
        return max(terms)

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
    attempts: tuple["StrokeTuning", ...] = ()

    @property
    def shortfall(self) -> float:
        """The largest relative shortfall of a margin over the positions (:meth:`PositionMargins.shortfall`):
        what the choice between attempts minimises."""
        return max(p.shortfall(self.chosen.targets) for p in self.positions)

    @property
    def shortest(self) -> PositionMargins:
        """The position whose margins fall shortest of their targets."""
        return max(self.positions, key=lambda p: p.shortfall(self.chosen.targets))

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
        attempts = [{"tuned_position": a.tuned_position, "shortfall": _finite(a.shortfall), "stable": a.stable,
                     "unmet": len(a.unmet), "chosen": a.tuned_position == self.tuned_position}
                    for a in (self.attempts or (self,))]
        return {"tuned_position": self.tuned_position, "attempts": attempts,
                "positions": [p.to_dict() for p in self.positions],
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


ROUNDS = 3
"""Most positions ``tune --all-positions`` tunes at (the softest first, then where the margins fell shortest)."""


def tune_over_stroke(machine: "Machine", axis: str | None, targets: "TuningTargets | None" = None, *,
                     points: int = 21, apply_notch: bool = False, rounds: int = ROUNDS,
                     progress: "ProgressCallback | None" = None) -> StrokeTuning:
    """Tune the axis (frequency approach) where its margins hold over the stroke.

    First at the mode map's worst position (lowest first mode), then the tuned loop is analysed at every
    mapped position. If a margin falls short somewhere, the tuning is repeated with the table where the
    margins fell shortest (the same targets, the velocity crossover that of the first tuning), up to
    ``rounds`` positions; of these attempts the one whose worst relative shortfall over the stroke is
    smallest is returned (:attr:`StrokeTuning.shortfall`; the first on a tie), with all attempts in
    :attr:`StrokeTuning.attempts`.

    ``apply_notch``: when the tuning suggests a notch, check (and report) the tuning with it, as
    ``tune --apply-notch`` does.
    """
    modes = mode_map(machine, axis, points, progress=progress)
    at = modes.worst_position
    if at is None:  # pragma: no cover - mode_map raises when no position has a flexible mode
        at = float(modes.position[0])
    attempts: list[StrokeTuning] = []
    while True:
        attempt = _attempt(machine, modes, at, targets, apply_notch, progress)
        attempts.append(attempt)
        targets = attempt.result.targets            # the resolved targets: the first tuning's crossover
        at = attempt.shortest.position
        if not attempt.unmet or len(attempts) >= rounds or at in [a.tuned_position for a in attempts]:
            break
    best = min(attempts, key=lambda a: a.shortfall)       # min keeps the first of equals
    return replace(best, attempts=tuple(attempts))


def _attempt(machine: "Machine", modes: ModeMap, at: float, targets: "TuningTargets | None", apply_notch: bool,
             progress: "ProgressCallback | None") -> StrokeTuning:
    """Tune with the table at ``at``, then analyse the tuned loop at every position of ``modes``."""
    from ..servo.loop import build_servo_loop
    from ..tuning.frequency import tune_frequency

    name = modes.axis
    result = tune_frequency(build_servo_loop(machine_at(machine, name, at), name), targets, progress=progress)
    chosen = result.with_notch if apply_notch and result.with_notch is not None else result
    gains, controller = chosen.tuned, chosen.loop.controller
    checked = []
    task = f"margins at {len(modes.position)} positions (tuned at {at:g} m)"
    notify(progress, task, 0, len(modes.position))
    for i, (x, row) in enumerate(zip(modes.position, modes.frequencies_hz)):
        loop = build_servo_loop(machine_at(machine, name, float(x)), name)
        loop = replace(loop, controller=controller).with_gains(Kp=gains.Kp, Ti=gains.Ti, Kv=gains.Kv)
        checked.append(position_margins(loop, float(x), _finite(float(row[0]))))
        notify(progress, task, i + 1, len(modes.position))
    return StrokeTuning(result, chosen, modes, at, tuple(checked))
