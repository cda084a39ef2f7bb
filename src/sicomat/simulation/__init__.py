"""Simulation of servo loops: setpoints sampled, the loop lowered to a hybrid program, the kernel run."""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np

from ..errors import ModelError
from ..progress import notify
from .timeseries import StepFigures, StepMetrics, TimeSeries, following_figures_many, step_figures, step_metrics

if TYPE_CHECKING:  # pragma: no cover
    from ..servo.loop import ServoLoop
    from ..progress import ProgressCallback
    from ..motion.setpoints import SetpointProfile
    from ..servo.program import HybridProgram
    from .kernel import KernelResult

__all__ = ["simulate", "simulate_batch", "BatchMetrics", "loop_program", "loop_programs",
           "TimeSeries", "StepMetrics", "step_metrics", "StepFigures", "step_figures"]
# the multi-axis runs (simulate_path, circle_test: simulation/paths.py) are not re-exported here:
# paths.py uses this module's simulate(), and re-exporting it would knot the two (an import cycle); the same
# for the coupled axes' run (simulate_coupled, CoupledRun: simulation/coupled.py)


def loop_program(loop: "ServoLoop", profile: "SetpointProfile", duration: float, *, nonlinear: bool = True):
    """The hybrid program of ``loop`` following ``profile`` for ``duration`` seconds, and its step count."""
    programs, n_steps = loop_programs([loop], profile, duration, nonlinear=nonlinear)
    return programs[0], n_steps


def loop_programs(loops: Sequence["ServoLoop"], profile: "SetpointProfile", duration: float, *,
                  nonlinear: bool = True, recorded: int | None = None) -> tuple[list, int]:
    """:func:`loop_program` for variants of one loop: the setpoints are sampled once for all.

    The loops must share their velocity and position periods (the setpoint table's timing).
    ``recorded``: values kept per base step by the run that follows (default: every signal of one
    loop, as :func:`simulate` keeps them), for the memory estimate made before anything is
    allocated (:func:`sicomat.budget.require_memory`).
    """
    from ..servo.loop import SetpointTable, servo_program

    if not loops:
        raise ModelError("no servo loop to simulate")
    first = loops[0]
    h = first.base_period
    Np = first.position_ratio
    for v, loop in enumerate(loops):
        if loop.base_period != h or loop.position_ratio != Np:
            raise ModelError(f"variant {v}: the loop periods differ from variant 0's "
                             f"({loop.base_period:g} s / {loop.position_ratio} against {h:g} s / {Np})",
                             path=f"axes.{loop.axis}.controller")
    per_step = recorded if recorded is not None else _values_per_step(first, profile, nonlinear)
    n_steps, n_pos = run_size(loops, duration, per_step)
    t_pos = np.arange(n_pos) * Np * h
    table = SetpointTable(*profile.evaluate(t_pos))
    return [servo_program(loop, table, nonlinear=nonlinear) for loop in loops], n_steps


def timed_run(program: "HybridProgram", n_steps: int, task: str, progress: "ProgressCallback | None",
              engine: "Callable[[HybridProgram, int], KernelResult] | None" = None) -> "tuple[KernelResult, float]":
    """Run ``program`` for ``n_steps`` with ``engine`` (default: the linear kernel,
    :func:`sicomat.simulation.kernel.run`) after loading (or compiling) it on a two-step run, so that the
    wall time returned is the simulation's own; ``progress`` is told the phases."""
    from .kernel import run

    engine = run if engine is None else engine
    notify(progress, "loading the simulation kernel (compiled on first use)", 0, None)
    engine(program, 2)
    notify(progress, task, 0, n_steps)
    start = _time.perf_counter()
    result = engine(program, n_steps)
    wall = _time.perf_counter() - start
    notify(progress, task, n_steps, n_steps)
    return result, wall


def run_steps(loops: Sequence["ServoLoop"], duration: float) -> int:
    """The base steps of a run of ``duration`` seconds of loops sharing their velocity period; a
    :class:`~sicomat.errors.ModelError` for a duration that is not a number of seconds > 0, shorter
    than two steps, or not longer than a loop's computation or feedforward delay."""
    h = loops[0].base_period
    try:
        duration = float(duration)
    except (TypeError, ValueError):
        duration = math.nan
    if not (math.isfinite(duration) and duration > 0):
        raise ModelError("the duration must be a finite number of seconds > 0", path="duration", value=duration)
    n_steps = int(math.floor(duration / h + 1e-9))
    if n_steps < 2:
        raise ModelError(f"the duration {duration:g} s is shorter than two velocity-loop periods ({h:g} s)",
                         path="duration", value=duration)
    for loop in loops:
        ctrl = loop.controller
        for key, delay in (("position_delay", ctrl.position_delay * ctrl.position_period),
                           ("velocity_delay", ctrl.velocity_delay * ctrl.velocity_period),
                           ("feedforward_delay", ctrl.feedforward_delay)):
            if delay >= duration:
                raise ModelError(f"the delay ({delay:g} s) is not shorter than the run ({duration:g} s)",
                                 path=f"axes.{loop.axis}.controller.{key}", value=getattr(ctrl, key))
    return n_steps


def _values_per_step(loop: "ServoLoop", profile: "SetpointProfile", nonlinear: bool) -> int:
    """Values one run of ``loop`` keeps per base step: the recorded slots, the continuous states and
    each friction link's force and stuck flag (the program of a one-sample table tells them)."""
    from ..servo.loop import SetpointTable, servo_program

    program = servo_program(loop, SetpointTable(*profile.evaluate(np.zeros(1))), nonlinear=nonlinear)
    return len(program.record) + program.continuous.A.shape[0] + 2 * program.continuous.G.shape[0]


def run_size(loops: Sequence["ServoLoop"], duration: float, per_step: int) -> tuple[int, int]:
    """The base steps and position-loop samples of a run of ``loops`` (sharing their periods) for ``duration``
    seconds keeping ``per_step`` values a step and loop, checked (:func:`run_steps`) and refused when its
    arrays would not fit in memory (:class:`~sicomat.errors.ResourceError`, before anything is allocated)."""
    n_steps = run_steps(loops, duration)
    n_pos = -(-n_steps // loops[0].position_ratio)
    delayed = sum(loop.controller.velocity_delay + loop.controller.position_delay for loop in loops)
    _require_memory(n_steps, per_step, n_pos, delayed)
    return n_steps, n_pos


def _require_memory(n_steps: int, per_step: int, n_pos: int, delayed: int = 0) -> None:
    """Refuse a run whose arrays cannot fit: the kernel's records (``per_step`` values of 8 bytes per
    step), as much again for the named and derived signals and the metrics computed from them, the
    setpoint table (time, position, velocity, acceleration and the kernel's 3 columns) and the ring
    buffers of the computation delays (``delayed`` samples)."""
    from ..budget import require_memory

    nbytes = 8.0 * (2.0 * n_steps * per_step + 7.0 * n_pos + delayed)
    require_memory(nbytes, "this simulation", f"{n_steps} steps x {per_step} values x 8 bytes, twice, "
                                              f"and the setpoint table")


def simulate(loop: "ServoLoop", profile: "SetpointProfile", duration: float, *, nonlinear: bool = True,
             progress: "ProgressCallback | None" = None) -> TimeSeries:
    """Simulate the closed loop following a setpoint profile.

    Parameters
    ----------
    loop : ServoLoop
        From :func:`sicomat.servo.loop.build_servo_loop`.
    profile : Profile
        Setpoint (see :mod:`sicomat.motion.setpoints`).
    duration : float
        Simulated time (s); the step is the velocity-loop period.
    nonlinear : bool
        ``False`` drops limits, quantizers and Coulomb friction (the linear loop).
    progress : callable, optional
        Told the phases (:mod:`sicomat.progress`): loading (or, the first time, compiling) the
        kernel, the steps (reported when the compiled run, one call, returns), the signals.

    Returns
    -------
    TimeSeries
        Every named signal at every base step, with :class:`~sicomat.simulation.timeseries.StepMetrics` and
        ``info["wall_time_s"]`` (the kernel's run time, without the one-time compilation or cache
        load of the compiled kernel, which a two-step warm-up run absorbs).

    Raises
    ------
    SimulationDiverged
        The loop is unstable: the message gives the time at which the states blew up.
    ResourceError
        The run's arrays would exceed the memory limit (:mod:`sicomat.budget`); estimated first.
    """
    program, n_steps = loop_program(loop, profile, duration, nonlinear=nonlinear)
    result, wall = timed_run(program, n_steps, f"simulating axis {loop.axis}: {n_steps} steps", progress)
    signals = named_signals(loop, program, result.records, profile.evaluate(result.time)[0], result.states)
    return axis_series(loop, profile, result.time, signals, wall=wall, nonlinear=nonlinear)


def axis_series(loop: "ServoLoop", profile: "SetpointProfile", time: np.ndarray, signals: dict[str, np.ndarray], *,
                wall: float, nonlinear: bool) -> TimeSeries:
    """An axis's :class:`TimeSeries` from its named signals (:func:`named_signals`): the step metrics of
    its move, the run's information."""
    actual = signals["setpoint.fine"] - signals["following_error"]
    metrics = step_metrics(time, signals["setpoint.fine"], actual, profile.distance, start=profile.breaks[0])
    return TimeSeries(time=time, signals=signals, metrics=metrics,
                      info={"wall_time_s": wall, "samples": len(time), "step": loop.base_period,
                            "axis": loop.axis, "notes": simulation_notes(loop, nonlinear),
                            "effort_unit": effort_unit(loop)})


def effort_unit(loop: "ServoLoop") -> str:
    """The unit of the drive's effort: ``"N"`` for a force actuator, ``"N·m"`` for a torque one."""
    return "N" if loop.mechanics.actuator(loop.actuator).kind == "translational" else "N·m"


def simulation_notes(loop: "ServoLoop", nonlinear: bool = True) -> list[str]:
    """What the simulation of ``loop`` leaves out although the model file gives it."""
    drv, ctrl = loop.drive, loop.controller
    notes = []
    if nonlinear and ctrl.velocity_loop == "continuous" and (np.isfinite(drv.i_peak) or np.isfinite(drv.u_max)):
        notes.append("the velocity loop is continuous: the drive's current and voltage limits (and the "
                     "anti-windup) act inside it and are not simulated; the loop is linear up to the plant's "
                     "friction")
    return notes



def named_signals(loop: "ServoLoop", program, records: np.ndarray, fine_setpoint: np.ndarray,
                  states: np.ndarray, *, view: Mapping[str, str] | None = None,
                  outputs: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Every signal of a run by name: the recorded slots, their aliases and the derived signals.

    For one axis of a coupled program: ``view`` maps the axis's signal names to the program's slot
    names (:func:`sicomat.servo.coupled.axis_view`), ``outputs`` are the continuous outputs as a
    single-axis plant names them (see :func:`sicomat.servo.loop.derived_signals`).
    """
    from ..servo.loop import derived_signals

    signals = {name: records[:, i] for i, name in enumerate(program.slot_names)}
    for name, index in program.aliases.items():
        signals[name] = records[:, index]
    if view is not None:
        signals = {own: signals[slot] for own, slot in view.items()}
    derived = derived_signals(loop, signals, fine_setpoint, states, outputs=outputs)
    return {**signals, **{name: value for name, value in derived.items() if name not in signals}}


@dataclass(frozen=True, eq=False)
class BatchMetrics:
    """Figures of each variant of a batch (arrays over the variants) and their run time.

    The following errors are in metres; ``overshoot_percent`` and ``settling_time`` (s) are those of
    :func:`~sicomat.simulation.timeseries.step_metrics` for :func:`simulate` (the same band around the
    final setpoint, the same start: the move's first break), NaN where a run has none (still outside
    the band at its end, or a move that does not end: distance 0); ``max_effort`` is the peak of the
    effort the drive is told to apply, ``kt · |current.applied|`` (N for a force actuator, N·m for a
    torque one: after the computation delay, the current limits and the quantizer; the drive's current
    loop follows it), the figure a motor's peak effort bounds. ``diverged`` flags the variants whose
    simulation blew up (their figures are NaN); ``limit_cycle`` those that end in a saturation-bound limit
    cycle (:func:`~sicomat.simulation.checks.saturation_cycle`, the check ``sicomat simulate`` makes: an
    unstable loop held by the current limits, whose figures are not a stable loop's; False where the current
    limits are not simulated).
    """

    max_following_error: np.ndarray
    rms_following_error: np.ndarray
    final_error: np.ndarray
    overshoot_percent: np.ndarray
    settling_time: np.ndarray
    max_effort: np.ndarray
    diverged: np.ndarray
    wall_time_s: float
    limit_cycle: np.ndarray

    def to_pandas(self):
        """One row per variant."""
        import pandas as pd

        return pd.DataFrame({"max_following_error": self.max_following_error,
                             "rms_following_error": self.rms_following_error,
                             "final_error": self.final_error, "overshoot_percent": self.overshoot_percent,
                             "settling_time": self.settling_time, "max_effort": self.max_effort,
                             "diverged": self.diverged, "limit_cycle": self.limit_cycle})


def simulate_batch(loops: Sequence["ServoLoop"], profile: "SetpointProfile", duration: float, *,
                   nonlinear: bool = True, progress: "ProgressCallback | None" = None,
                   threads: int | None = None) -> BatchMetrics:
    """Simulate many variants of one loop (other gains, masses, stiffnesses, limits, ...) in one
    compiled call and return each variant's figures (:class:`BatchMetrics`).

    The variants must share the loop's structure (same blocks, sample periods, delays, filters
    and friction links); only numbers may differ. Only the position sensor, the applied current and
    its two limits are recorded. The variants are shared over ``threads`` threads (default: numba's thread count in the
    calling thread, see :func:`~sicomat.simulation.kernel.run_batch`); each one's figures are the same
    whatever the thread count and the other variants.
    With ``progress`` (:mod:`sicomat.progress`) the variants run in about twenty compiled calls
    instead of one, each reported when it returns (the figures are the same: variants are independent).
    """
    from .checks import saturation_cycle, tail_start
    from .kernel import run_batch

    programs, n_steps = loop_programs(loops, profile, duration, nonlinear=nonlinear,
                                      recorded=BATCH_VALUES_PER_STEP * len(loops))
    sensors = [f"sensor.{loop.controller.position_sensor}" for loop in loops]
    if len(set(sensors)) != 1:
        raise ModelError("the variants of a batch must share their position sensor", path="controller.position_sensor")
    first_program = programs[0]
    applied = first_program.aliases.get("current.applied", None)
    if applied is None:
        applied = first_program.slot_names.index("current.applied")
    # the current limits, for the limit-cycle check (absent when they are not simulated: a continuous velocity
    # loop, nonlinear=False)
    limits = [n for n in ("current.lower", "current.upper") if n in first_program.slot_names]
    record: list[int | str] = [sensors[0], int(applied), *limits]
    chunk = len(programs) if progress is None else max(1, -(-len(programs) // 20))
    task = f"simulating {len(programs)} variants: {n_steps} steps each"
    notify(progress, task, 0, len(programs))
    start = _time.perf_counter()
    parts = []
    for first in range(0, len(programs), chunk):
        parts.append(run_batch(programs[first: first + chunk], n_steps, record=record, on_divergence="flag",
                               threads=threads))
        notify(progress, task, min(first + chunk, len(programs)), len(programs))
    wall = _time.perf_counter() - start
    result = parts[0]
    records = np.concatenate([p.records for p in parts]) if len(parts) > 1 else result.records
    fine = profile.evaluate(result.time)[0]
    gains = np.array([loop.position_gain for loop in loops])
    kt = np.array([loop.drive.kt for loop in loops])
    bad = np.concatenate([p.diverged for p in parts]) if len(parts) > 1 else result.diverged
    # as axis_series and step_metrics do for simulate(): the following error from the sensor reading, the
    # actual position the fine setpoint minus it
    figures = following_figures_many(result.time, fine, records[:, :, 0], gains, records[:, :, 1], kt,
                                     profile.distance, start=profile.breaks[0])
    max_error, rms_error, final_error, overshoot, settling, effort = (np.where(bad, np.nan, f) for f in figures)
    cycle = np.zeros(len(loops), dtype=bool)
    if len(limits) == 2:
        start = tail_start(records.shape[1])
        still = bool(np.ptp(fine[start:]) == 0)
        for v in np.flatnonzero(~bad):
            tail = records[v, start:]
            cycle[v] = saturation_cycle(tail[:, 1], tail[:, 2], tail[:, 3], still) is not None
    return BatchMetrics(max_error, rms_error, final_error, overshoot_percent=overshoot, settling_time=settling,
                        max_effort=effort, diverged=bad, wall_time_s=wall, limit_cycle=cycle)


BATCH_VALUES_PER_STEP = 6
"""Values per variant and step that :func:`simulate_batch` keeps (its memory estimate): the kernel's records (the
position sensor, the applied current and its two limits) and the following error and position computed from
them."""
