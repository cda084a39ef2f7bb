"""Drive and controller kinds ("Modify Scheme", paper III): a small protocol, a registry keyed by the
model file's ``type``, and ONE lowering per block.

A **drive kind** lowers its description to a :class:`~sicomat.servo.drive.DriveModel` (the current
loop as a lag from the current reference, the current and voltage limits) and names its lags for the
rigid tuning model. A **controller kind** lowers the velocity law of the cascade to a linear block:

- :meth:`ControllerKind.law`: the discrete law at the velocity period, inputs ``(e, e_int,
  u_sat − u, v_meas)`` — the velocity error, the error that feeds the integrator (gated by the
  clamping anti-windup), the saturation excess (back-calculation) and the measured velocity —
  output the effort ``u`` (N or N·m) from the law's state;
- :meth:`ControllerKind.continuous_law`: the same law in continuous time for an analog velocity loop,
  inputs ``(e, v_meas)``.

That lowering is the only place a law's algebra is written: the simulator
(:func:`~sicomat.servo.loop.servo_program`), the analog loop (:func:`~sicomat.servo.analog.analog_loop`),
the loop's linear model (:class:`~sicomat.servo.linear.LoopModel`: closed velocity loop, poles, the
frequency factors of :class:`~sicomat.frequency.loops.LoopAnalysis`) and the tuning's equivalent
delay (:func:`loop_delays`) all read it. The standard nonlinear elements (saturation, current and
voltage limit, quantization, anti-windup gate) stay those of the kernel.

A new type is one class with ``@CONTROLLERS.register`` (or ``@DRIVES.register``); its parameters are
fields of the description (``description/servo.py``), which the schema validates.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from .controller import DiscreteSS, velocity_law
from .drive import DriveModel
from ..description.registry import Registry
from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..description.servo import ControllerSpec, DriveSpec
    from .loop import ServoLoop

__all__ = ["DriveKind", "ControllerKind", "DRIVES", "CONTROLLERS", "drive_kind", "drive_model", "controller_kind",
           "FirstOrderDrive", "PIController", "IPController", "TransferFunctionController", "linear_law",
           "loop_delays"]

# --------------------------------------------------------------------------- drives
class DriveKind(Protocol):
    """A power converter: its lowering to a drive model and its lags (s) for the rigid tuning model."""

    type: str

    def lower(self, spec: "DriveSpec", rotational: bool) -> "DriveModel": ...

    def delays(self, model: "DriveModel") -> list[tuple[str, float]]: ...


DRIVES: Registry[DriveKind] = Registry("drive")


@DRIVES.register
class FirstOrderDrive:
    """``type = "first-order"``: the q-axis current loop as ``τ di/dt = i_ref − i`` (paper II.D)."""

    type = "first-order"

    def lower(self, spec: "DriveSpec", rotational: bool) -> DriveModel:
        if spec.pole_pairs is not None:
            electrical = float(spec.pole_pairs)
        elif spec.pole_pitch is not None:
            electrical = np.pi / spec.pole_pitch
        else:
            electrical = 0.0
        return DriveModel(
            tau=spec.tau, kt=spec.force_constant,
            i_peak=spec.peak_current if spec.peak_current is not None else np.inf,
            u_max=spec.supply_voltage if spec.supply_voltage is not None else np.inf,
            resistance=spec.resistance, ke=spec.ke, wl=electrical * spec.inductance, kind=self.type)

    def delays(self, model: "DriveModel") -> list[tuple[str, float]]:
        return [("current loop", model.tau)]     # a first-order lag ≈ a delay τ below its bandwidth


def drive_kind(name: str, *, path: str | None = None) -> DriveKind:
    """The drive kind of a ``type``."""
    return DRIVES.lookup(name, path=path)


def drive_model(spec: "DriveSpec", rotational: bool) -> DriveModel:
    """Lower a drive description by its kind; ``rotational`` says whether the actuator drives an inertia."""
    return drive_kind(spec.type, path="drive.type").lower(spec, rotational)


# --------------------------------------------------------------------------- controllers
class ControllerKind(Protocol):
    """The velocity law of a cascade controller (the position loop is a P law for every kind).

    ``tunable``: whether ``tune`` can set its gains (Kp and Ti of a PI-type law).
    """

    type: str
    tunable: bool

    def law(self, spec: "ControllerSpec", Kp: float, Ti: float, period: float,
            tracking_time: float | None) -> DiscreteSS: ...

    def continuous_law(self, spec: "ControllerSpec", Kp: float, Ti: float) -> DiscreteSS: ...


CONTROLLERS: Registry[ControllerKind] = Registry("controller")


class _PILike:
    tunable = True
    type = ""

    def law(self, spec: "ControllerSpec", Kp: float, Ti: float, period: float,
            tracking_time: float | None) -> DiscreteSS:
        return velocity_law(self.type, Kp, Ti, period, tracking_time)

    def continuous_law(self, spec: "ControllerSpec", Kp: float, Ti: float) -> DiscreteSS:
        """``dξ/dt = (Kp/Ti) e``; PI ``u = Kp e + ξ``, IP ``u = ξ − Kp v``."""
        D = np.array([[Kp, 0.0]]) if self.type == "P-PI" else np.array([[0.0, -Kp]])
        return DiscreteSS(np.array([[0.0]]), np.array([[Kp / Ti, 0.0]]), np.array([[1.0]]), D)


@CONTROLLERS.register
class PIController(_PILike):
    """``type = "P-PI"``: ``u = Kp e + z``, ``z+ = z + (Kp T/Ti) e`` (forward Euler)."""

    type = "P-PI"


@CONTROLLERS.register
class IPController(_PILike):
    """``type = "P-IP"``: ``u = z − Kp v_meas`` (proportional action on the measurement)."""

    type = "P-IP"


@CONTROLLERS.register
class TransferFunctionController:
    """``type = "P-TF"``: a velocity law given as a discrete transfer function at the velocity period,
    ``u = Kp · N(z⁻¹)/D(z⁻¹) · e`` with ``numerator`` N and ``denominator`` D in ascending powers of
    z⁻¹ (a CNC's "free" velocity-loop filter: PI with lead, double integrator, lag…).

    Lowered by its controllable canonical form (``scipy.signal.tf2ss``); the anti-windup is ``none``
    (a general law has no integrator to stop) and the velocity loop discrete. ``tune`` does not apply:
    it sets the Kp and Ti of a PI-type law, and this law's shape is fixed by its coefficients.
    """

    type = "P-TF"
    tunable = False

    def law(self, spec: "ControllerSpec", Kp: float, Ti: float, period: float,
            tracking_time: float | None) -> DiscreteSS:
        import scipy.signal

        num, den = np.asarray(spec.numerator, dtype=float), np.asarray(spec.denominator, dtype=float)
        k = max(num.size, den.size)     # z⁻¹ polynomials padded to one length are z polynomials
        num, den = np.pad(num, (0, k - num.size)), np.pad(den, (0, k - den.size))
        A, B, C, D = (np.atleast_2d(m) for m in scipy.signal.tf2ss(Kp * num, den))
        if A.size == 0:
            A, B, C = np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0))
        zero = np.zeros_like(B)
        return DiscreteSS(A, np.hstack([B, zero, zero, zero]), C,
                          np.hstack([D, np.zeros((1, 3))]))

    def continuous_law(self, spec: "ControllerSpec", Kp: float, Ti: float) -> DiscreteSS:
        raise ModelError("a 'P-TF' controller is a discrete transfer function: expected velocity_loop = "
                         "'discrete'", path="controller.velocity_loop", value=spec.velocity_loop)


def controller_kind(name: str, *, path: str | None = None) -> ControllerKind:
    """The controller kind of a ``type``."""
    return CONTROLLERS.lookup(name, path=path)


def linear_law(loop: "ServoLoop", Kp: float, Ti: float, *, error_form: bool = False) -> DiscreteSS:
    """The velocity law of ``loop``'s controller without its nonlinear elements, inputs
    ``(e, v_meas)``: discrete at the velocity period (the integrator fed by the error itself, no
    saturation excess), or continuous for an analog velocity loop.

    ``error_form=True`` folds the measurement input into the error one (``u = C_e(e) + C_v(v)``
    with ``e = r − v`` seen from ``e`` only: ``B_e − B_v``, ``D_e − D_v``): the law the loop gain
    sees, equal for P-PI and P-IP.
    """
    ctrl = loop.controller
    kind = controller_kind(ctrl.type, path=f"axes.{loop.axis}.controller.type")
    if ctrl.velocity_loop == "continuous":
        law = kind.continuous_law(ctrl, Kp, Ti)
        B, D = law.B, law.D
    else:
        law = kind.law(ctrl, Kp, Ti, ctrl.velocity_period, None)
        B = np.column_stack([law.B[:, 0] + law.B[:, 1], law.B[:, 3]])
        D = np.column_stack([law.D[:, 0] + law.D[:, 1], law.D[:, 3]])
    if error_form:
        B = np.column_stack([B[:, 0] - B[:, 1], np.zeros(B.shape[0])])
        D = np.column_stack([D[:, 0] - D[:, 1], np.zeros(D.shape[0])])
    return DiscreteSS(law.A, B, law.C, D)


def loop_delays(loop: "ServoLoop") -> list[tuple[str, float]]:
    """The lags of the velocity loop as delays (s), block by block, for the rigid model of the
    tuning (an analog loop keeps only the current loop and the filters).

    The ZOH ``Tv/2`` and the computation delay ``d_v·Tv`` (the controller's sampling), the drive's
    lags (its kind), the differencing of a position sensor ``Tv/2``, each filter's group delay at
    low frequency (low-pass ``2ζ/ω``; notch ``2(ζ_p − ζ_z)/ω``); a PI's forward-Euler integrator is
    neglected.
    """
    ctrl = loop.controller
    T = ctrl.velocity_period if ctrl.velocity_loop == "discrete" else 0.0    # an analog loop: no sampling
    pieces = [("hold", T / 2), ("computation", ctrl.velocity_delay * T)]
    pieces += drive_kind(loop.drive.kind).delays(loop.drive)
    vel = loop.mechanics.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
    if vel.kind == "position":
        pieces.append(("differencing", T / 2))
    filters = list(ctrl.current_filters) + ([ctrl.velocity_filter] if ctrl.velocity_filter else [])
    for f in filters:
        w = 2 * np.pi * f.frequency
        pieces.append((f"{f.type} filter",
                       2 * f.damping / w if f.type == "low-pass" else 2 * (f.width / 2) * (1 - f.depth) / w))
    return pieces
