"""The ``components`` mechanics kind (issue 12, §3): an axis described as the ordered chain of its parts,
motor to load, lowered to lumped bodies and springs by the drive-train rules (:mod:`.drivetrain`).

A part is a table with ``kind`` (one of :data:`~sicomat.description.parts.KINDS`), the kind's parameters
and optionally ``id`` (the catalogue entry its values came from; the model-file loader fills in the
entry's values that the file does not give, :mod:`sicomat.catalogue.resolve`) and ``name`` (the body or
sensor it becomes). ``position`` is the nut's (carriage's) distance from the motor-side end of the
stroke, ``detail`` how many compliances are kept. The lowering (:func:`sicomat.description.chain.derive`) keeps
what it derived (:class:`ChainModel`: each body and spring with the parts and rules it comes from) for
``sicomat check --lumped``. The rules, their sources and the decisions are in ``docs/components.md``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

from pydantic import ConfigDict, Field, create_model, model_validator

from . import motor_checks as mc
from .chain import ChainModel, derive
from .base import Frequency, Name, Spec, fail, quantity
from .mechanics import LumpedSpec
from .parts import KINDS
from .registry import register

__all__ = ["ComponentsSpec", "PART_CLASSES", "STAGES", "DETAILS", "drive_defaults", "motor_drive_defaults", "motor_constants",
           "closest_parameters"]

DETAILS = ("rigid", "2-mass", "full", "auto")
STAGES: dict[str, int] = {"motor": 0, "linear-motor": 0, "coupling": 1, "gearbox": 1, "ball-screw": 2, "belt": 2,
                          "rack-pinion": 2, "guide": 3, "table": 3, "encoder": -1, "scale": -1}
"""Place of each kind in the chain, motor (0) to load (3): couplings and gearboxes (1) between the motor
and the one transmission (2), guides and tables (3) after it; sensors (-1) anywhere after the motor."""
_STAGE_WORDS = {0: "the motor", 1: "couplings and gearboxes", 2: "the transmission (ball-screw, belt or "
                "rack-pinion)", 3: "guides and tables"}


def _part_class(kind: str, params: type[Spec]) -> type[Spec]:
    title = "".join(w.capitalize() for w in kind.split("-")) + "Part"
    return create_model(title, __base__=params, __doc__=f"A ``{kind}`` part of a drive chain.", __module__=__name__,
                        kind=(Literal[kind], ...),  # type: ignore[arg-type]
                        id=(Annotated[str, Field(min_length=1)] | None, None),
                        recorded=(bool | None, None),
                        name=(Name | None, None))


PART_CLASSES: dict[str, type[Spec]] = {kind: _part_class(kind, params) for kind, params in KINDS.items()}
"""Kind → the part schema: the kind's parameters (:mod:`.parts`) plus ``kind``, ``id``, ``recorded`` and
``name``. ``recorded = true`` (written by Save Model beside an ``id``): the part holds the entry's values as
they were when the model was saved, and the loader does not read the entry again."""
globals().update({cls.__name__: cls for cls in PART_CLASSES.values()})   # importable by name: they pickle


def closest_parameters(kind: str, name: str) -> str:
    """``"; closest <kind> parameters: ..."`` for a misspelt key ``name`` of a ``kind`` part ('' if none).

    >>> closest_parameters("ball-screw", "mountng")
    '; closest ball-screw parameters: mounting'
    """
    import difflib

    close = difflib.get_close_matches(name, list(PART_CLASSES[kind].model_fields), n=3)
    return f"; closest {kind} parameters: {', '.join(close)}" if close else ""


if TYPE_CHECKING:   # the parts' classes are made at import; a type checker sees them as Any
    Part = Any
else:
    Part = Annotated[Union[tuple(PART_CLASSES.values())], Field(discriminator="kind")]


@register("mechanics")
class ComponentsSpec(Spec):
    """A drive chain of catalogue or inline parts, from the motor to the load.

    ``detail``: ``"full"`` keeps every compliance (each coupling, the gearbox, the screw's torsion and
    its axial stiffness, the belt, the rack mesh) as a spring; ``"2-mass"`` lumps them into one spring
    between the motor and the load; ``"rigid"`` keeps none (one body, the load, driven through the rigid
    transmission); ``"auto"`` keeps the compliances whose own frequency is below ``bandwidth_multiple``
    times ``bandwidth``. ``damping_ratio`` gives each derived spring without a damping of its own the
    damping ``2ζ√(k·m)`` (``m`` the reduced mass across it).
    """

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "components", "position": "0.4 m", "detail": "full",      # parts inline (no catalogue ids)
         "parts": [{"kind": "motor", "rotor_inertia": "23 kg*cm^2"},
                   {"kind": "coupling", "inertia": "1.2e-4 kg*m^2", "torsional_stiffness": "18000 N*m/rad"},
                   {"kind": "ball-screw", "lead": "10 mm", "diameter": "40 mm", "root_diameter": "34 mm",
                    "length": "1.2 m", "mounting": "fixed-supported", "nut_stiffness": "1000 N/um",
                    "bearing_stiffness": "1000 N/um"},
                   {"kind": "guide", "friction_coefficient": 0.005},
                   {"kind": "table", "mass": "350 kg"},
                   {"kind": "encoder", "resolution": 1048576}]}]})

    type: Literal["components"]
    parts: list[Part] = Field(min_length=2)
    position: Annotated[float, quantity("length"), Field(ge=0)] | None = None
    detail: Literal["rigid", "2-mass", "full", "auto"] = "full"
    bandwidth: Frequency | None = None
    bandwidth_multiple: Annotated[float, Field(gt=1)] = 10.0
    damping_ratio: Annotated[float, Field(ge=0, lt=1)] = 0.02
    datasheet_tolerance: Annotated[float, Field(gt=0, le=1)] = mc.DATASHEET_TOLERANCE

    @model_validator(mode="after")
    def _check(self) -> "ComponentsSpec":
        _check_order(self.parts)
        if self.detail == "auto" and self.bandwidth is None:
            raise fail("detail 'auto' keeps the compliances below a multiple of a bandwidth: give 'bandwidth' "
                       "(Hz, e.g. the velocity loop's)", "bandwidth", None)
        _check_needed(self)
        _check_datasheets(self)
        self._remember(derive(self))     # the position inside the stroke, positive stiffnesses
        return self

    def _key(self) -> tuple[Any, ...]:
        """What the derived chain depends on: the parts are frozen, so their identities stand for them
        (``model_copy(update=...)`` makes a new key and the chain is derived again)."""
        return (self.position, self.detail, self.bandwidth, self.bandwidth_multiple, self.damping_ratio,
                tuple(map(id, self.parts)))

    def _remember(self, chain: ChainModel) -> ChainModel:
        object.__setattr__(self, "_chain_cache", (self._key(), chain))
        return chain

    @property
    def warnings(self) -> list[str]:
        """Datasheet values that disagree by more than half the tolerance (but within it)."""
        return list(self._warnings)  # type: ignore[attr-defined]

    @property
    def chain(self) -> ChainModel:
        """What the lowering derived: bodies, springs, sensors, with their sources."""
        key, chain = getattr(self, "_chain_cache", (None, None))
        if key == self._key() and isinstance(chain, ChainModel):
            return chain
        return self._remember(derive(self))

    def to_lumped(self) -> LumpedSpec:
        """The chain as a :class:`~sicomat.description.mechanics.LumpedSpec`."""
        return self.chain.lumped

    def part(self, kind: str) -> Any | None:
        """The first part of ``kind`` (its parameters and ``id``), or ``None``."""
        return next((p for p in self.parts if p.kind == kind), None)

    def transmission(self) -> Any | None:
        """The ball screw, belt or rack and pinion of the chain (``None`` with a linear motor)."""
        return next((p for p in self.parts if STAGES[p.kind] == 2), None)

    def stroke(self) -> float | None:
        """Length (m) over which ``position`` runs: the screw's length between its bearings, the belt's
        centre distance (end-driven) or clamp distance (omega); ``None`` where the position changes
        nothing (rack and pinion, linear motor) or the belt's length is not given."""
        t = self.transmission()
        if t is None or t.kind == "rack-pinion":
            return None
        return t.length

    def resolved_position(self) -> float:
        """``position``, or mid-stroke by default (0 without a stroke)."""
        stroke = self.stroke()
        if self.position is not None:
            return self.position
        return 0.5 * stroke if stroke is not None else 0.0


# --------------------------------------------------------------------------- validation
def _check_order(parts: list[Any]) -> None:
    first = parts[0]
    if STAGES[first.kind] != 0:
        raise fail("a drive chain starts with its motor ('motor' or 'linear-motor'); got a {value} first",
                   "parts.0.kind", first.kind)
    stage, transmission = 0, None
    for i, part in enumerate(parts[1:], start=1):
        s = STAGES[part.kind]
        if s == -1:
            if part.kind == "encoder" and first.kind == "linear-motor":
                raise fail("a rotary encoder has no shaft to read on a linear-motor axis; use a 'scale'",
                           f"parts.{i}.kind", part.kind)
            continue
        if s == 0:
            raise fail("a chain has one motor, first; parts go from the motor to the load", f"parts.{i}.kind",
                       part.kind)
        if s < stage:
            raise fail("a {value} cannot come after {after}: parts go from the motor to the load (the motor, "
                       "couplings and gearboxes, one transmission, guides and tables)", f"parts.{i}.kind",
                       part.kind, after=_STAGE_WORDS[stage])
        if s == 2:
            if first.kind == "linear-motor":
                raise fail("a linear motor drives the table directly; a {value} has no place in its chain",
                           f"parts.{i}.kind", part.kind)
            if transmission is not None:
                raise fail("a chain has one transmission; {value} follows the {first} of parts.{at}",
                           f"parts.{i}.kind", part.kind, first=parts[transmission].kind, at=transmission)
            transmission = i
        if s == 1 and first.kind == "linear-motor":
            raise fail("a linear motor drives the table directly; a {value} has no place in its chain",
                       f"parts.{i}.kind", part.kind)
        stage = s
    if first.kind == "motor" and transmission is None:
        raise fail("a rotary motor needs a transmission to move the table: add a 'ball-screw', 'belt' or "
                   "'rack-pinion' part", "parts", None)
    if not any(p.kind == "table" for p in parts):
        raise fail("a drive chain ends in the load: add a 'table' part (its mass)", "parts", None)


_NEEDED: dict[str, tuple[str, ...]] = {
    "coupling": ("torsional_stiffness",), "gearbox": ("torsional_stiffness",),
    "ball-screw": ("nut_stiffness", "bearing_stiffness"), "rack-pinion": ("mesh_stiffness",), "belt": ("length",),
}
"""Parameters a compliant detail (every detail but ``rigid``) needs from each kind."""


def _check_needed(spec: ComponentsSpec) -> None:
    if spec.detail == "rigid":
        return
    for i, part in enumerate(spec.parts):
        for key in _NEEDED.get(part.kind, ()):
            if getattr(part, key) is None:
                origin = f"the catalogue entry {part.id!r}" if part.id else "the part"
                raise fail("detail {detail!r} needs the {kind}'s {key}, which neither {origin} nor the file "
                           "gives; add it to the part (or choose detail 'rigid')", f"parts.{i}.{key}", None,
                           detail=spec.detail, kind=part.kind, key=key, origin=origin)


def _check_datasheets(spec: ComponentsSpec) -> None:
    """Refuse a motor whose datasheet values disagree beyond ``datasheet_tolerance`` (kT ≈ √3·kE,
    T_mech = 3·R·J/kT², M0 = I0·kT); a disagreement beyond half of it is kept as a warning
    (:attr:`ComponentsSpec.warnings`, shown by ``sicomat check``)."""
    found: list[str] = []
    keys = {"kT_kE": "back_emf_constant", "T_mech": "mechanical_time_constant", "M0": "stall_torque"}
    for i, part in enumerate(spec.parts):
        if part.kind != "motor" or part.torque_constant is None:
            continue
        constants = motor_constants(part)
        for w in mc.datasheet_warnings(**constants, tolerance=spec.datasheet_tolerance):
            key = keys[w.name]
            raise fail("inconsistent datasheet values: {text}; fix the values or their bases, or widen "
                       "'datasheet_tolerance' if the datasheet really says so", f"parts.{i}.{key}",
                       getattr(part, key), text=w.message)
        for w in mc.datasheet_warnings(**constants, tolerance=spec.datasheet_tolerance / 2):
            found.append(f"parts.{i}.{keys[w.name]}: {w.message.split(' (check')[0]} (within the "
                         f"{spec.datasheet_tolerance:g} tolerance)")
    object.__setattr__(spec, "_warnings", found)


def motor_constants(motor: Any) -> dict[str, Any]:
    """A rotary motor part's constants in the checks' conventions: ``torque_constant`` per A rms,
    ``back_emf_constant`` line-to-line rms (V·s/rad), ``phase_resistance``, ``mechanical_time_constant``,
    ``stall_current`` (A rms,
    the currents read in the torque constant's basis), ``stall_torque``, ``rotor_inertia``."""
    kt = mc.torque_constant_rms(motor.torque_constant, motor.torque_constant_basis)
    scale = math.sqrt(0.5) if motor.torque_constant_basis == "peak" else 1.0   # current values to A rms
    out: dict[str, Any] = {"torque_constant": kt, "rotor_inertia": motor.rotor_inertia}
    if motor.back_emf_constant is not None:
        out["back_emf_constant"] = mc.back_emf_line_rms(motor.back_emf_constant, motor.back_emf_basis)
    if motor.resistance is not None:
        out["phase_resistance"] = mc.phase_resistance(motor.resistance, motor.resistance_basis)
    if motor.mechanical_time_constant is not None:
        out["mechanical_time_constant"] = motor.mechanical_time_constant
    if motor.stall_current is not None and motor.stall_torque is not None:
        out["stall_current"] = motor.stall_current * scale
        out["stall_torque"] = motor.stall_torque
    return out


# --------------------------------------------------------------------------- drive from the motor
def drive_defaults(spec: ComponentsSpec) -> dict[str, Any]:
    """The drive's constants that the chain's motor implies (:func:`motor_drive_defaults` of its first part)."""
    return motor_drive_defaults(spec.parts[0])


def motor_drive_defaults(m: Any) -> dict[str, Any]:
    """The drive's constants that a ``motor`` or ``linear-motor`` part implies (``[axes.X.drive]`` keys the file does not give).

    The drive's model is per phase, rms (``docs/components.md``): ``force_constant`` = kT per A rms (N·m/A,
    or N/A for a linear motor), ``back_emf_constant`` = the phase EMF rms per unit speed = kE_ll,rms/√3
    (so that the power balance ``T·ω = 3·E·I`` holds), ``resistance`` and ``inductance`` per phase,
    ``peak_current`` in A rms, ``supply_voltage`` = U_dc/√6 (the largest phase voltage rms a space-vector
    modulated inverter gives from its DC bus, U_ll,rms = U_dc/√2), ``pole_pairs`` or ``pole_pitch``.
    Nothing without the motor's torque (force) constant.
    """
    linear = m.kind == "linear-motor"
    kt_value = m.force_constant if linear else m.torque_constant
    basis = m.force_constant_basis if linear else m.torque_constant_basis
    if kt_value is None:
        return {}
    out: dict[str, Any] = {"force_constant": mc.torque_constant_rms(kt_value, basis)}
    to_rms = math.sqrt(0.5) if basis == "peak" else 1.0
    if m.back_emf_constant is not None:
        out["back_emf_constant"] = mc.back_emf_line_rms(m.back_emf_constant, m.back_emf_basis) / math.sqrt(3.0)
    if m.resistance is not None:
        out["resistance"] = mc.phase_resistance(m.resistance, m.resistance_basis)
    if m.inductance is not None:
        out["inductance"] = mc.phase_resistance(m.inductance, m.inductance_basis)
    if m.peak_current is not None:
        out["peak_current"] = m.peak_current * to_rms
    if m.dc_bus is not None and m.resistance is not None:
        out["supply_voltage"] = m.dc_bus / math.sqrt(6.0)
    if linear:
        if m.pole_pitch is not None:
            out["pole_pitch"] = m.pole_pitch
    elif m.pole_pairs is not None:
        out["pole_pairs"] = m.pole_pairs
    return out
