"""The machine description: one tree of validated, immutable pydantic models (the model-file schema).

Quantities are parsed to SI floats when the model is built (see :mod:`sicomat.description.units`); everything
downstream reads plain SI numbers. Changing a model means making a new one
(``machine.model_copy(update=...)`` or :func:`sicomat.io.modelfile.with_overrides`).
"""

from __future__ import annotations

from typing import Any, Literal, Mapping

from pydantic import ConfigDict, Field, model_validator

from .base import Inertia, Mass, Name, Spec, fail
from .registry import register
from .units import UNITS, parse_quantity

__all__ = [
    "GROUND", "Body", "Coupling", "Friction", "Actuator", "Sensor",
    "LumpedSpec", "resolve_stretch", "geared_kind", "quantization_step",
]

GROUND = "ground"
"""Reserved name of the fixed frame (the machine bed) in couplings, frictions and actuators."""

Kind = Literal["translational", "rotational"]


# --------------------------------------------------------------------------- lumped elements
class Body(Spec):
    """A rigid body with one degree of freedom: give ``mass`` (translation) or ``inertia`` (rotation)."""

    mass: Mass | None = None
    inertia: Inertia | None = None

    @model_validator(mode="after")
    def _one_of(self) -> "Body":
        if (self.mass is None) == (self.inertia is None):
            raise fail("a body needs exactly one of 'mass' (translational) or 'inertia' (rotational)", "")
        return self

    @property
    def kind(self) -> Kind:
        """``"translational"`` for a mass, ``"rotational"`` for an inertia."""
        return "translational" if self.mass is not None else "rotational"

    @property
    def value(self) -> float:
        """The mass (kg) or inertia (kg·m²)."""
        return self.mass if self.mass is not None else self.inertia  # type: ignore[return-value]


class _Link(Spec):
    """Common part of couplings and frictions: two ends and their transmission ratios.

    The link's stretch is ``ratios[0]*q[between[0]] - ratios[1]*q[between[1]]``; the ground's
    position is zero. ``stretch`` says whether that is a translation (m) or a rotation (rad); by
    default it is a translation when either end is a translational body, a rotation otherwise.
    """

    between: tuple[Name, Name]
    ratios: tuple[float, float] = (1.0, 1.0)
    stretch: Kind | None = None


class Coupling(_Link):
    """A spring with internal material damping between two bodies or a body and the ground."""

    stiffness: float = Field(default=0.0, ge=0)
    damping: float = Field(default=0.0, ge=0)


class Friction(_Link):
    """Viscous and Coulomb friction on the relative motion of two bodies (or a body and the ground).

    ``static`` is the breakaway force (default: equal to ``coulomb``); only the simulator uses the
    Coulomb and static parts, the linear model carries the viscous part.
    """

    viscous: float = Field(default=0.0, ge=0)
    coulomb: float = Field(default=0.0, ge=0)
    static: float | None = Field(default=None, ge=0)

    @model_validator(mode="after")
    def _static_above_coulomb(self) -> "Friction":
        if self.static is not None and self.static < self.coulomb:
            raise fail("the static (breakaway) friction must be at least the Coulomb friction {coulomb}",
                        "static", self.static, coulomb=self.coulomb)
        return self


class Actuator(Spec):
    """A force (on a mass) or torque (on an inertia), with its reaction on another body if given.

    ``ratio`` and ``stretch`` describe a motor geared rigidly to the body it drives: the motor's own
    coordinate is ``ratio * q[body]`` and is a rotation or a translation (``stretch``, default the
    body's kind), so a rotary motor can drive a translating body through a rigid screw
    (``ratio = 2*pi/p`` rad/m, the reciprocal of the lead); the body then receives ``ratio * u``.
    """

    body: Name
    reaction: Name | None = None
    ratio: float = 1.0
    stretch: Kind | None = None

    @model_validator(mode="after")
    def _nonzero(self) -> "Actuator":
        if self.ratio == 0:
            raise fail("the ratio must be non-zero", "ratio", self.ratio)
        return self


class Sensor(Spec):
    """A position or velocity measurement of a body, absolute or relative to another body.

    ``resolution`` (m for a mass, rad for an inertia; or ``counts_per_revolution`` for a rotary
    encoder) is the quantization step of a position sensor, applied where the CNC samples it.
    ``ratio`` and ``stretch`` (as for an :class:`Actuator`) describe a sensor geared rigidly to its
    body: it reads ``ratio * q[body]``, a rotation or a translation (default the body's kind), e.g. a
    motor encoder on a translating body that lumps the whole rigid axis.
    """

    body: Name
    relative_to: Name | None = None
    kind: Literal["position", "velocity"] = "position"
    resolution: float | None = Field(default=None, gt=0)
    counts_per_revolution: int | None = Field(default=None, gt=0)
    ratio: float = 1.0
    stretch: Kind | None = None

    @model_validator(mode="after")
    def _one_resolution(self) -> "Sensor":
        if self.ratio == 0:
            raise fail("the ratio must be non-zero", "ratio", self.ratio)
        quantization_step(self.resolution, self.counts_per_revolution)
        return self

    @property
    def step(self) -> float | None:
        """Quantization step in SI units (m or rad), or ``None``."""
        return quantization_step(self.resolution, self.counts_per_revolution)


def quantization_step(resolution: float | None, counts_per_revolution: int | None) -> float | None:
    """A position sensor's quantization step in SI units (m or rad) from its ``resolution`` or its
    ``counts_per_revolution`` (``None`` without either); giving both is a located validation error."""
    if resolution is not None and counts_per_revolution is not None:
        raise fail("give either 'resolution' or 'counts_per_revolution', not both", "counts_per_revolution",
                   counts_per_revolution)
    if counts_per_revolution is not None:
        return 2.0 * 3.141592653589793 / counts_per_revolution
    return resolution


# --------------------------------------------------------------------------- mechanics descriptions
_STIFFNESS = {"translational": "linear_stiffness", "rotational": "torsional_stiffness"}
_DAMPING = {"translational": "linear_damping", "rotational": "torsional_damping"}
_LOAD = {"translational": "force", "rotational": "torque"}


def _ratio_unit(body_kind: str, stretch: str) -> str:
    if body_kind == stretch:
        return "dimensionless"
    return "radius" if body_kind == "rotational" else "inverse_radius"


@register("mechanics")
class LumpedSpec(Spec):
    """The general lumped model: named bodies, couplings, frictions, actuators and sensors.

    Examples
    --------
    >>> spec = LumpedSpec(bodies={"m": {"mass": "2 kg"}},
    ...                   couplings={"k": {"between": ["m", "ground"], "stiffness": "8 N/m"}})
    >>> spec.bodies["m"].mass
    2.0
    """

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "lumped",
         "bodies": {"motor": {"inertia": "23 kg*cm^2"}, "screw": {"inertia": "2.37e-3 kg*m^2"},
                    "table": {"mass": "350 kg"}},
         "couplings": {"coupling": {"between": ["motor", "screw"], "stiffness": "18000 N*m/rad"},
                       "screw_nut": {"between": ["screw", "table"], "ratios": ["10 mm/rev", 1],
                                     "stiffness": "1.8e8 N/m", "damping": "6000 N*s/m"}},
         "frictions": {"guides": {"between": ["table", "ground"], "viscous": "300 N*s/m", "coulomb": "120 N"}},
         "actuators": {"motor": {"body": "motor"}},
         "sensors": {"encoder": {"body": "motor", "counts_per_revolution": 4096},
                     "scale": {"body": "table", "resolution": "0.05 um"}}},
        {"type": "lumped",   # two motors on one load (gantry), the load also held by a spring to the frame
         "bodies": {"left": {"mass": 20}, "right": {"mass": 20}, "beam": {"mass": 100}},
         "couplings": {"kl": {"between": ["left", "beam"], "stiffness": 1e7},
                       "kr": {"between": ["beam", "right"], "stiffness": 1e7},
                       "k0": {"between": ["beam", "ground"], "stiffness": 1e3}},
         "actuators": {"ml": {"body": "left"}, "mr": {"body": "right", "reaction": "beam"}},
         "sensors": {"gap": {"body": "left", "relative_to": "right"}}}]})

    type: Literal["lumped"] = "lumped"
    bodies: dict[Name, Body] = Field(min_length=1)
    couplings: dict[Name, Coupling] = Field(default_factory=dict)
    frictions: dict[Name, Friction] = Field(default_factory=dict)
    actuators: dict[Name, Actuator] = Field(default_factory=dict)
    sensors: dict[Name, Sensor] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _parse_link_quantities(cls, data: Any) -> Any:
        """Parse the units of links, whose dimensions depend on the kinds of the bodies they join."""
        if not isinstance(data, dict):
            return data
        bodies = data.get("bodies")
        if not isinstance(bodies, dict):
            return data
        kinds = {name: ("rotational" if isinstance(b, (dict, Body)) and _has_inertia(b) else "translational")
                 for name, b in bodies.items()}
        data = dict(data)
        for table, fields in (("couplings", {"stiffness": _STIFFNESS, "damping": _DAMPING}),
                              ("frictions", {"viscous": _DAMPING, "coulomb": _LOAD, "static": _LOAD})):
            links = data.get(table)
            if not isinstance(links, dict):
                continue
            data[table] = {name: _parse_link(link, kinds, fields, f"{table}.{name}")
                           for name, link in links.items()}
        for table in ("actuators", "sensors"):
            items = data.get(table)
            if isinstance(items, dict):
                data[table] = {name: _parse_geared(item, kinds, f"{table}.{name}") for name, item in items.items()}
        return data

    @model_validator(mode="after")
    def _check_topology(self) -> "LumpedSpec":
        names = set(self.bodies)
        if GROUND in names:
            raise fail("'ground' is reserved for the fixed frame and cannot name a body", f"bodies.{GROUND}")
        for table in ("couplings", "frictions"):
            for name, link in getattr(self, table).items():
                for end in link.between:
                    if end != GROUND and end not in names:
                        raise fail("unknown body {value}; expected one of {known}",
                                    f"{table}.{name}.between", end, known=_known(names))
                if link.between[0] == link.between[1]:
                    raise fail("a link needs two different ends", f"{table}.{name}.between",
                                list(link.between))
                if all(r == 0 for r, end in zip(link.ratios, link.between) if end != GROUND):
                    raise fail("at least one ratio of a body end must be non-zero",
                                f"{table}.{name}.ratios", list(link.ratios))
        for name, act in self.actuators.items():
            for key, end in (("body", act.body), ("reaction", act.reaction)):
                if end is not None and end not in names:
                    raise fail("unknown body {value}; expected one of {known}",
                                f"actuators.{name}.{key}", end, known=_known(names))
            if act.reaction is not None:
                if act.reaction == act.body:
                    raise fail("the reaction must act on another body", f"actuators.{name}.reaction",
                                act.reaction)
                if self.bodies[act.reaction].kind != self.bodies[act.body].kind:
                    raise fail("the reaction body must be of the same kind ({kind}) as the driven body",
                                f"actuators.{name}.reaction", act.reaction,
                                kind=self.bodies[act.body].kind)
        for name, sensor in self.sensors.items():
            for key, end in (("body", sensor.body), ("relative_to", sensor.relative_to)):
                if end is not None and end not in names:
                    raise fail("unknown body {value}; expected one of {known}",
                                f"sensors.{name}.{key}", end, known=_known(names))
            if sensor.relative_to is not None and \
                    self.bodies[sensor.relative_to].kind != self.bodies[sensor.body].kind:
                raise fail("a relative sensor needs two bodies of the same kind",
                            f"sensors.{name}.relative_to", sensor.relative_to)
        self._check_connected()
        return self

    def _check_connected(self) -> None:
        edges: list[tuple[str, str]] = []
        for link in (*self.couplings.values(), *self.frictions.values()):
            edges.append(link.between)
        for act in self.actuators.values():
            edges.append((act.body, act.reaction or GROUND))
        parent = {n: n for n in (*self.bodies, GROUND)}

        def root(n: str) -> str:
            while parent[n] != n:
                parent[n] = parent[parent[n]]
                n = parent[n]
            return n

        touched: set[str] = set()
        for a, b in edges:
            touched.update((a, b))
            parent[root(a)] = root(b)
        for name in self.bodies:
            if name not in touched:
                raise fail("body {value} is linked to nothing (no coupling, friction or actuator); "
                            "expected it to be connected to the rest of the axis", f"bodies.{name}", name)
        groups = {root(n) for n in self.bodies}
        if len(groups) > 1:
            ground_root = root(GROUND)
            cut = sorted(n for n in self.bodies if root(n) != ground_root) or sorted(self.bodies)
            raise fail("bodies {value} are not connected to the rest of the axis (or to the ground); "
                        "expected one connected mechanism", f"bodies.{cut[0]}", cut)

    def to_lumped(self) -> "LumpedSpec":
        """This description as the general lumped form (itself)."""
        return self


def _has_inertia(body: Any) -> bool:
    if isinstance(body, Body):
        return body.inertia is not None
    return "inertia" in body and body.get("mass") is None


def _known(names: set[str]) -> str:
    return ", ".join(sorted(names) + [GROUND])


def resolve_stretch(explicit: Any, between: Any, kinds: Mapping[str, str]) -> Kind:
    """Whether a link stretches in translation or rotation: ``explicit`` when given, else
    translational if either end is a translational body (``kinds``: body name → kind)."""
    if explicit in ("translational", "rotational"):
        return explicit
    ends = [kinds.get(e) for e in between if e != GROUND and e in kinds]
    return "translational" if "translational" in ends or not ends else "rotational"


def _parse_link(link: Any, kinds: dict[str, str], fields: dict[str, dict[str, str]], where: str) -> Any:
    if not isinstance(link, dict):
        return link
    between = link.get("between")
    if not (isinstance(between, (list, tuple)) and len(between) == 2 and all(isinstance(e, str) for e in between)):
        return link  # the field validator reports the shape error
    stretch = resolve_stretch(link.get("stretch"), between, kinds)
    out = dict(link)
    for key, units in fields.items():
        if key in out and out[key] is not None:
            try:
                out[key] = parse_quantity(out[key], UNITS[units[stretch]])
            except ValueError as exc:
                raise fail(str(exc), f"{where}.{key}", out[key]) from None
    ratios = out.get("ratios")
    if isinstance(ratios, (list, tuple)) and len(ratios) == 2:
        parsed = []
        for i, (end, ratio) in enumerate(zip(between, ratios)):
            unit = "dimensionless" if end == GROUND or end not in kinds else _ratio_unit(kinds[end], stretch)
            try:
                parsed.append(parse_quantity(ratio, UNITS[unit]))
            except ValueError as exc:
                raise fail(str(exc), f"{where}.ratios.{i}", ratio) from None
        out["ratios"] = parsed
    return out


def geared_kind(item: Any, kinds: Mapping[str, str]) -> Kind:
    """The kind of an actuator's or sensor's own coordinate: its ``stretch``, else its body's kind."""
    stretch = getattr(item, "stretch", None) if not isinstance(item, dict) else item.get("stretch")
    if stretch in ("translational", "rotational"):
        return stretch
    body = getattr(item, "body", None) if not isinstance(item, dict) else item.get("body")
    return "rotational" if isinstance(body, str) and kinds.get(body) == "rotational" else "translational"


def _parse_geared(item: Any, kinds: dict[str, str], where: str) -> Any:
    """Parse an actuator's or sensor's ``ratio`` (motor coordinate per body coordinate) and a sensor's
    ``resolution`` (in its own coordinate) with their units; an unknown body is reported by the
    topology check (a translational body is assumed meanwhile)."""
    if not isinstance(item, dict):
        return item
    out = dict(item)
    own = geared_kind(item, kinds)
    body = item.get("body")
    body_kind = kinds.get(body, "translational") if isinstance(body, str) else "translational"
    for key, unit in (("ratio", _ratio_unit(body_kind, own) if own != body_kind else "dimensionless"),
                      ("resolution", "angle" if own == "rotational" else "length")):
        if out.get(key) is not None:
            try:
                out[key] = parse_quantity(out[key], UNITS[unit])
            except ValueError as exc:
                raise fail(str(exc), f"{where}.{key}", out[key]) from None
    return out

