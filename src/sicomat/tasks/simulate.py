"""Helpers of ``sicomat simulate``: the setpoint from a step, a move or the model, the JSON payload,
a G-code run. Errors name the parameter (``ModelError.path``); the command line checks how its
options combine before calling."""

from __future__ import annotations

from typing import Any

from ..errors import ModelError

__all__ = ["choose_profile", "simulate_payload", "diverged_payload", "simulate_gcode", "STEP_FIGURES"]

STEP_FIGURES = ("overshoot_percent", "rise_time", "settling_time")
"""Figures of a settling step response: None (null) when the loop is unstable."""

DEFAULT_MAX_VELOCITY = 0.2   # m/s, for --move without limits in the model
DEFAULT_MAX_ACCELERATION = 2.0  # m/s^2
MAX_GCODE_BYTES = 256 * 1024 ** 2  # a G-code program read whole: larger ones are refused


def choose_profile(trajectory, step_mm, move_mm, max_velocity, max_acceleration):
    """The setpoint profile and a default duration from the command-line options and the model.

    ``--step`` and ``--move`` become setpoint descriptions (step, trapezoid) and every profile comes
    from the one lowering, :func:`~sicomat.motion.setpoints.profile_from_spec`. ``--move`` takes its
    limits from the options, else from the model's trajectory when it is a trapezoid, else the defaults.
    The options were checked by the CLI (finite, magnitudes 1e-100 to 1e100, limits > 0), so the
    descriptions are constructed without the model file's unit checks, which would refuse a step below
    1e-100 m that the option accepts (``model_construct``: same numbers as before, nothing re-parsed).
    """
    from ..description.motion import StepSetpoint, TrapezoidSetpoint
    from ..motion.setpoints import profile_from_spec

    if step_mm is not None and move_mm is not None:
        raise ModelError("give either a step or a move, not both", path="move_mm", value=move_mm)
    if step_mm is not None:
        return profile_from_spec(StepSetpoint.model_construct(type="step", distance=step_mm * 1e-3)), 0.3
    if move_mm is not None:
        vmax, amax = DEFAULT_MAX_VELOCITY, DEFAULT_MAX_ACCELERATION
        if isinstance(trajectory, TrapezoidSetpoint):
            vmax, amax = trajectory.max_velocity, trajectory.max_acceleration
        move = TrapezoidSetpoint.model_construct(type="trapezoid", distance=move_mm * 1e-3,
                                                max_velocity=max_velocity or vmax,
                                                max_acceleration=max_acceleration or amax)
        profile = profile_from_spec(move)
        return profile, profile.end_time + 0.2
    if trajectory is None:
        raise ModelError("no setpoint: give a step or a move, or add a [axes.<name>.trajectory] table",
                         path="trajectory")
    profile = profile_from_spec(trajectory)
    return profile, profile.end_time + (0.2 if profile.kind != "ramp" else 0.3)


def simulate_payload(series, verdict=None) -> dict[str, Any]:
    """The ``sicomat simulate --json`` object, with the run's ``stable`` verdict and ``warnings``
    (:func:`sicomat.simulation.checks.simulation_verdict`); an unstable loop has no step figures."""
    m = series.metrics.to_dict()
    out = {"axis": series.info["axis"], **m, "samples": series.info["samples"],
           "step_s": series.info["step"], "duration_s": float(series.info["samples"] * series.info["step"]),
           "wall_time_s": series.info["wall_time_s"], "notes": list(series.info.get("notes", []))}
    if verdict is not None:
        if verdict.stable is False:
            out.update({key: None for key in STEP_FIGURES})
        out.update({"diverged": False, **verdict.to_dict()})
    return out


def diverged_payload(loop, exc, verdict, notes) -> dict[str, Any]:
    """The ``sicomat simulate --json`` object of a run that diverged: no figures, the time it diverged."""
    from ..simulation.timeseries import StepMetrics

    figures = {key: None for key in StepMetrics.__dataclass_fields__}
    return {"axis": loop.axis, **figures, "samples": int(exc.step), "step_s": loop.base_period,
            "duration_s": float(exc.time), "wall_time_s": None, "notes": list(notes), "diverged": True,
            "divergence_time": float(exc.time), **verdict.to_dict()}


def simulate_gcode(machine, gcode_path, feed_mm_min, step_mm, move_mm, *, nonlinear: bool = True, progress=None,
                   model: str = "decoupled"):
    """Parse a G-code file, interpolate it with the machine's interpolator, simulate the axes it moves
    (``model``: :func:`~sicomat.simulation.paths.simulate_path`'s, ``"nonlinear"`` for ``--coupled``: a path on
    a robot machine's coupled nonlinear dynamics, read at the tool point).

    Returns the ``simulate --gcode --json`` object and the :class:`~sicomat.simulation.paths.PathRun` (None
    when an axis diverged: the payload then has the verdict and no figures)."""
    from pathlib import Path as _Path

    from ..motion.gcode import parse_gcode
    from ..simulation.paths import axis_for, simulate_path
    from ..motion import interpolate

    if step_mm is not None or move_mm is not None:
        raise ModelError("a G-code path cannot be combined with a step or a move", path="gcode_path",
                         value=str(gcode_path))
    if feed_mm_min is not None and not feed_mm_min > 0:
        raise ModelError("the feed must be > 0 mm/min", path="feed_mm_min", value=feed_mm_min)
    try:
        from ..io.modelfile import read_text_bounded

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
    from ..simulation.paths import axes_verdict
    from ..simulation.kernel import SimulationDiverged

    try:
        run = simulate_path(machine, samples, nonlinear=nonlinear, progress=progress, model=model)
    except SimulationDiverged as exc:
        verdict = axes_verdict(machine, path.axis_names).with_warnings([str(exc)], unstable=True)
        return {"max_following_error": None, "rms_following_error": None, "final_error": None,
                "path_length": float(path.length), "diverged": True, "divergence_time": float(exc.time),
                **verdict.to_dict()}, None
    payload = run.to_dict()
    summary = {key: max((a[key] for a in payload["axes"].values() if a[key] is not None), key=abs)
               for key in ("max_following_error", "rms_following_error", "final_error")}
    return {**summary, **payload, "diverged": False, "model": model}, run
