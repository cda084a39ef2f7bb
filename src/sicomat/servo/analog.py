"""Continuous (analog) loops of the cascade, closed around the plant as one LTI continuous part.

A drive with an analog velocity loop (the CNC sends a ±10 V velocity command) or a fully analog
servo is linear and unsampled inside: its PI law, velocity-measurement and current-setpoint filters
join the continuous part of the simulation, which the kernel advances exactly (ZOH of the held
commands, stick–slip friction included). The digital parts around it (the interpolator's setpoints,
a sampled position loop, feedforward delays) stay kernel ops.

Every signal is a row over ``[x; xc; r]``: the plant states ``x`` (``servo_plant``), the
controller states ``xc`` (velocity filter, integral action, current filters) and the held inputs
``r`` (see :attr:`AnalogLoop.inputs`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .blocks import linear_law
from .controller import continuous_filter

if TYPE_CHECKING:  # pragma: no cover
    from .loop import ServoLoop
    from ..lti.plant import Plant

__all__ = ["AnalogLoop", "analog_loop"]


@dataclass(frozen=True, eq=False)
class AnalogLoop:
    """The plant with its continuous loops closed: ``d[x; xc]/dt = A [x; xc] + B r``.

    Attributes
    ----------
    A : ndarray, shape (nx + nc, nx + nc)
    B : ndarray, shape (nx + nc, n_inputs)
    inputs : tuple of str
        The held inputs ``r``: ``("velocity.command", "feedforward.effort")`` behind a discrete
        position loop, ``("setpoint.position", "feedforward.velocity", "feedforward.effort")`` when
        the position loop is continuous too (axis units: m or rad, per s; the feedforward effort in
        N or N·m, added to the controller's output).
    outputs : dict of str to ndarray
        Controller signals as rows over ``[x; xc; r]``: ``velocity.measured``, ``velocity.error``,
        ``velocity.integral`` (the integral action, N or N·m), ``current.command`` (A, before the
        current filters) and ``current.applied`` (A, the current loop's reference).
    n_controller : int
        ``nc``, the controller states (appended after the plant's).
    """

    A: np.ndarray
    B: np.ndarray
    inputs: tuple[str, ...]
    outputs: dict[str, np.ndarray]
    n_controller: int


def analog_loop(loop: "ServoLoop", plant: "Plant", *, error_form: bool = False) -> AnalogLoop:
    """Close the continuous loops of ``loop`` (``velocity_loop = "continuous"``) around ``plant``.

    The laws are those of the discrete loops without sampling: PI ``u = Kp e + ξ``, IP
    ``u = ξ − Kp v``, with ``dξ/dt = (Kp / Ti) e`` (``ξ`` the integral action in effort units),
    ``e = v_cmd − v`` in axis units; the current command ``u / kt`` plus the acceleration
    feedforward effort over ``kt``, through the current filters (continuous, unwarped), is the
    current loop's reference. A continuous position loop adds ``v_cmd = Kv (x_ref − x) + k_vff v_ref``.
    """
    ctrl, drv = loop.controller, loop.drive
    mech = loop.mechanics
    nx = plant.n_states
    position_analog = ctrl.position_loop == "continuous"
    inputs = (("setpoint.position", "feedforward.velocity", "feedforward.effort") if position_analog
              else ("velocity.command", "feedforward.effort"))
    vel_filter = [] if ctrl.velocity_filter is None else [_filter_ss(ctrl.velocity_filter)]
    cur_filters = [_filter_ss(spec) for spec in ctrl.current_filters]
    law = linear_law(loop, loop.Kp, loop.Ti, error_form=error_form)
    nc = sum(f[0].shape[0] for f in vel_filter + cur_filters) + law.A.shape[0]
    N = nx + nc + len(inputs)
    deriv = np.zeros((nx + nc, N))
    free = [nx]                                    # next unused controller state

    def unit(i: int) -> np.ndarray:
        row = np.zeros(N)
        row[i] = 1.0
        return row

    def through(ss: tuple[np.ndarray, ...], signal: np.ndarray) -> np.ndarray:
        """Append the states of a SISO block driven by ``signal``; return its output row."""
        A, B, C, D = ss
        k, start = A.shape[0], free[0]
        states = np.zeros((k, N))
        states[:, start: start + k] = np.eye(k)
        deriv[start: start + k] = A @ states + np.outer(B[:, 0], signal)
        free[0] += k
        return C[0] @ states + D[0, 0] * signal

    def reading(sensor_name: str, gain: float, rate: bool) -> np.ndarray:
        """A sensor's reading (``rate``: its time derivative, a velocity sensor's own reading) in axis
        units: a position sensor read for velocity is differentiated, exactly, not differenced."""
        row = np.zeros(N)
        row[slice(mech.n, 2 * mech.n) if rate else slice(0, mech.n)] = mech.sensor(sensor_name).vector
        return row / gain

    r = {name: unit(nx + nc + j) for j, name in enumerate(inputs)}
    v_meas = reading(ctrl.velocity_sensor or ctrl.position_sensor, loop.velocity_gain, rate=True)
    for flt in vel_filter:
        v_meas = through(flt, v_meas)
    if position_analog:
        x_meas = reading(ctrl.position_sensor, loop.position_gain, rate=False)
        v_cmd = loop.Kv * (r["setpoint.position"] - x_meas) + ctrl.velocity_feedforward * r["feedforward.velocity"]
    else:
        v_cmd = r["velocity.command"]
    error = v_cmd - v_meas
    k, start = law.A.shape[0], free[0]      # the law: inputs (e, v_meas), states ξ (the integral action)
    states = np.zeros((k, N))
    states[:, start: start + k] = np.eye(k)
    deriv[start: start + k] = law.A @ states + np.outer(law.B[:, 0], error) + np.outer(law.B[:, 1], v_meas)
    free[0] += k
    xi = law.C[0] @ states
    effort = xi + law.D[0, 0] * error + law.D[0, 1] * v_meas
    command = (effort + r["feedforward.effort"]) / drv.kt
    applied = command
    for flt in cur_filters:
        applied = through(flt, applied)
    # the plant: its own dynamics, driven by the current reference
    deriv[:nx, :nx] = plant.A
    deriv[:nx] += np.outer(plant.B[:, 0], applied)
    outputs = {"velocity.measured": v_meas, "velocity.error": error, "velocity.integral": xi,
               "current.command": command, "current.applied": applied}
    return AnalogLoop(A=deriv[:, : nx + nc], B=deriv[:, nx + nc:], inputs=inputs, outputs=outputs,
                      n_controller=nc)


def _filter_ss(spec) -> tuple[np.ndarray, ...]:
    """A filter as a continuous state space (controllable canonical form of its transfer function)."""
    import scipy.signal

    num, den = continuous_filter(spec)
    return tuple(np.atleast_2d(m) for m in scipy.signal.tf2ss(num, den))
