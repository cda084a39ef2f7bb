"""Helpers of ``sicomat simulate``: choosing the setpoint from options, the JSON payload."""

from __future__ import annotations

from typing import Any

from ..errors import ModelError

__all__ = ["choose_profile", "simulate_payload"]

DEFAULT_MAX_VELOCITY = 0.2   # m/s, for --move without limits in the model
DEFAULT_MAX_ACCELERATION = 2.0  # m/s^2


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
            "wall_time_s": series.info["wall_time_s"]}
