"""Helpers of ``sicomat simulate``: choosing the setpoint from options, the JSON payload."""

from __future__ import annotations

from typing import Any

from ..errors import ModelError

__all__ = ["choose_profile", "simulate_payload"]

DEFAULT_MAX_VELOCITY = 0.2   # m/s, for --move without limits in the model
DEFAULT_MAX_ACCELERATION = 2.0  # m/s^2
MAX_GCODE_BYTES = 256 * 1024 ** 2  # a G-code program read whole: larger ones are refused


def choose_profile(trajectory, step_mm, move_mm, max_velocity, max_acceleration):
    """The setpoint profile and a default duration from the command-line options and the model."""
    from ..servo_spec import TrapezoidSetpoint
    from ..setpoints import profile_from_spec, step_profile, trapezoid_profile

    if step_mm is not None and move_mm is not None:
        raise ModelError("give either --step or --move, not both", source="options")
    for name, value in (("--max-velocity", max_velocity), ("--max-acceleration", max_acceleration)):
        if value is not None and value <= 0:
            raise ModelError(f"{name} must be > 0", source="options", value=value)
    if step_mm is not None:
        return step_profile(step_mm * 1e-3), 0.3
    if move_mm is not None:
        vmax, amax = DEFAULT_MAX_VELOCITY, DEFAULT_MAX_ACCELERATION
        if isinstance(trajectory, TrapezoidSetpoint):
            vmax, amax = trajectory.max_velocity, trajectory.max_acceleration
        profile = trapezoid_profile(move_mm * 1e-3, max_velocity or vmax, max_acceleration or amax)
        return profile, profile.end_time + 0.2
    if trajectory is None:
        raise ModelError("no setpoint: give --step MM or --move MM, or add a [axes.<name>.trajectory] table",
                         source="options")
    profile = profile_from_spec(trajectory)
    return profile, profile.end_time + (0.2 if profile.kind != "ramp" else 0.3)


def simulate_payload(series) -> dict[str, Any]:
    """The ``sicomat simulate --json`` object."""
    m = series.metrics
    return {"axis": series.info["axis"], **m.to_dict(), "samples": series.info["samples"],
            "step_s": series.info["step"], "duration_s": float(series.info["samples"] * series.info["step"]),
            "wall_time_s": series.info["wall_time_s"], "notes": list(series.info.get("notes", []))}


def simulate_gcode(machine, gcode_path, feed_mm_min, step_mm, move_mm, *, nonlinear: bool = True):
    """Parse a G-code file, interpolate it with the machine's interpolator, simulate the axes it moves."""
    from pathlib import Path as _Path

    from ..gcode import parse_gcode
    from ..multiaxis import axis_for, simulate_path
    from ..path import interpolate

    if step_mm is not None or move_mm is not None:
        raise ModelError("--gcode cannot be combined with --step or --move", source="options")
    if feed_mm_min is not None and not feed_mm_min > 0:
        raise ModelError("the feed must be > 0 mm/min", source="--feed", value=feed_mm_min)
    try:
        from ..modelfile import read_text_bounded

        text = read_text_bounded(_Path(gcode_path), MAX_GCODE_BYTES, "a G-code file")
    except FileNotFoundError:
        raise ModelError("no such G-code file", source=str(gcode_path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read the G-code file ({exc})", source=str(gcode_path)) from None
    ip = machine.interpolator
    present = {name.upper() for name in machine.axes}
    letters = "".join(letter for letter in "XYZ" if letter in present)
    if len(letters) < 2:
        raise ModelError("a G-code path needs at least two of the axes X, Y, Z in the machine", source="axes")
    path = parse_gcode(text, source=str(gcode_path), rapid_feed=ip.rapid_feed, axes=letters)
    first = machine.axes[axis_for(machine, path.axis_names[0])]
    period = first.controller.position_period if first.controller is not None else 1e-3
    feed = feed_mm_min * 1e-3 / 60.0 if feed_mm_min is not None else None
    samples = interpolate(path, feed, ip.max_acceleration, ip.max_jerk, period,
                          corner_tolerance=ip.corner_tolerance)
    return simulate_path(machine, samples, nonlinear=nonlinear)
