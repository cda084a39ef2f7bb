"""Two or more decoupled axes following one path (paper II.B): per-axis servo simulations joined into
tool-point traces, the contour error, and the ISO 230-4 circle test.

Each path axis (``x``, ``y``, ``z`` of the interpolated path) is simulated by the machine axis of the
same name (case-insensitive) with its own mechanics, drive and controller; the setpoint is the
interpolator's exact S-curve mapped through the geometry, sampled by each axis's position loop.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from ..errors import ModelError
from ..servo.stability import Verdict, combine

if TYPE_CHECKING:  # pragma: no cover
    from ..motion.circle import CircleResult
    from ..description.machine import Machine
    from ..motion import Path, PathSamples
    from ..progress import ProgressCallback
    from .timeseries import TimeSeries

__all__ = ["PathRun", "CircleTest", "PATH_MODELS", "axis_for", "with_feedforward", "simulate_path", "circle_test", "axes_verdict",
           "PATH_METRICS"]

PATH_MODELS = ("decoupled", "coupled", "nonlinear")
"""The models a path is simulated on (:func:`simulate_path`)."""

PATH_METRICS = ("max_following_error", "rms_following_error", "final_error")
"""The per-axis figures of a path run: the following error only. Step-response figures (overshoot,
rise and settling time) have no meaning on a path (a closed one returns to its start: no step)."""


@dataclass(frozen=True, eq=False)
class PathRun:
    """Result of :func:`simulate_path`: per-axis time series and the joined tool-point traces (SI).

    ``setpoint`` and ``actual`` are ``(n, dimension)`` tool positions in path coordinates (m);
    ``s`` the commanded arc length (m); ``contour_error`` the normal distance from the actual point
    to the programmed path (m).
    """

    path: "Path"
    samples: "PathSamples"
    axes: dict[str, "TimeSeries"]
    time: np.ndarray
    s: np.ndarray
    setpoint: np.ndarray
    actual: np.ndarray
    contour_error: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    verdicts: dict[str, Verdict] = field(default_factory=dict)

    @property
    def verdict(self) -> Verdict:
        """One verdict of all the axes (each warning prefixed with its machine axis)."""
        names = list(self.verdicts)
        return combine([self.verdicts[n] for n in names],
                       [f"axis {self.info['machine_axes'][n]}: " for n in names])

    @property
    def max_contour_error(self) -> float:
        """Largest contour error over the run (m)."""
        return float(np.max(np.abs(self.contour_error)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: contour error and each axis's following-error figures."""
        return {"max_contour_error": self.max_contour_error,
                "rms_contour_error": float(np.sqrt(np.mean(self.contour_error ** 2))),
                "path_length": float(self.path.length), "duration_s": float(self.time[-1] + self.info["step"]),
                "samples": int(self.time.size), "wall_time_s": self.info.get("wall_time_s"),
                "axes": {name: {"machine_axis": self.info["machine_axes"][name],
                                **{key: getattr(series.metrics, key) for key in PATH_METRICS},
                                **(self.verdicts[name].to_dict() if name in self.verdicts else {})}
                         for name, series in self.axes.items()},
                **self.verdict.to_dict()}

    def to_pandas(self):
        """Time-indexed frame: commanded and actual tool positions per axis, s, contour error."""
        import pandas as pd

        cols = {"s": self.s, "contour_error": self.contour_error}
        for k, name in enumerate(self.path.axis_names):
            cols[f"{name}.setpoint"] = self.setpoint[:, k]
            cols[f"{name}.actual"] = self.actual[:, k]
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time"))

    def plot(self, magnification: float | None = None):
        """The path and the actual trace in the plane (the deviation magnified: automatic by default),
        and the contour error against time."""
        from ..plots.motion import plot_path_run

        return plot_path_run(self, magnification)


@dataclass(frozen=True, eq=False)
class CircleTest:
    """An ISO 230-4 circle test run: the simulated :class:`PathRun`, its :class:`CircleResult` and the
    verdict of the axes. An unstable axis (poles, divergence or limit cycle) leaves no figures:
    ``circle`` is None (and ``run`` too when the test was not simulated)."""

    run: PathRun | None
    circle: "CircleResult | None"
    feedforward: str
    verdict: Verdict = field(default_factory=lambda: Verdict(True))
    radius: float = 0.0
    feed: float = 0.0
    clockwise: bool = False
    machine_axes: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The ``sicomat circle --json`` object."""
        if self.circle is None or self.run is None:
            return {"circular_deviation": None, "radius": self.radius, "clockwise": self.clockwise,
                    "feed": self.feed, "feedforward": self.feedforward,
                    "axes": {name: {"machine_axis": axis} for name, axis in self.machine_axes.items()},
                    **self.verdict.to_dict()}
        out = self.circle.to_dict()
        out.update({"max_contour_error": self.run.max_contour_error, "feedforward": self.feedforward,
                    "wall_time_s": self.run.info.get("wall_time_s"),
                    "axes": self.run.to_dict()["axes"], **self.verdict.to_dict()})
        return out

    def plot(self, magnification: float | None = None, *, label: str | None = None,
             others: "Mapping[str, CircleResult] | None" = None):
        """The ballbar-style polar plot of the radial deviation (``others``: circles drawn beside it)."""
        if self.circle is None:
            from ..errors import AnalysisError

            raise AnalysisError("no circle figure: " + "; ".join(self.verdict.warnings))
        return self.circle.plot(magnification, label=label, others=others)


def axes_verdict(machine: "Machine", names) -> Verdict:
    """The verdict of the machine axes driving the path axes ``names``, from their closed loops' poles
    (each warning prefixed with its machine axis)."""
    from ..servo.loop import build_servo_loop
    from ..servo.stability import loop_verdict

    axes = [axis_for(machine, name) for name in names]
    return combine([loop_verdict(build_servo_loop(machine, axis)) for axis in axes], [f"axis {a}: " for a in axes])


def axis_for(machine: "Machine", name: str) -> str:
    """The machine axis that drives path axis ``name`` (same name, case-insensitive)."""
    for axis in machine.axes:
        if axis.lower() == name.lower():
            return axis
    raise ModelError(f"the path moves axis {name.upper()!r} but the machine has only {', '.join(machine.axes)}",
                     path="axes")


def with_feedforward(machine: "Machine", mode: str | None) -> "Machine":
    """A copy with velocity and acceleration feedforward set on every axis (``"on"``: 100 %, ``"off"``: 0)."""
    if mode is None:
        return machine
    if mode not in ("on", "off"):
        raise ModelError("expected 'on' or 'off'", path="feedforward", value=mode)
    gain = 1.0 if mode == "on" else 0.0
    axes = {}
    for name, axis in machine.axes.items():
        if axis.controller is not None:
            ctrl = axis.controller.model_copy(update={"velocity_feedforward": gain, "acceleration_feedforward": gain})
            axis = axis.model_copy(update={"controller": ctrl})
        axes[name] = axis
    return machine.model_copy(update={"axes": axes})


def simulate_path(machine: "Machine", samples: "PathSamples", *, settle: float = 0.05,
                  nonlinear: bool = True, progress: "ProgressCallback | None" = None,
                  model: str = "decoupled") -> PathRun:
    """Simulate every axis of the machine that the interpolated path moves, and join the traces;
    ``progress`` (:mod:`sicomat.progress`) follows each axis's simulation.

    ``model`` (:data:`PATH_MODELS`): ``"decoupled"`` simulates each axis alone on its own model (for a
    robot machine, its decoupled linearisation: the other motors locked) and reads its tool sensor;
    ``"coupled"`` (a ``[robot]`` machine) simulates every axis's loop together on the robot's coupled
    linearisation at its configuration, the axes the path does not move holding their position, and
    reads the tool point's path coordinates (:class:`sicomat.robotics.path_model.ToolPoint`, linearised);
    ``"nonlinear"`` the same loops on the robot's nonlinear dynamics (large motions:
    :mod:`sicomat.simulation.nonlinear`), the tool point by the geometric model. The path starts at the
    configuration.

    Raises
    ------
    ModelError
        A path axis has no machine axis, an axis has no servo loop, an unknown ``model``, or a coupled
        model of a machine without a ``[robot]`` section.
    SimulationDiverged
        An axis diverged; the message names it and its attribute ``axis`` too.
    """
    if model not in PATH_MODELS:
        raise ModelError(f"unknown model {model!r}; expected one of {', '.join(PATH_MODELS)}", path="model",
                         value=model)
    from ..motion.contour import contour_error
    from ..servo.loop import build_servo_loop
    from . import simulate
    from .checks import simulation_verdict
    from .kernel import SimulationDiverged

    path = samples.path
    names = path.axis_names
    mapping = {name: axis_for(machine, name) for name in names}
    duration = samples.profile.end_time + settle
    runs: dict[str, TimeSeries] = {}
    verdicts: dict[str, Verdict] = {}
    wall = 0.0
    if model != "decoupled":
        runs, verdicts, wall = _coupled_runs(machine, samples, mapping, duration, nonlinear=nonlinear,
                                             progress=progress, large=model == "nonlinear")
    for k, name in enumerate(names if model == "decoupled" else ()):
        loop = build_servo_loop(machine, mapping[name])
        axis_setpoint = samples.axis_setpoint(k)
        try:
            series = simulate(loop, axis_setpoint, duration, nonlinear=nonlinear, progress=progress)
        except SimulationDiverged as exc:
            raise SimulationDiverged(f"axis {mapping[name]}: {exc}", time=exc.time, step=exc.step,
                                     axis=mapping[name]) from None
        wall += series.info["wall_time_s"]
        runs[name] = series
        verdicts[name] = simulation_verdict(loop, series, axis_setpoint)
    first = runs[names[0]]
    t = first.time
    setpoint = np.empty((t.size, len(names)))
    actual = np.empty_like(setpoint)
    for k, name in enumerate(names):
        series = runs[name]
        offset = float(path.start[k])
        setpoint[:, k] = offset + np.interp(t, series.time, series["setpoint.fine"])
        actual[:, k] = offset + np.interp(t, series.time, series["tool.position"])
    s = samples.profile.evaluate(t)[0]
    start = _time.perf_counter()
    contour = contour_error(path, actual, s_hint=s)
    return PathRun(path=path, samples=samples, axes=runs, time=t, s=s, setpoint=setpoint, actual=actual,
                   contour_error=contour,
                   info={"wall_time_s": wall + (_time.perf_counter() - start), "step": first.info["step"],
                         "machine_axes": mapping, "model": model}, verdicts=verdicts)


def _coupled_runs(machine: "Machine", samples: "PathSamples", mapping: dict[str, str], duration: float, *,
                  nonlinear: bool, progress: "ProgressCallback | None", large: bool
                  ) -> tuple[dict[str, "TimeSeries"], dict[str, Verdict], float]:
    """The path axes' series of one coupled run of every axis of a robot machine (see :func:`simulate_path`)."""
    from ..motion.setpoints import step_profile
    from ..robotics.path_model import rigid_body_dynamics, tool_point
    from ..servo.coupled import CoupledLoop, robot_coupled_loop
    from .checks import coupled_simulation_verdict
    from .coupled import simulate_coupled
    from .kernel import SimulationDiverged

    spec = machine.robot
    if spec is None:
        raise ModelError("a coupled path simulation needs a machine described by a [robot] section (its "
                         "motorised joints are the axes); this machine's axes are independent", path="robot")
    names = samples.path.axis_names
    base = robot_coupled_loop(machine)
    point = tool_point(spec, [mapping[name] for name in names])
    rows = point.linear()
    tools = dict(base.tools)
    for k, name in enumerate(names):
        tools[mapping[name]] = rows[k]
    coupled = CoupledLoop(base.mechanics, base.loops, tools)
    profiles: dict[str, Any] = {axis: step_profile(0.0) for axis in coupled.axes}   # a profile each
    for k, name in enumerate(names):
        profiles[mapping[name]] = samples.axis_setpoint(k)

    def tool_positions(dq: np.ndarray) -> dict[str, np.ndarray]:
        c = point.coordinates(dq)
        return {mapping[name]: c[:, k] for k, name in enumerate(names)}

    try:
        run = simulate_coupled(coupled, profiles, duration, nonlinear=nonlinear, progress=progress,
                               dynamics=rigid_body_dynamics(spec) if large else None,
                               tool_positions=tool_positions if large else None)
    except SimulationDiverged as exc:
        axes = ", ".join(coupled.axes)
        raise SimulationDiverged(f"axes {axes} (coupled): {exc}", time=exc.time, step=exc.step) from None
    runs = {name: run[mapping[name]] for name in names}
    # one verdict of the coupled loops (their poles all closed, each axis's run): on the first path axis, the
    # others carry its stability only (the path's verdict joins them, a warning once)
    verdict = coupled_simulation_verdict(coupled, run, profiles)
    verdicts = {name: verdict if k == 0 else Verdict(verdict.stable) for k, name in enumerate(names)}
    return runs, verdicts, float(run.info["wall_time_s"])


def circle_test(machine: "Machine", radius: float, feed: float, *, clockwise: bool = False,
                feedforward: str | None = None, max_acceleration: float | None = None,
                max_jerk: float | None = None, axes: tuple[str, str] = ("x", "y"),
                nonlinear: bool = True, progress: "ProgressCallback | None" = None,
                model: str = "decoupled") -> CircleTest:
    """Simulate the ballbar circle (lead-in arc, 360° evaluated at constant feed, lead-out arc).

    Parameters
    ----------
    machine : Machine
        With two axes named like ``axes`` (default X and Y), each with a servo loop.
    radius : float
        Circle radius (m), > 0.
    feed : float
        Path velocity (m/s), > 0.
    clockwise : bool
        G02 direction when True (seen from +Z).
    feedforward : {"on", "off"} or None
        Override the velocity and acceleration feedforward of every axis.
    max_acceleration, max_jerk : float, optional
        Path limits of the interpolator (default: the machine's ``interpolator`` table).
    axes : tuple of str
        The two path axes (machine axes of the same names).
    nonlinear : bool
        ``False`` simulates the linear loops (no friction, limits or quantization).
    progress : callable, optional
        Follows the axes' simulations (:mod:`sicomat.progress`).
    model : {"decoupled", "coupled", "nonlinear"}
        The model the axes are simulated on (:func:`simulate_path`); the circle is centred so that it
        starts at the machine's configuration.
    """
    from ..motion.circle import evaluate_circle
    from ..motion import circle_test_path, interpolate

    if not radius > 0:
        raise ModelError("the radius must be > 0", path="radius", value=radius)
    if not feed > 0:
        raise ModelError("the feed must be > 0", path="feed", value=feed)
    machine = with_feedforward(machine, feedforward)
    ip = machine.interpolator
    acc = max_acceleration if max_acceleration is not None else ip.max_acceleration
    jerk = max_jerk if max_jerk is not None else ip.max_jerk
    if feed ** 2 / radius > acc:
        raise ModelError(f"the centripetal acceleration feed²/R = {feed ** 2 / radius:.3g} m/s² exceeds the "
                         f"interpolator's limit {acc:g} m/s²: lower the feed or raise max_acceleration",
                         path="feed", value=feed)
    test = circle_test_path((0.0, 0.0), radius, clockwise)
    path = test.path
    first = machine.axes[axis_for(machine, axes[0])]
    period = first.controller.position_period if first.controller is not None else 1e-3
    samples = interpolate(path, feed, acc, jerk, period)
    mapping = {name: axis_for(machine, name) for name in path.axis_names}
    about: dict[str, Any] = {"feedforward": feedforward or "model", "radius": float(radius), "feed": float(feed),
             "clockwise": bool(clockwise), "machine_axes": mapping}
    verdict = axes_verdict(machine, path.axis_names)
    if verdict.stable is False:       # the figures of an unstable axis mean nothing: do not simulate
        return CircleTest(run=None, circle=None, verdict=verdict.with_warnings(
            ["no circle figures: an axis is unstable"]), **about)
    from .kernel import SimulationDiverged

    try:
        run = simulate_path(machine, samples, nonlinear=nonlinear, progress=progress, model=model)
    except SimulationDiverged as exc:
        return CircleTest(run=None, circle=None, verdict=verdict.with_warnings(
            [f"{exc}", "no circle figures: an axis diverged"], unstable=True), **about)
    if run.verdict.stable is False:
        return CircleTest(run=run, circle=None, verdict=run.verdict.with_warnings(
            ["no circle figures: an axis is unstable"]), **about)
    circle = evaluate_circle(run.actual[:, 0], run.actual[:, 1], test.center[:2], radius, s=run.s,
                             window=test.window, clockwise=clockwise, feed=feed)
    return CircleTest(run=run, circle=circle, verdict=run.verdict, **about)
