"""A study's analysis settings (``[tune]``, ``[simulate]``, ``[circle]``, ``[size]``) in SI units, and the checks
that the base model can run the analyses asked for, both made on the client before any work."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import ModelError, SicomatError

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from .spec import StudySpec

__all__ = ["StudyOptions", "analysis_options", "check_analyses"]


@dataclass(frozen=True)
class StudyOptions:
    """The analyses' settings in SI units (parsed once, on the client, from the study file)."""

    analyses: tuple[str, ...]
    axis: str
    tune: dict[str, float | None] = field(default_factory=dict)
    move: float | None = None
    max_velocity: float | None = None
    max_acceleration: float | None = None
    duration: float | None = None
    circle_radius: float = 0.02
    circle_feed: float = 1 / 6
    circle_model: str | None = None
    size_move: float | None = None
    inertia_ratio_limit: float = 10.0


def analysis_options(spec: "StudySpec", axis: str, source: str) -> StudyOptions:
    """The study's ``[tune]``, ``[simulate]``, ``[circle]``, ``[size]`` tables in SI; a :class:`ModelError`
    names the key of a value that does not parse."""
    from ..description.units import UNITS, Unit, parse_quantity

    def si(table: str, key: str, value: Any, unit: Unit) -> float | None:
        if value is None:
            return None
        try:
            return parse_quantity(value, unit)
        except ValueError as exc:
            raise ModelError(str(exc), source=source, path=f"{table}.{key}", value=value) from None

    def positive(table: str, key: str, value: float | None, given: Any) -> None:
        """As the commands' options: a limit, crossover, duration, radius or feed is > 0 when given."""
        if value is not None and not value > 0:
            raise ModelError(f"expected a {key} > 0", source=source, path=f"{table}.{key}", value=given)

    angular = Unit("rad/s", "an angular frequency (rad/s, or Hz)")
    degrees = Unit("", "an angle in degrees (a plain number)")
    decibels = Unit("", "a gain in dB (a plain number)")
    t = spec.tune
    tune = {"velocity_crossover": si("tune", "velocity_crossover", t.velocity_crossover, angular),
            "velocity_phase_margin": si("tune", "velocity_phase_margin", t.velocity_phase_margin, degrees),
            "position_phase_margin": si("tune", "position_phase_margin", t.position_phase_margin, degrees),
            "position_crossover": si("tune", "position_crossover", t.position_crossover, angular),
            "min_gain_margin": si("tune", "min_gain_margin", t.min_gain_margin, decibels)}
    if tune["position_phase_margin"] is not None and tune["position_crossover"] is not None:
        raise ModelError("give either position_phase_margin or position_crossover", source=source,
                         path="tune.position_crossover")
    for key in ("velocity_crossover", "position_crossover", "min_gain_margin"):
        positive("tune", key, tune[key], getattr(t, key))
    for key in ("velocity_phase_margin", "position_phase_margin"):
        if tune[key] is not None and not 0 < tune[key] < 180:   # type: ignore[operator]
            raise ModelError("expected a phase margin between 0 and 180 degrees", source=source,
                             path=f"tune.{key}", value=tune[key])
    s = spec.simulate
    move = si("simulate", "move", s.move, UNITS["length"])
    duration = si("simulate", "duration", s.duration, UNITS["time"])
    positive("simulate", "duration", duration, s.duration)
    radius = si("circle", "radius", spec.circle.radius, UNITS["length"])
    feed = si("circle", "feed", spec.circle.feed, UNITS["velocity"])
    positive("circle", "radius", radius, radius)
    positive("circle", "feed", feed, feed)
    size_move = si("size", "move", spec.size.move, UNITS["length"])
    max_velocity = si("simulate", "max_velocity", s.max_velocity, UNITS["velocity"])
    max_acceleration = si("simulate", "max_acceleration", s.max_acceleration, UNITS["acceleration"])
    # a zero limit would fall back to the trajectory's
    positive("simulate", "max_velocity", max_velocity, s.max_velocity)
    positive("simulate", "max_acceleration", max_acceleration, s.max_acceleration)
    for table, value, given in (("simulate", move, s.move), ("size", size_move, spec.size.move)):
        if value == 0:
            raise ModelError("expected a move of non-zero length", source=source, path=f"{table}.move", value=given)
    return StudyOptions(tuple(spec.analyses), axis, tune, move, max_velocity, max_acceleration,
                        duration, radius, feed, spec.circle.model, size_move,   # type: ignore[arg-type]
                        spec.size.inertia_ratio_limit)


def check_analyses(spec: "StudySpec", machine: "Machine", axis: str, source: str, options: StudyOptions) -> None:
    """Refuse, before any work, analyses the base model cannot run (no controller, no move, one axis), and a
    simulated duration whose records would not fit in memory for one variant (as ``sicomat simulate``)."""
    needs_loop = [a for a in spec.analyses if a in ("tune", "margins", "simulate", "size")]
    if needs_loop:
        from ..servo.loop import build_servo_loop

        try:
            loop = build_servo_loop(machine, axis)
        except SicomatError as exc:
            raise ModelError(f"{', '.join(needs_loop)} need the axis's servo loop, which the base model cannot "
                             f"build: {exc}", source=source, path="analyses") from None
        if "simulate" in spec.analyses and options.duration is not None:
            from ..simulation import BATCH_VALUES_PER_STEP, run_size

            try:
                run_size([loop], options.duration, BATCH_VALUES_PER_STEP)
            except SicomatError as exc:   # a ModelError's own path and value are run_steps': the study's key instead
                message = exc.message if isinstance(exc, ModelError) else str(exc)
                raise ModelError(message, source=source, path="simulate.duration", value=spec.simulate.duration) \
                    from None
    if "simulate" in spec.analyses and spec.simulate.move is None and machine.axes[axis].trajectory is None:
        raise ModelError(f"simulate needs a move: give [simulate] move or an [axes.{axis}.trajectory] in the base "
                         "model", source=source, path="simulate.move")
    if "size" in spec.analyses and spec.size.move is None and machine.axes[axis].trajectory is None:
        raise ModelError(f"size needs a move: give [size] move or an [axes.{axis}.trajectory] in the base model",
                         source=source, path="size.move")
    if "circle" in spec.analyses and len(machine.axes) < 2:
        raise ModelError("the circle test needs a machine of two axes or more; the base model has one",
                         source=source, path="analyses")
    if spec.circle.model not in (None, "decoupled") and machine.robot is None:
        raise ModelError("the coupled and nonlinear circle models need a [robot] machine", source=source,
                         path="circle.model", value=spec.circle.model)
