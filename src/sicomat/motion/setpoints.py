"""Single-axis setpoint profiles: step, ramp and trapezoidal velocity (S-curves: :mod:`sicomat.motion.trajectory`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np

from ..description.motion import RampSetpoint, SCurveSetpoint, SetpointSpec, StepSetpoint, TrapezoidSetpoint
from ..description.registry import Registry, registered_types
from .trajectory import JerkProfile, scurve_profile

__all__ = ["SetpointProfile", "Profile", "profile_from_spec", "lowers", "step_profile", "ramp_profile",
           "trapezoid_profile"]


class SetpointProfile(Protocol):
    """What a simulation reads from a setpoint: :class:`Profile`, the S-curve
    :class:`~sicomat.motion.trajectory.JerkProfile` and one axis of a path
    (:class:`~sicomat.motion.path.AxisSetpoint`) all have it (a static type, checked by mypy)."""

    @property
    def kind(self) -> str: ...

    @property
    def breaks(self) -> tuple[float, ...]: ...

    @property
    def end_time(self) -> float: ...

    @property
    def distance(self) -> float: ...

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class Profile:
    """A setpoint as a function of time: ``evaluate(t) -> (position, velocity, acceleration)``.

    Piecewise polynomial: ``breaks`` (s) and, per piece, the position, velocity and acceleration at its
    start (constant acceleration inside a piece); before the first break everything is 0.
    """

    breaks: tuple[float, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    accelerations: tuple[float, ...]
    kind: str = "profile"

    @property
    def distance(self) -> float:
        """Net displacement at the end of the last piece (for a ramp: 0, it never ends)."""
        return float(self.positions[-1]) if self.velocities[-1] == 0 else 0.0

    @property
    def end_time(self) -> float:
        """Time of the last break (s)."""
        return float(self.breaks[-1])

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at times ``t`` (arrays of the shape of ``t``)."""
        t = np.asarray(t, dtype=float)
        idx = np.searchsorted(np.asarray(self.breaks), t, side="right") - 1
        before = idx < 0
        idx = np.clip(idx, 0, len(self.breaks) - 1)
        dt = t - np.asarray(self.breaks)[idx]
        p0, v0, a0 = (np.asarray(x)[idx] for x in (self.positions, self.velocities, self.accelerations))
        pos = np.where(before, 0.0, p0 + v0 * dt + 0.5 * a0 * dt ** 2)
        vel = np.where(before, 0.0, v0 + a0 * dt)
        acc = np.where(before, 0.0, a0)
        return pos, vel, acc


def step_profile(distance: float, start: float = 0.0) -> Profile:
    """A position step (velocity and acceleration setpoints stay 0)."""
    return Profile((start,), (distance,), (0.0,), (0.0,), kind="step")


def ramp_profile(velocity: float, start: float = 0.0) -> Profile:
    """Position growing at constant ``velocity`` from ``start``."""
    return Profile((start,), (0.0,), (velocity,), (0.0,), kind="ramp")


def trapezoid_profile(distance: float, max_velocity: float, max_acceleration: float, start: float = 0.0) -> Profile:
    """Time-optimal move under velocity and acceleration limits (triangular when v_max is not reached).

    Examples
    --------
    >>> prof = trapezoid_profile(0.1, 1.0, 10.0)          # triangular: t_a = sqrt(D / a) = 0.1 s
    >>> round(prof.end_time, 12)
    0.2
    """
    if max_velocity <= 0 or max_acceleration <= 0:
        raise ValueError("max_velocity and max_acceleration must be > 0")
    sign = 1.0 if distance >= 0 else -1.0
    d = abs(distance)
    if d == 0:
        return step_profile(0.0, start)
    if d <= max_velocity ** 2 / max_acceleration:
        ta = np.sqrt(d / max_acceleration)
        tc, v = 0.0, max_acceleration * ta
    else:
        ta = max_velocity / max_acceleration
        v = max_velocity
        tc = (d - v * ta) / v
    a = max_acceleration
    breaks = [start, start + ta, start + ta + tc, start + 2 * ta + tc]
    pos = [0.0, 0.5 * a * ta ** 2, 0.5 * a * ta ** 2 + v * tc, d]
    vel = [0.0, v, v, 0.0]
    acc = [a, 0.0, -a, 0.0]
    if tc == 0.0:
        del breaks[1], pos[1], vel[1], acc[1]
    return Profile(tuple(breaks), tuple(sign * x for x in pos), tuple(sign * x for x in vel),
                   tuple(sign * x for x in acc), kind="trapezoid")


# --------------------------------------------------------------------------- the one lowering
AnyProfile = SetpointProfile
_LOWERINGS: Registry[Callable[[Any], AnyProfile]] = Registry("setpoint")


def lowers(type_name: str) -> Callable[[Callable[[Any], AnyProfile]], Callable[[Any], AnyProfile]]:
    """Decorator: the function lowers the setpoint ``type_name`` (registered in
    :mod:`sicomat.description.motion`) to its profile."""
    if type_name not in registered_types("setpoint"):
        known = ", ".join(registered_types("setpoint"))
        raise ValueError(f"no setpoint type {type_name!r} is registered; expected one of {known}")

    def decorate(fn: Callable[[Any], AnyProfile]) -> Callable[[Any], AnyProfile]:
        return _LOWERINGS.add(type_name, fn)

    return decorate


def profile_from_spec(spec: SetpointSpec) -> AnyProfile:
    """The profile a setpoint description (a model file's ``trajectory`` table) describes: the one
    lowering of the setpoint generator, used by ``simulate`` (model trajectory, ``--step``, ``--move``).

    Examples
    --------
    >>> profile_from_spec(StepSetpoint(type="step", distance=0.01, start=0.1)).breaks
    (0.1,)
    """
    lower = _LOWERINGS.get(spec.type)
    if lower is None:
        raise TypeError(f"setpoint type {spec.type!r} has no lowering in sicomat.motion.setpoints")
    return lower(spec)


@lowers("step")
def _step(spec: StepSetpoint) -> Profile:
    return step_profile(spec.distance, spec.start)


@lowers("ramp")
def _ramp(spec: RampSetpoint) -> Profile:
    return ramp_profile(spec.velocity, spec.start)


@lowers("trapezoid")
def _trapezoid(spec: TrapezoidSetpoint) -> Profile:
    return trapezoid_profile(spec.distance, spec.max_velocity, spec.max_acceleration, spec.start)


@lowers("s-curve")
def _scurve(spec: SCurveSetpoint) -> JerkProfile:
    return scurve_profile(spec.distance, spec.max_velocity, spec.max_acceleration, spec.max_jerk, spec.start)
