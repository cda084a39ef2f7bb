"""Schemas of the catalogue's component kinds: one validated parameter set per kind, SI inside.

The kind strings (:data:`KINDS`' keys) and the ball-screw axis's parameter names are a contract
(issue 12, §3). Every quantity is a number (SI) or a string with units, as in model files. Datasheet
conventions that differ between vendors are explicit fields beside the value they qualify, required
whenever that value is given (never guessed): ``torque_constant_basis`` (per A ``rms`` or ``peak``),
``resistance_basis`` (``phase`` or ``line-to-line``), ``back_emf_basis`` (``line-to-line-rms``, the
usual datasheet form, ``line-to-line-peak``, ``phase-rms`` or ``phase-peak``). The same words are the
conventions of :mod:`sicomat.description.motor_checks`. ``docs/catalogue.md`` lists every field.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import BeforeValidator, Field, model_validator

from .base import Spec
from .units import UNITS, Unit, parse_quantity
from .drivetrain import STEEL_DENSITY, STEEL_SHEAR_MODULUS, STEEL_YOUNGS_MODULUS

__all__ = ["KINDS", "Dimension", "unit_of", "parameter_names", "Provenance", "Datasheet", "Typical",
           "MotorParameters", "LinearMotorParameters", "CouplingParameters", "GearboxParameters",
           "BeltParameters", "BallScrewParameters", "RackPinionParameters", "GuideParameters",
           "TableParameters", "EncoderParameters", "ScaleParameters", "STEEL"]


@dataclass(frozen=True)
class Dimension:
    """The unit a parameter is written in (kept in its annotation, read by :func:`unit_of`)."""

    unit: Unit


_EXTRA_UNITS = {
    "angular_speed": Unit("rad/s", "an angular speed (rad/s, e.g. '3000 rpm')"),
    "specific_stiffness": Unit("N", "a belt specific stiffness (N, i.e. N/m per m of span)"),
    "mass_per_length": Unit("kg/m", "a mass per length (kg/m)"),
    "density": Unit("kg/m**3", "a density (kg/m^3)"),
    "modulus": Unit("Pa", "an elastic modulus (Pa, e.g. '210 GPa')"),
}


def _unit(name: str) -> Unit:
    return _EXTRA_UNITS[name] if name in _EXTRA_UNITS else UNITS[name]


def _parse(name: str) -> BeforeValidator:
    unit = _unit(name)
    return BeforeValidator(lambda v: parse_quantity(v, unit))


def _dim(name: str) -> Dimension:
    return Dimension(_unit(name))


def _parse_lead(value: Any) -> float:
    """A lead per revolution in m: ``"10 mm"`` (per revolution) or ``"10 mm/rev"``."""
    try:
        return parse_quantity(value, UNITS["length"])
    except ValueError:
        try:
            return float(f"{2.0 * math.pi * parse_quantity(value, UNITS['radius']):.15g}")   # 15 digits, as units.py
        except ValueError:
            raise ValueError("expected a lead per revolution (m, e.g. '10 mm' or '10 mm/rev')") from None


Positive = Annotated[float, _parse("dimensionless"), Field(gt=0), _dim("dimensionless")]
NonNegative = Annotated[float, _parse("dimensionless"), Field(ge=0), _dim("dimensionless")]
Torque = Annotated[float, _parse("torque"), Field(gt=0), _dim("torque")]
Force = Annotated[float, _parse("force"), Field(gt=0), _dim("force")]
NonNegativeForce = Annotated[float, _parse("force"), Field(ge=0), _dim("force")]
Current = Annotated[float, _parse("current"), Field(gt=0), _dim("current")]
Voltage = Annotated[float, _parse("voltage"), Field(gt=0), _dim("voltage")]
Resistance = Annotated[float, _parse("resistance"), Field(gt=0), _dim("resistance")]
Inductance = Annotated[float, _parse("inductance"), Field(gt=0), _dim("inductance")]
Inertia = Annotated[float, _parse("inertia"), Field(gt=0), _dim("inertia")]
NonNegativeInertia = Annotated[float, _parse("inertia"), Field(ge=0), _dim("inertia")]
Mass = Annotated[float, _parse("mass"), Field(gt=0), _dim("mass")]
NonNegativeMass = Annotated[float, _parse("mass"), Field(ge=0), _dim("mass")]
Length = Annotated[float, _parse("length"), Field(gt=0), _dim("length")]
NonNegativeLength = Annotated[float, _parse("length"), Field(ge=0), _dim("length")]
Angle = Annotated[float, _parse("angle"), Field(ge=0), _dim("angle")]
Speed = Annotated[float, _parse("angular_speed"), Field(gt=0), _dim("angular_speed")]
LinearSpeed = Annotated[float, _parse("velocity"), Field(gt=0), _dim("velocity")]
TorsionalStiffness = Annotated[float, _parse("torsional_stiffness"), Field(gt=0), _dim("torsional_stiffness")]
LinearStiffness = Annotated[float, _parse("linear_stiffness"), Field(gt=0), _dim("linear_stiffness")]
TorsionalDamping = Annotated[float, _parse("torsional_damping"), Field(ge=0), _dim("torsional_damping")]
LinearDamping = Annotated[float, _parse("linear_damping"), Field(ge=0), _dim("linear_damping")]
TorqueConstant = Annotated[float, _parse("torque_constant"), Field(gt=0), _dim("torque_constant")]
ForceConstant = Annotated[float, _parse("force_constant"), Field(gt=0), _dim("force_constant")]
RotaryEmf = Annotated[float, _parse("rotary_emf"), Field(gt=0), _dim("rotary_emf")]
LinearEmf = Annotated[float, _parse("linear_emf"), Field(gt=0), _dim("linear_emf")]
Fraction = Annotated[float, _parse("fraction"), Field(gt=0, le=1), _dim("fraction")]
TimeConstant = Annotated[float, _parse("time"), Field(gt=0), _dim("time")]
SpecificStiffness = Annotated[float, _parse("specific_stiffness"), Field(gt=0), _dim("specific_stiffness")]
MassPerLength = Annotated[float, _parse("mass_per_length"), Field(gt=0), _dim("mass_per_length")]
Density = Annotated[float, _parse("density"), Field(gt=0), _dim("density")]
Modulus = Annotated[float, _parse("modulus"), Field(gt=0), _dim("modulus")]
Lead = Annotated[float, BeforeValidator(_parse_lead), Field(gt=0), Dimension(UNITS["length"])]

CurrentBasis = Literal["rms", "peak"]
ResistanceBasis = Literal["phase", "line-to-line"]
EmfBasis = Literal["line-to-line-rms", "line-to-line-peak", "phase-rms", "phase-peak"]

STEEL = {"density": STEEL_DENSITY, "youngs_modulus": STEEL_YOUNGS_MODULUS, "shear_modulus": STEEL_SHEAR_MODULUS}
"""Defaults of a ball screw's material: the drive-train rules' steel (:mod:`sicomat.description.drivetrain`:
ρ = 7850 kg/m³, E = 206 GPa, G = 79 GPa, the screw makers' values; alloy steels vary by ±3 %)."""


def _needs_basis(spec: Spec, pairs: tuple[tuple[str, str], ...]) -> None:
    for value, basis in pairs:
        if getattr(spec, value) is not None and getattr(spec, basis) is None:
            raise ValueError(f"'{value}' is given without '{basis}': state the datasheet's convention "
                             "(it differs between vendors and is never guessed)")


class MotorParameters(Spec):
    """A rotary permanent-magnet servo motor (three-phase)."""

    rotor_inertia: Inertia
    torque_constant: Optional[TorqueConstant] = None
    torque_constant_basis: Optional[CurrentBasis] = None
    back_emf_constant: Optional[RotaryEmf] = None
    back_emf_basis: Optional[EmfBasis] = None
    resistance: Optional[Resistance] = None
    resistance_basis: Optional[ResistanceBasis] = None
    inductance: Optional[Inductance] = None
    inductance_basis: Optional[ResistanceBasis] = None
    pole_pairs: Optional[Annotated[int, Field(gt=0)]] = None
    stall_torque: Optional[Torque] = None
    stall_current: Optional[Current] = None
    rated_torque: Optional[Torque] = None
    rated_current: Optional[Current] = None
    rated_speed: Optional[Speed] = None
    peak_torque: Optional[Torque] = None
    peak_current: Optional[Current] = None
    max_speed: Optional[Speed] = None
    dc_bus: Optional[Voltage] = None
    mass: Optional[Mass] = None
    shaft_torsional_stiffness: Optional[TorsionalStiffness] = None
    mechanical_time_constant: Optional[TimeConstant] = None

    @model_validator(mode="after")
    def _conventions(self) -> "MotorParameters":
        _needs_basis(self, (("torque_constant", "torque_constant_basis"), ("back_emf_constant", "back_emf_basis"),
                            ("resistance", "resistance_basis"), ("inductance", "inductance_basis")))
        return self


class LinearMotorParameters(Spec):
    """An iron-core or ironless linear motor (primary = the moving coil unit)."""

    primary_mass: Mass
    force_constant: Optional[ForceConstant] = None
    force_constant_basis: Optional[CurrentBasis] = None
    back_emf_constant: Optional[LinearEmf] = None
    back_emf_basis: Optional[EmfBasis] = None
    resistance: Optional[Resistance] = None
    resistance_basis: Optional[ResistanceBasis] = None
    inductance: Optional[Inductance] = None
    inductance_basis: Optional[ResistanceBasis] = None
    continuous_force: Optional[Force] = None
    continuous_current: Optional[Current] = None
    peak_force: Optional[Force] = None
    peak_current: Optional[Current] = None
    attraction_force: Optional[NonNegativeForce] = None
    pole_pitch: Optional[Length] = None
    max_speed: Optional[LinearSpeed] = None
    dc_bus: Optional[Voltage] = None

    @model_validator(mode="after")
    def _conventions(self) -> "LinearMotorParameters":
        _needs_basis(self, (("force_constant", "force_constant_basis"), ("back_emf_constant", "back_emf_basis"),
                            ("resistance", "resistance_basis"), ("inductance", "inductance_basis")))
        return self


class CouplingParameters(Spec):
    """A shaft coupling (bellows, disc, jaw): its total inertia and torsional stiffness."""

    inertia: NonNegativeInertia
    torsional_stiffness: Optional[TorsionalStiffness] = None
    damping: Optional[TorsionalDamping] = None
    rated_torque: Optional[Torque] = None
    max_speed: Optional[Speed] = None


class GearboxParameters(Spec):
    """A gearbox: ``ratio`` = input speed / output speed; stiffness and backlash at the output."""

    ratio: Positive
    input_inertia: NonNegativeInertia
    torsional_stiffness: Optional[TorsionalStiffness] = None
    backlash: Optional[Angle] = None
    efficiency: Optional[Fraction] = None
    rated_torque: Optional[Torque] = None
    max_input_speed: Optional[Speed] = None


class BeltParameters(Spec):
    """A timing-belt linear drive: pulleys, belt, arrangement (``end-driven``: drive pulley at one end,
    idler at the other, the carriage clamped to the belt; ``omega``: belt fixed at both ends of the
    stroke, the drive pulley rides on the carriage)."""

    drive_pulley_radius: Length
    drive_pulley_inertia: NonNegativeInertia
    idler_pulley_radius: Optional[Length] = None
    idler_pulley_inertia: Optional[NonNegativeInertia] = None
    specific_stiffness: SpecificStiffness
    mass_per_length: MassPerLength
    arrangement: Literal["end-driven", "omega"] = "end-driven"
    length: Optional[Length] = None
    width: Optional[Length] = None
    pitch: Optional[Length] = None


class BallScrewParameters(Spec):
    """A ball screw with its nut and support bearings. ``diameter`` is the nominal one, ``root_diameter``
    the core (the axial and torsional stiffness use it); ``length`` is the free length between the
    bearings; ``lead`` per revolution."""

    lead: Lead
    diameter: Length
    root_diameter: Length
    length: Length
    mounting: Literal["fixed-fixed", "fixed-supported", "fixed-free"]
    nut_stiffness: Optional[LinearStiffness] = None
    nut_preload: Optional[NonNegativeForce] = None
    bearing_stiffness: Optional[LinearStiffness] = None
    density: Density = STEEL["density"]
    youngs_modulus: Modulus = STEEL["youngs_modulus"]
    shear_modulus: Modulus = STEEL["shear_modulus"]
    dynamic_load: Optional[Force] = None
    max_speed: Optional[Speed] = None

    @model_validator(mode="after")
    def _core_inside(self) -> "BallScrewParameters":
        if not self.root_diameter < self.diameter:
            raise ValueError(f"root_diameter ({self.root_diameter:g} m) must be below diameter "
                             f"({self.diameter:g} m)")
        return self


class RackPinionParameters(Spec):
    """A rack and pinion: the pinion's pitch radius and inertia, the mesh stiffness at the pitch line."""

    pinion_radius: Length
    pinion_inertia: NonNegativeInertia
    module: Optional[Length] = None
    mesh_stiffness: Optional[LinearStiffness] = None
    backlash: Optional[NonNegativeLength] = None
    rack_mass_per_length: Optional[MassPerLength] = None


class GuideParameters(Spec):
    """A linear guide (profile rail or slideway): friction and the carriages' mass."""

    friction_coefficient: NonNegative
    seal_friction: Optional[NonNegativeForce] = None
    viscous_damping: Optional[LinearDamping] = None
    carriage_mass: Optional[NonNegativeMass] = None


class TableParameters(Spec):
    """A table, carriage or load: a rigid mass."""

    mass: Mass


class EncoderParameters(Spec):
    """A rotary encoder: counts per revolution (after interpolation), where it is mounted."""

    resolution: Annotated[int, Field(gt=0)]
    mounting: Literal["motor", "load"] = "motor"
    inertia: Optional[NonNegativeInertia] = None


class ScaleParameters(Spec):
    """A linear scale: its resolution (a length) and where it measures."""

    resolution: Length
    mounting: Literal["table", "carriage"] = "table"
    accuracy: Optional[Length] = None


KINDS: dict[str, type[Spec]] = {
    "motor": MotorParameters, "linear-motor": LinearMotorParameters, "coupling": CouplingParameters,
    "gearbox": GearboxParameters, "belt": BeltParameters, "ball-screw": BallScrewParameters,
    "rack-pinion": RackPinionParameters, "guide": GuideParameters, "table": TableParameters,
    "encoder": EncoderParameters, "scale": ScaleParameters,
}
"""Kind string (a contract) → its parameter schema."""


class Datasheet(Spec):
    """Values read from a vendor's public document."""

    source: Literal["datasheet"]
    family: str = Field(min_length=1)
    part_number: str = Field(min_length=1)
    document: str = Field(min_length=1)
    page: Union[Annotated[int, Field(gt=0)], Annotated[str, Field(min_length=1)]]
    note: Optional[str] = None


class Typical(Spec):
    """Representative values of a class of parts, not of one part number: ``range`` says how far real
    parts of the class spread."""

    source: Literal["typical"]
    range: str = Field(min_length=1)
    note: Optional[str] = None


Provenance = Annotated[Union[Datasheet, Typical], Field(discriminator="source")]


def parameter_names(kind: str) -> list[str]:
    """The parameters of ``kind`` in schema order."""
    return list(KINDS[kind].model_fields)


def unit_of(kind: str, name: str) -> Unit | None:
    """The unit parameter ``name`` of ``kind`` is written in; None for a word (``mounting``) or an integer.

    >>> unit_of("motor", "peak_torque").si
    'N*m'
    >>> unit_of("ball-screw", "mounting") is None
    True
    """
    field = KINDS[kind].model_fields[name]
    for item in field.metadata:
        if isinstance(item, Dimension):
            return item.unit
    return _find_dimension(field.annotation)


def _find_dimension(annotation: Any) -> Unit | None:
    if typing.get_origin(annotation) is Annotated:
        for item in annotation.__metadata__:
            if isinstance(item, Dimension):
                return item.unit
    for arg in typing.get_args(annotation):
        found = _find_dimension(arg)
        if found is not None:
            return found
    return None
