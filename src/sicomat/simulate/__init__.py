"""Simulation of servo loops: setpoints sampled, the loop lowered to a hybrid program, the kernel run."""

from __future__ import annotations

import math
import time as _time
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from ..timeseries import TimeSeries, step_metrics

if TYPE_CHECKING:  # pragma: no cover
    from ..loop import ServoLoop
    from ..setpoints import Profile

__all__ = ["simulate", "loop_program"]


def loop_program(loop: "ServoLoop", profile: "Profile", duration: float, *, nonlinear: bool = True):
    """The hybrid program of ``loop`` following ``profile`` for ``duration`` seconds, and its step count."""
    from ..loop import SetpointTable, servo_program

    h = loop.base_period
    n_steps = int(math.floor(duration / h + 1e-9))
    if n_steps < 2:
        raise ModelError(f"the duration {duration:g} s is shorter than two velocity-loop periods ({h:g} s)",
                         path="duration", value=duration)
    ctrl = loop.controller
    for key, delay in (("position_delay", ctrl.position_delay * ctrl.position_period),
                       ("velocity_delay", ctrl.velocity_delay * ctrl.velocity_period),
                       ("feedforward_delay", ctrl.feedforward_delay)):
        if delay >= duration:
            raise ModelError(f"the delay ({delay:g} s) is not shorter than the run ({duration:g} s)",
                             path=f"axes.{loop.axis}.controller.{key}", value=getattr(ctrl, key))
    Np = loop.position_ratio
    t_fine = np.arange(n_steps) * h
    t_pos = np.arange(-(-n_steps // Np)) * Np * h
    position, velocity, acceleration = profile.evaluate(t_pos)
    fine, _, _ = profile.evaluate(t_fine)
    table = SetpointTable(position, velocity, acceleration, fine)
    return servo_program(loop, table, nonlinear=nonlinear), n_steps


def simulate(loop: "ServoLoop", profile: "Profile", duration: float, *, nonlinear: bool = True) -> TimeSeries:
    """Simulate the closed loop following a setpoint profile.

    Parameters
    ----------
    loop : ServoLoop
        From :func:`sicomat.loop.build_servo_loop`.
    profile : Profile
        Setpoint (see :mod:`sicomat.setpoints`).
    duration : float
        Simulated time (s); the step is the velocity-loop period.
    nonlinear : bool
        ``False`` drops limits, quantizers and Coulomb friction (the linear loop).

    Returns
    -------
    TimeSeries
        Every named signal at every base step, with :class:`~sicomat.timeseries.StepMetrics` and
        ``info["wall_time_s"]`` (the kernel's run time, without the one-time compilation or cache
        load of the compiled kernel, which a two-step warm-up run absorbs).

    Raises
    ------
    SimulationDiverged
        The loop is unstable: the message gives the time at which the states blew up.
    """
    from .kernel import run

    program, n_steps = loop_program(loop, profile, duration, nonlinear=nonlinear)
    run(program, 2)  # loads (or compiles) the kernel, so that only the simulation itself is timed
    start = _time.perf_counter()
    result = run(program, n_steps)
    wall = _time.perf_counter() - start
    signals = {name: result.records[:, i] for i, name in enumerate(program.slot_names)}
    actual = signals["setpoint.fine"] - signals["following_error"]
    metrics = step_metrics(result.time, signals["setpoint.fine"], actual, profile.distance, start=profile.breaks[0])
    return TimeSeries(time=result.time, signals=signals, metrics=metrics,
                      info={"wall_time_s": wall, "samples": n_steps, "step": loop.base_period,
                            "axis": loop.axis})

