"""The validated model-file schema (stage 1): base types and units, mechanics, the shorthands with
their lowering, servo blocks, motion blocks, the machine."""

from .base import (Spec, Name, quantity, fail, Mass, Inertia, NonNegativeMass, NonNegativeInertia, Length, LinearStiffness, LinearDamping, TorsionalDamping, Time, NonNegativeTime, Frequency, Gain, Current, Voltage, Resistance, Inductance, Fraction)
from .machine import MechanicsSpec, Axis, Machine
from .mechanics import GROUND, Body, Coupling, Friction, Actuator, Sensor, LumpedSpec, resolve_stretch
from .motion import (StepSetpoint, RampSetpoint, TrapezoidSetpoint, SCurveSetpoint, SetpointSpec, InterpolatorSpec)
from .registry import (Registry, KINDS, MechanicsKind, SetpointKind, register, spec_class, registered_types, spec_union, union_tags)
from .servo import DriveSpec, FilterSpec, ControllerSpec
from .shorthands import ChainSpec, BeltRackSpec, chain_to_lumped, belt_rack_to_lumped, belt_rack_equivalents
from .units import parse_quantity, Unit, UNITS

__all__ = [
    "Registry",
    "Spec",
    "Name",
    "quantity",
    "fail",
    "Mass",
    "Inertia",
    "NonNegativeMass",
    "NonNegativeInertia",
    "Length",
    "LinearStiffness",
    "LinearDamping",
    "TorsionalDamping",
    "Time",
    "NonNegativeTime",
    "Frequency",
    "Gain",
    "Current",
    "Voltage",
    "Resistance",
    "Inductance",
    "Fraction",
    "MechanicsSpec",
    "Axis",
    "Machine",
    "GROUND",
    "Body",
    "Coupling",
    "Friction",
    "Actuator",
    "Sensor",
    "LumpedSpec",
    "resolve_stretch",
    "StepSetpoint",
    "RampSetpoint",
    "TrapezoidSetpoint",
    "SCurveSetpoint",
    "SetpointSpec",
    "InterpolatorSpec",
    "KINDS",
    "MechanicsKind",
    "SetpointKind",
    "register",
    "spec_class",
    "registered_types",
    "spec_union",
    "union_tags",
    "DriveSpec",
    "FilterSpec",
    "ControllerSpec",
    "ChainSpec",
    "BeltRackSpec",
    "chain_to_lumped",
    "belt_rack_to_lumped",
    "belt_rack_equivalents",
    "parse_quantity",
    "Unit",
    "UNITS",
]
