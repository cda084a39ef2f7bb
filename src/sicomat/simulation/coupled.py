"""Simulation of coupled axes: the servo loops of several axes on one mechanics
(:class:`~sicomat.servo.coupled.CoupledLoop`), run as one hybrid program, read back as one
:class:`~sicomat.simulation.timeseries.TimeSeries` per axis (the signals a single-axis run has) and the
coupled mechanics' own signals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from ..errors import ModelError
from . import _require_memory, axis_series, named_signals, run_steps, timed_run
from .timeseries import TimeSeries

if TYPE_CHECKING:  # pragma: no cover
    import os
    from pathlib import Path

    import pandas
    from matplotlib.figure import Figure

    from ..motion.setpoints import SetpointProfile
    from ..progress import ProgressCallback
    from ..servo.coupled import CoupledLoop
    from ..servo.program import HybridProgram
    from ..robotics.path_model import RigidBodyDynamics
    from .kernel import KernelResult

__all__ = ["CoupledRun", "coupled_run_program", "simulate_coupled"]


@dataclass(frozen=True, eq=False)
class CoupledRun:
    """Result of :func:`simulate_coupled`.

    Attributes
    ----------
    axes : dict of str to TimeSeries
        Per axis, the signals a single-axis run has (following error, tool position, currents,
        controller signals, the sensors, every dof and friction force of the coupled mechanics) with its
        step metrics; ``run["X"]`` is ``run.axes["X"]``.
    mechanics : TimeSeries
        The coupled mechanics' signals: every dof's position and velocity, every sensor's reading,
        the acting friction forces (no metrics).
    info : dict
        ``wall_time_s`` (the kernel's run), ``samples``, ``step``, ``axes``.
    """

    axes: dict[str, TimeSeries]
    mechanics: TimeSeries
    info: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, axis: str) -> TimeSeries:
        return self.axes[axis]

    def to_pandas(self) -> "pandas.DataFrame":
        """One DataFrame indexed by time (s): each axis's own signals named ``"<axis>.<signal>"``
        (``X.following_error``, ``Y.current.applied``), then the coupled mechanics' signals (every dof,
        sensor and acting friction force) once, under their own names."""
        import pandas as pd

        shared = set(self.mechanics.names)
        columns = {f"{axis}.{name}": values for axis, series in self.axes.items()
                   for name, values in series.signals.items() if name not in shared}
        columns.update(self.mechanics.signals)
        return pd.DataFrame(columns, index=pd.Index(self.mechanics.time, name="time"))

    def to_csv(self, path: "str | os.PathLike") -> "Path":
        """Write :meth:`to_pandas` as CSV (atomically: temporary file, then rename)."""
        from ..io.csv import write_frame_csv

        return write_frame_csv(self.to_pandas(), path)

    def plot(self) -> "Figure":
        """The following error of every axis against time, one panel each; returns the Figure."""
        from ..plots.time import plot_following_errors

        return plot_following_errors({axis: (series.time, series["following_error"])
                                      for axis, series in self.axes.items()})


def coupled_run_program(coupled: "CoupledLoop", profiles: Mapping[str, "SetpointProfile"], duration: float, *,
                        nonlinear: bool = True) -> tuple["HybridProgram", int]:
    """The hybrid program of ``coupled`` following one profile per axis for ``duration`` seconds, and its
    step count (each profile sampled at its axis's position period; the memory estimated first)."""
    from ..servo.coupled import coupled_program
    from ..servo.loop import SetpointTable

    missing = [axis for axis in coupled.axes if axis not in profiles]
    if missing:
        raise ModelError(f"no setpoint profile for axis {missing[0]} (a coupled run takes one per axis: "
                         f"{', '.join(coupled.axes)})", path="profiles", value=missing[0])
    n_steps = run_steps(coupled.loops, duration)
    h = coupled.base_period
    one = {axis: SetpointTable(*profiles[axis].evaluate(np.zeros(1))) for axis in coupled.axes}
    probe = coupled_program(coupled, one, nonlinear=nonlinear)
    per_step = len(probe.record) + probe.continuous.A.shape[0] + 2 * probe.continuous.G.shape[0]
    n_pos = sum(-(-n_steps // loop.position_ratio) for loop in coupled.loops)
    delayed = sum(loop.controller.velocity_delay + loop.controller.position_delay for loop in coupled.loops)
    _require_memory(n_steps, per_step, n_pos, delayed)
    tables = {}
    for loop in coupled.loops:
        Np = loop.position_ratio
        t_pos = np.arange(-(-n_steps // Np)) * Np * h
        tables[loop.axis] = SetpointTable(*profiles[loop.axis].evaluate(t_pos))
    return coupled_program(coupled, tables, nonlinear=nonlinear), n_steps


def simulate_coupled(coupled: "CoupledLoop", profiles: Mapping[str, "SetpointProfile"], duration: float, *,
                     nonlinear: bool = True, progress: "ProgressCallback | None" = None,
                     dynamics: "RigidBodyDynamics | None" = None,
                     tool_positions: "Callable[[np.ndarray], Mapping[str, np.ndarray]] | None" = None) -> CoupledRun:
    """Simulate coupled axes, each following its setpoint profile.

    Parameters
    ----------
    coupled : CoupledLoop
        The axes' loops on one mechanics (:class:`sicomat.servo.coupled.CoupledLoop`).
    profiles : mapping of str to Profile
        One setpoint profile per axis (axis units), sampled by that axis's position loop.
    duration : float
        Simulated time (s); the step is the shared velocity-loop period.
    nonlinear : bool
        ``False`` drops limits, quantizers and Coulomb friction (the linear loops).
    progress : callable, optional
        Told the phases, as :func:`sicomat.simulate` does.
    dynamics : RigidBodyDynamics, optional
        A robot's rigid-body dynamics (:func:`sicomat.robotics.path_model.rigid_body_dynamics`, about the
        configuration ``coupled.mechanics`` was linearised at, every joint free): the run then advances
        the mechanics with the robot's nonlinear dynamics (large motions,
        :mod:`sicomat.simulation.nonlinear`) instead of the linear model. ``info["engine"]`` says which.
    tool_positions : callable, optional
        The axes' tool coordinates from the joint displacements ``δq`` (n_steps, n): a mapping of axis to
        (n_steps,) that replaces those axes' ``tool.position`` (and so ``tool_error``) — for a large motion,
        the tool point by the robot's geometric model (:meth:`sicomat.robotics.path_model.ToolPoint.coordinates`)
        rather than the linear tool vectors.

    Returns
    -------
    CoupledRun
        One :class:`TimeSeries` per axis with the signal names of a single-axis run, and the coupled
        mechanics' signals.

    Raises
    ------
    ModelError
        A profile missing for an axis, a bad duration (see :func:`sicomat.simulate`).
    SimulationDiverged
        The coupled loops are unstable.
    ResourceError
        The run's arrays would exceed the memory limit.
    """
    from ..servo.coupled import axis_view, coupled_plant

    program, n_steps = coupled_run_program(coupled, profiles, duration, nonlinear=nonlinear)
    engine = None
    if dynamics is not None:
        from .nonlinear import run_nonlinear

        def engine(program: "HybridProgram", n: int) -> "KernelResult":
            return run_nonlinear(program, n, dynamics)
    result, wall = timed_run(program, n_steps, f"simulating axes {', '.join(coupled.axes)}: {n_steps} steps",
                             progress, engine)
    plant = coupled_plant(coupled)
    values = result.states @ plant.C.T
    outputs = {name: values[:, i] for i, name in enumerate(plant.outputs)}
    slots = list(program.slot_names) + list(program.aliases)
    tools = tool_positions(result.states[:, :coupled.mechanics.n]) if tool_positions is not None else {}
    axes = {}
    for loop in coupled.loops:
        own = {name: outputs[coupled_name]
               for name, coupled_name in axis_view(coupled, loop.axis, list(outputs)).items()}
        if loop.axis in tools:
            own["tool.position"] = np.asarray(tools[loop.axis], dtype=float)
        signals = named_signals(loop, program, result.records, profiles[loop.axis].evaluate(result.time)[0],
                                result.states, view=axis_view(coupled, loop.axis, slots), outputs=own)
        axes[loop.axis] = axis_series(loop, profiles[loop.axis], result.time, signals, wall=wall, nonlinear=nonlinear)
    mech = coupled.mechanics
    shared = [f"sensor.{s.name}" for s in mech.sensors]
    shared += [name for d in mech.dofs for name in (d.position, d.velocity)]
    signals = {name: outputs[name] for name in shared}
    signals.update({name: result.records[:, i] for i, name in enumerate(program.slot_names)
                    if name.startswith("friction.")})
    info = {"wall_time_s": wall, "samples": n_steps, "step": coupled.base_period, "axes": list(coupled.axes),
            "engine": "linear" if dynamics is None else "nonlinear"}
    return CoupledRun(axes=axes, mechanics=TimeSeries(time=result.time, signals=signals, info=dict(info)), info=info)
