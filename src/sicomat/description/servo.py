"""Schema of the servo blocks of an axis: the drive (power converter), the CNC controller, the setpoint.

Each block kind has implementations chosen by ``type`` ("Modify Scheme" of the paper): the
controllers ``P-PI``, ``P-IP`` and ``P-TF`` (a velocity law given as a discrete transfer function),
the drive ``first-order`` (their lowerings: ``sicomat.servo.blocks``), the setpoints ``step``, ``ramp`` and
``trapezoid``. Units follow the axis: N, m for a linear motor on a linear axis; N·m, rad for a
rotary motor (see ``docs/servo.md``).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from .base import (Current, Fraction, Frequency, Gain, Inductance, Length, Name, NonNegativeTime, Resistance, Spec, Time, Voltage, fail, quantity)
from .units import UNITS, parse_quantity

__all__ = ["DriveSpec", "FilterSpec", "ControllerSpec"]


def _either_unit(value: Any, kinds: tuple[str, ...]) -> float:
    """Parse a quantity that may have one of several dimensions (e.g. N/A or N·m/A)."""
    if not isinstance(value, str):
        return parse_quantity(value, UNITS[kinds[0]])
    errors = []
    for kind in kinds:
        try:
            return parse_quantity(value, UNITS[kind])
        except ValueError as exc:
            errors.append(exc)
    names = " or ".join(UNITS[k].name for k in kinds)
    message = str(errors[0])
    if "unknown unit" in message or "cannot read" in message:
        raise errors[0]
    raise ValueError(f"expected {names}")


ForceConstant = Annotated[float, Field(gt=0)]


class DriveSpec(Spec):
    """The drive of paper II.D: a current loop modelled on the q axis as a first-order lag.

    ``force_constant`` (N/A or N·m/A) turns current into force or torque. Give the current loop's
    ``time_constant`` or its ``bandwidth`` (−3 dB, Hz; τ = 1/(2π f)). ``peak_current`` saturates the
    current reference. With ``supply_voltage`` the available current falls as the speed rises:
    ``(R i + Ke ω)² + (ω_el L i)² ≤ U²`` with the winding ``resistance``, the ``back_emf_constant``
    Ke (default: equal to the force constant, as for SI-consistent q-axis constants), the
    ``inductance`` L and the electrical speed ω_el = ``pole_pairs``·ω (rotary) or π·v/``pole_pitch``
    (linear).
    """

    type: Literal["first-order"] = "first-order"
    actuator: Name | None = None
    force_constant: float = Field(gt=0)
    time_constant: Time | None = None
    bandwidth: Frequency | None = None
    peak_current: Current | None = None
    supply_voltage: Voltage | None = None
    resistance: Resistance = 0.0
    back_emf_constant: float | None = Field(default=None, ge=0)
    inductance: Inductance = 0.0
    pole_pairs: int | None = Field(default=None, gt=0)
    pole_pitch: Length | None = None

    @model_validator(mode="before")
    @classmethod
    def _constants(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        data = dict(data)
        for key, kinds in (("force_constant", ("force_constant", "torque_constant")),
                           ("back_emf_constant", ("linear_emf", "rotary_emf"))):
            if data.get(key) is not None:
                try:
                    data[key] = _either_unit(data[key], kinds)
                except ValueError as exc:
                    raise fail(str(exc), key, data[key]) from None
        return data

    @model_validator(mode="after")
    def _lag(self) -> "DriveSpec":
        if (self.time_constant is None) == (self.bandwidth is None):
            raise fail("give exactly one of 'time_constant' or 'bandwidth' for the current loop", "time_constant",
                       self.time_constant)
        if self.supply_voltage is not None and self.resistance == 0 and self.inductance == 0:
            raise fail("a supply voltage limit needs the winding 'resistance' (and 'inductance' if known)",
                       "resistance", self.resistance)
        return self

    @property
    def tau(self) -> float:
        """Current-loop time constant (s)."""
        if self.time_constant is not None:
            return self.time_constant
        return 1.0 / (2.0 * 3.141592653589793 * self.bandwidth)  # type: ignore[operator]

    @property
    def ke(self) -> float:
        """Back-EMF constant (V·s/m or V·s/rad)."""
        return self.force_constant if self.back_emf_constant is None else self.back_emf_constant


class FilterSpec(Spec):
    """A second-order filter: ``low-pass`` (frequency, damping) or ``notch`` (frequency, width, depth).

    The notch is ``(s² + 2 ζ_z ω s + ω²)/(s² + 2 ζ_p ω s + ω²)`` with ``ζ_p = width/2`` (the −3 dB
    width relative to the centre frequency) and ``ζ_z = depth·ζ_p`` (depth 0: full notch; the gain at
    the centre is ``depth``). Discrete loops use the Tustin transform prewarped at the frequency.
    """

    type: Literal["low-pass", "notch"]
    frequency: Frequency
    damping: float = Field(default=0.707, gt=0)
    width: float = Field(default=0.5, gt=0)
    depth: Fraction = 0.0


Sampling = Annotated[float, quantity("time"), Field(ge=0)]
MAX_PERIOD_RATIO = 10000
"""Most velocity periods in one position period accepted (see ``ControllerSpec``)."""


class ControllerSpec(Spec):
    """The CNC cascade controller of paper II.E: position P, velocity PI or IP, feedforwards.

    Gains: ``Kv`` (1/s) of the position loop; the velocity loop's proportional gain either in
    physical units ``Kp`` (N·s/m, or N·m·s/m for a rotary motor on a linear axis: force or torque per
    axis velocity) or normalised ``Kp_normalized`` (1/s, the paper's Table I: divided by the rigid
    moving mass or inertia seen by the actuator); ``Ti`` (s) the integral time.
    Sampling: ``position_period`` and ``velocity_period`` (s; the position period a whole multiple
    of the velocity period), computation delays in samples of each loop.
    Feedback: ``position_sensor`` and ``velocity_sensor`` name sensors of the mechanics; a position
    sensor used for velocity is differenced at the velocity period, as a CNC does.
    Time domain of each loop: ``velocity_loop`` and ``position_loop`` are ``"discrete"`` (sampled,
    the CNC) or ``"continuous"`` (an analog loop, e.g. a drive's analog velocity loop behind a
    ±10 V command; a continuous position loop needs a continuous velocity loop). A continuous loop
    has no computation delay, quantization or sampling of its own: its period is then only the
    step at which the simulator samples it (``velocity_period``) or at which the interpolator hands
    it setpoints (``position_period``). See ``docs/servo.md``.

    ``type = "P-TF"``: the velocity law is ``u = Kp · N(z⁻¹)/D(z⁻¹) · e`` at the velocity period,
    ``numerator`` N and ``denominator`` D the coefficients of ascending powers of z⁻¹ (``D[0] ≠ 0``);
    no ``Ti``, anti-windup ``none``, a discrete velocity loop.
    """

    type: Literal["P-PI", "P-IP", "P-TF"] = "P-PI"
    position_sensor: Name
    velocity_sensor: Name | None = None
    Kv: Gain
    Kp: float | None = Field(default=None, gt=0)
    Kp_normalized: Gain | None = None
    Ti: Time | None = None
    numerator: list[float] | None = Field(default=None, min_length=1)
    denominator: list[float] | None = Field(default=None, min_length=1)
    anti_windup: Literal["clamping", "back-calculation", "none"] = "clamping"
    tracking_time: Time | None = None
    velocity_feedforward: Fraction = 0.0
    acceleration_feedforward: Fraction = 0.0
    feedforward_delay: NonNegativeTime = 0.0
    position_period: Sampling = 1e-3
    velocity_period: Sampling = 125e-6
    position_delay: int = Field(default=1, ge=0)
    velocity_delay: int = Field(default=1, ge=0)
    command_bits: int | None = Field(default=None, ge=2, le=32)
    velocity_filter: FilterSpec | None = None
    current_filters: list[FilterSpec] = Field(default_factory=list)
    velocity_loop: Literal["discrete", "continuous"] = "discrete"
    position_loop: Literal["discrete", "continuous"] = "discrete"

    @model_validator(mode="before")
    @classmethod
    def _kp_units(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("Kp") is not None:
            try:
                data = {**data, "Kp": _either_unit(data["Kp"], ("linear_velocity_gain", "rotary_velocity_gain"))}
            except ValueError as exc:
                raise fail(str(exc), "Kp", data["Kp"]) from None
        return data

    @model_validator(mode="before")
    @classmethod
    def _tf_anti_windup(cls, data: Any) -> Any:
        """A transfer-function law has no integrator to stop: its anti-windup defaults to none."""
        if isinstance(data, dict) and data.get("type") == "P-TF" and "anti_windup" not in data:
            data = {**data, "anti_windup": "none"}
        return data

    @model_validator(mode="before")
    @classmethod
    def _continuous_delays(cls, data: Any) -> Any:
        """A continuous loop computes without delay: its delay defaults to 0 instead of 1 sample."""
        if isinstance(data, dict):
            for loop in ("velocity", "position"):
                if data.get(f"{loop}_loop") == "continuous" and f"{loop}_delay" not in data:
                    data = {**data, f"{loop}_delay": 0}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> "ControllerSpec":
        if (self.Kp is None) == (self.Kp_normalized is None):
            raise fail("give exactly one of 'Kp' (physical units) or 'Kp_normalized' (1/s)", "Kp", self.Kp)
        self._law_parameters()
        if self.velocity_period <= 0 or self.position_period <= 0:
            raise fail("sample periods must be > 0 (for an analog loop set velocity_loop or position_loop "
                       "= 'continuous' and keep its period as the simulator's step)",
                       "velocity_period" if self.velocity_period <= 0 else "position_period",
                       self.velocity_period if self.velocity_period <= 0 else self.position_period)
        ratio = self.position_period / self.velocity_period
        if abs(ratio - round(ratio)) > 1e-9 * max(ratio, 1.0) or round(ratio) < 1:
            raise fail("the position period must be a whole multiple of the velocity period {tv} s",
                       "position_period", self.position_period, tv=self.velocity_period)
        if round(ratio) > MAX_PERIOD_RATIO:
            raise fail("the position period is more than {limit} velocity periods ({tv} s): CNCs use 1 to 32, and "
                       "the lifted position-loop model costs one matrix product per velocity period",
                       "position_period", self.position_period, tv=self.velocity_period, limit=MAX_PERIOD_RATIO)
        if self.velocity_loop == "discrete":    # sampled filters (Tustin) exist below the Nyquist frequency only
            filters = [("velocity_filter", self.velocity_filter)] if self.velocity_filter is not None else []
            for key, spec in filters + [(f"current_filters.{i}", f) for i, f in enumerate(self.current_filters)]:
                if spec.frequency >= 0.5 / self.velocity_period:
                    raise fail("filter frequency {value} Hz is not below the Nyquist frequency {nyquist:g} Hz of "
                               "the sampled velocity loop", f"{key}.frequency", spec.frequency,
                               nyquist=0.5 / self.velocity_period)
        if self.position_loop == "continuous" and self.velocity_loop != "continuous":
            raise fail("a continuous position loop needs a continuous velocity loop (a sampled inner loop "
                       "inside an analog outer loop is not a cascade a drive builds); set velocity_loop = "
                       "'continuous' or position_loop = 'discrete'", "position_loop", self.position_loop)
        for loop in ("velocity", "position"):
            if getattr(self, f"{loop}_loop") == "continuous" and getattr(self, f"{loop}_delay"):
                raise fail("a continuous loop has no computation delay: expected 0 samples (or a "
                           f"discrete {loop}_loop)", f"{loop}_delay", getattr(self, f"{loop}_delay"))
        if self.velocity_loop == "continuous" and self.command_bits is not None:
            raise fail("command_bits quantizes the current command of a discrete velocity loop; a "
                       "continuous velocity loop has no DAC of its own", "command_bits", self.command_bits)
        return self

    def _law_parameters(self) -> None:
        """The parameters of the velocity law that its ``type`` needs, and only those."""
        if self.type != "P-TF":
            if self.Ti is None:
                raise fail("a {kind} controller needs the integral time 'Ti'", "Ti", None, kind=self.type)
            for key in ("numerator", "denominator"):
                if getattr(self, key) is not None:
                    raise fail("'{key}' belongs to a 'P-TF' controller (a velocity law given as a transfer "
                               "function); a {kind} law has Kp and Ti", key, getattr(self, key), key=key,
                               kind=self.type)
            return
        for key in ("numerator", "denominator"):
            if getattr(self, key) is None:
                raise fail("a 'P-TF' controller needs its '{key}' (coefficients of ascending powers of z^-1)",
                           key, None, key=key)
        if self.Ti is not None:
            raise fail("a 'P-TF' controller has no integral time: its integrator, if any, is in the "
                       "denominator", "Ti", self.Ti)
        if self.denominator[0] == 0:  # type: ignore[index]
            raise fail("the first denominator coefficient (of z^0) must not be 0: the law would not be causal",
                       "denominator.0", 0.0)
        if not any(self.numerator):  # type: ignore[arg-type]
            raise fail("the numerator is all zeros: the velocity law would not act", "numerator",
                       self.numerator)
        if self.anti_windup != "none":
            raise fail("a 'P-TF' law has no integrator to stop: expected anti_windup = 'none'", "anti_windup",
                       self.anti_windup)
        if self.velocity_loop != "discrete":
            raise fail("a 'P-TF' law is a discrete transfer function: expected velocity_loop = 'discrete'",
                       "velocity_loop", self.velocity_loop)
