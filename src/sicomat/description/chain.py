"""The lowering of a ``components`` drive chain (:mod:`.components`) to lumped bodies and springs, by the
drive-train rules (:mod:`.drivetrain`): walk the parts motor to load, opening a body after each compliance,
then keep the compliances the ``detail`` asks for. Every body and spring records the parts and rules it
comes from (:class:`ChainModel`, shown by ``sicomat check --lumped``); ``docs/components.md`` states the rules
and the decisions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from . import drivetrain as dt
from .base import fail
from .mechanics import LumpedSpec

if TYPE_CHECKING:  # pragma: no cover
    from .components import ComponentsSpec

__all__ = ["ChainModel", "ChainBody", "ChainSpring", "derive", "GRAVITY"]

GRAVITY = 9.80665
"""m/s², standard gravity: the normal load of a horizontal axis's guides (the guide friction)."""


# --------------------------------------------------------------------------- the derived chain
@dataclass
class ChainBody:
    """A lumped body: ``value`` kg or kg·m² in its own coordinate; ``gain`` its rigid-motion ratio to
    the motor's coordinate (1 for the motor; the lead, m/rad, for the table of a screw axis);
    ``parts`` what it carries (``"parts.2: 1.2e-3 kg*m^2 (screw, π·ρ·L·d⁴/32 × ...)"``)."""

    name: str
    kind: Literal["translational", "rotational"]
    value: float
    gain: float
    parts: list[str] = field(default_factory=list)

    @property
    def referred(self) -> float:
        """The inertia seen at the motor's coordinate, ``value·gain²``."""
        return self.value * self.gain ** 2


@dataclass
class ChainSpring:
    """A spring from body ``between[0]`` to ``between[1]``; its stretch is ``ratio·q0 − q1`` in the
    downstream body's coordinate, ``stiffness`` in that coordinate's unit (N/m or N·m/rad);
    ``damping`` ``None`` until the damping ratio gives it; ``rule`` how it was derived."""

    name: str
    between: tuple[str, str]
    ratio: float
    stiffness: float
    rule: str
    damping: float | None = None
    frequency_hz: float | None = None    # its own frequency (the whole chain split at it), for 'auto'


@dataclass
class ChainModel:
    """The lowering's result: bodies and springs (motor to load), frictions, sensors, the actuator, the
    position used and notes (what was merged or dropped and why)."""

    bodies: list[ChainBody]
    springs: list[ChainSpring]
    frictions: dict[str, dict[str, Any]]
    sensors: dict[str, dict[str, Any]]
    actuator: dict[str, Any]
    position: float
    stroke: float | None
    detail: str
    notes: list[str] = field(default_factory=list)
    home: dict[str, str] = field(default_factory=dict)   # body of the walk → the body it ended up in
    lumped: LumpedSpec = field(init=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain data: ``{"position", "stroke", "detail", "bodies", "springs", "frictions", "sensors",
        "actuator", "notes"}`` (SI)."""
        return {"position": self.position, "stroke": self.stroke, "detail": self.detail,
                "bodies": [{"name": b.name, "kind": b.kind, ("mass" if b.kind == "translational" else "inertia"):
                            b.value, "parts": list(b.parts)} for b in self.bodies],
                "springs": [{"name": s.name, "between": list(s.between), "ratio": s.ratio,
                             "stiffness": s.stiffness, "damping": s.damping, "frequency_hz": s.frequency_hz,
                             "rule": s.rule} for s in self.springs],
                "frictions": self.frictions, "sensors": self.sensors, "actuator": self.actuator,
                "notes": list(self.notes)}


class _Builder:
    """Walks the parts motor to load, opening a body after each compliance."""

    def __init__(self) -> None:
        self.bodies: list[ChainBody] = []
        self.springs: list[ChainSpring] = []
        self.names: set[str] = set()

    def unique(self, name: str) -> str:
        base, n = name, 2
        while name in self.names:
            name, n = f"{base}_{n}", n + 1
        self.names.add(name)
        return name

    def open(self, kind: Literal["translational", "rotational"], gain: float, name: str | None = None) -> None:
        self.bodies.append(ChainBody(self.unique(name) if name else "", kind, 0.0, gain))

    @property
    def current(self) -> ChainBody:
        return self.bodies[-1]

    def add(self, value: float, what: str, name: str | None = None) -> None:
        """Add inertia (or mass) to the current body; the first contribution after a spring names it."""
        body = self.current
        if not body.name and name:
            body.name = self.unique(name)
        body.value += value
        body.parts.append(what)

    def spring(self, name: str, stiffness: float, ratio: float, rule: str, damping: float | None = None,
               next_kind: Literal["translational", "rotational"] | None = None) -> None:
        up = self.current
        kind = next_kind or up.kind
        self.open(kind, up.gain * ratio)
        self.springs.append(ChainSpring(self.unique(name), (up.name, ""), ratio, stiffness, rule, damping))


def _qty(value: float, unit: str) -> str:
    return f"{value:.6g} {unit}"


def derive(spec: "ComponentsSpec") -> ChainModel:
    """The lumped chain of ``spec`` at its position (a :class:`ChainModel`, ``.lumped`` the lumped form)."""
    parts = spec.parts
    stroke = spec.stroke()
    x = spec.resolved_position()
    if spec.position is not None:
        where = spec.transmission()
        if stroke is not None and not 0.0 <= x <= stroke:
            raise fail("the position is outside the stroke [0, {stroke:g}] m (the {kind}'s length)",
                       "position", x, stroke=stroke, kind=where.kind if where is not None else "")
    b = _Builder()
    motor = parts[0]
    linear = motor.kind == "linear-motor"
    label = {i: f"parts.{i} ({p.kind}{' ' + p.id if p.id else ''})" for i, p in enumerate(parts)}
    sensor_at: list[tuple[int, Any]] = []   # (part index, encoder or scale part), placed after merging
    if linear:
        b.open("translational", 1.0, "table")
        b.add(motor.primary_mass, f"{label[0]}: primary {_qty(motor.primary_mass, 'kg')}")
    else:
        b.open("rotational", 1.0, motor.name or "motor")
        b.add(motor.rotor_inertia, f"{label[0]}: rotor {_qty(motor.rotor_inertia, 'kg*m^2')}")
        if motor.shaft_torsional_stiffness is not None and spec.detail != "rigid":
            b.spring("motor_shaft", motor.shaft_torsional_stiffness, 1.0, f"{label[0]}: shaft_torsional_stiffness")
    moving_mass_parts: list[tuple[float, str]] = []
    for i, p in enumerate(parts[1:], start=1):
        if p.kind == "coupling":
            half = 0.5 * p.inertia
            b.add(half, f"{label[i]}: half the coupling {_qty(half, 'kg*m^2')}")
            b.spring(p.name or "coupling", p.torsional_stiffness or math.inf, 1.0,
                     f"{label[i]}: torsional_stiffness", p.damping)
            b.add(half, f"{label[i]}: half the coupling {_qty(half, 'kg*m^2')}")
        elif p.kind == "gearbox":
            b.add(p.input_inertia, f"{label[i]}: input inertia {_qty(p.input_inertia, 'kg*m^2')}")
            b.spring(p.name or "gearbox", p.torsional_stiffness or math.inf, 1.0 / p.ratio,
                     f"{label[i]}: torsional_stiffness at the output, ratio i = {p.ratio:g} (stretch θ_in/i − θ_out)")
        elif p.kind == "ball-screw":
            lead = p.lead / (2.0 * math.pi)
            js = dt.screw_inertia(p.diameter, p.length, density=p.density)
            frac = x / p.length
            near, far = 0.5 * js * frac, js - 0.5 * js * frac
            rule_j = f"π·ρ·L·d⁴/32 = {_qty(js, 'kg*m^2')} (nominal d, whole length L)"
            b.add(near, f"{label[i]}: screw between motor end and nut, half: {_qty(near, 'kg*m^2')} of {rule_j}",
                  "screw")
            kt = dt.screw_torsional_stiffness(p.root_diameter, x, shear_modulus=p.shear_modulus)
            b.spring("screw_torsion", kt, 1.0, f"{label[i]}: G·π·d_r⁴/(32·l), l = {x:.6g} m from the motor-side end")
            b.add(far, f"{label[i]}: screw at the nut and beyond: {_qty(far, 'kg*m^2')}", "screw_nut")
            if p.nut_stiffness is not None and p.bearing_stiffness is not None:
                kax = dt.screw_axial_stiffness(p.root_diameter, p.length, x, p.mounting,
                                               nut_stiffness=p.nut_stiffness, bearing_stiffness=p.bearing_stiffness,
                                               youngs_modulus=p.youngs_modulus)
                form = "A·E·L/(a·b)" if p.mounting == "fixed-fixed" else "A·E/x"
                rule = (f"{label[i]}: shaft {form} ({p.mounting}, x = {x:.6g} m) + nut + bearing in series")
            else:
                kax, rule = math.inf, f"{label[i]}: rigid (no nut/bearing stiffness; detail 'rigid')"
            b.spring("screw_axial", kax, lead, rule + f", through the lead p/2π = {lead:.6g} m/rad",
                     next_kind="translational")
        elif p.kind == "rack-pinion":
            b.add(p.pinion_inertia, f"{label[i]}: pinion {_qty(p.pinion_inertia, 'kg*m^2')}", "pinion")
            b.spring(p.name or "rack_mesh", p.mesh_stiffness or math.inf, p.pinion_radius,
                     f"{label[i]}: mesh_stiffness at the pitch line, r = {p.pinion_radius:.6g} m",
                     next_kind="translational")
        elif p.kind == "belt":
            r = p.drive_pulley_radius
            b.add(p.drive_pulley_inertia, f"{label[i]}: drive pulley {_qty(p.drive_pulley_inertia, 'kg*m^2')}",
                  "pulley")
            if p.length is not None:
                spans = (dt.linear_belt_spans(x, p.length) if p.arrangement == "end-driven"
                         else dt.omega_belt_spans(x, p.length))
                kb = dt.belt_axis_stiffness(p.specific_stiffness, spans)
                rule = (f"{label[i]}: c_spec/L per span, spans {spans[0]:.6g} m and {spans[1]:.6g} m in parallel "
                        f"({p.arrangement})")
            else:
                kb, rule = math.inf, f"{label[i]}: rigid (no length; detail 'rigid')"
            b.spring(p.name or "belt", kb, r, rule + f", pulley radius {r:.6g} m", next_kind="translational")
            if p.arrangement == "end-driven":
                r_i = p.idler_pulley_radius or r
                belt_len = 2.0 * (p.length or 0.0) + math.pi * (r + r_i)
                if p.idler_pulley_inertia:
                    moving_mass_parts.append((p.idler_pulley_inertia / r_i ** 2,
                                              f"{label[i]}: idler J/r² = {_qty(p.idler_pulley_inertia / r_i ** 2, 'kg')}"))
                if p.length is not None:
                    m_belt = p.mass_per_length * belt_len
                    moving_mass_parts.append((m_belt, f"{label[i]}: belt {p.mass_per_length:g} kg/m × "
                                                      f"{belt_len:.6g} m = {_qty(m_belt, 'kg')}"))
            elif motor.mass is not None:   # omega: the motor rides on the carriage, the belt stands still
                moving_mass_parts.append((motor.mass, f"{label[0]}: motor mass on the carriage "
                                                      f"{_qty(motor.mass, 'kg')} (omega drive)"))
        elif p.kind in ("table", "guide"):
            if not b.current.name:
                b.current.name = b.unique("table")
            if p.kind == "table":
                b.add(p.mass, f"{label[i]}: {_qty(p.mass, 'kg')}", "table")
            elif p.carriage_mass:
                b.add(p.carriage_mass, f"{label[i]}: carriages {_qty(p.carriage_mass, 'kg')}", "table")
        elif p.kind in ("encoder", "scale"):
            sensor_at.append((i, p))
    for m, what in moving_mass_parts:
        b.bodies[-1].value += m
        b.bodies[-1].parts.append(what)
    for j, body in enumerate(b.bodies):   # a body no part named: after its spring
        if not body.name:
            body.name = b.unique(f"{b.springs[j - 1].name}_out" if j else "motor")
    for k, s in enumerate(b.springs):     # spring k joins bodies k and k + 1 (both named only now)
        s.between = (b.bodies[k].name, b.bodies[k + 1].name)
    for i, p in sensor_at:         # encoder inertias, on the body they turn with
        if p.kind == "encoder" and p.inertia:
            host = b.bodies[0] if p.mounting == "motor" else _last_rotational(b.bodies)
            host.value += p.inertia
            host.parts.append(f"{label[i]}: encoder {_qty(p.inertia, 'kg*m^2')}")
    chain = ChainModel(b.bodies, b.springs, {}, {}, {}, x, stroke, spec.detail,
                       home={body.name: body.name for body in b.bodies})
    hosts = [(p, *_host(b.bodies, p)) for _, p in sensor_at]   # where each sensor reads, before merging
    _guides(spec, chain, label)
    _massless(chain)
    _reduce(spec, chain)
    _damp(spec, chain)
    _sensors(spec, chain, hosts)
    chain.actuator = {"body": chain.bodies[0].name if not linear else chain.bodies[-1].name}
    motor_body = chain.bodies[0]
    if not linear and motor_body.kind == "translational":    # the whole chain lumped into the load
        chain.actuator.update(ratio=1.0 / motor_body.gain, stretch="rotational")
    chain.lumped = _lumped(chain)
    return chain


def _last_rotational(bodies: list[ChainBody]) -> ChainBody:
    return [b for b in bodies if b.kind == "rotational"][-1]


def _host(bodies: list[ChainBody], part: Any) -> tuple[str, float]:
    """The body a sensor part reads (name, gain) in the chain as walked: an encoder the motor (or, mounted
    at the load, the last rotating body), a scale the table."""
    if part.kind == "scale" or not any(b.kind == "rotational" for b in bodies):
        return bodies[-1].name, bodies[-1].gain
    host = bodies[0] if part.mounting == "motor" else _last_rotational(bodies)
    return host.name, host.gain


def _guides(spec: "ComponentsSpec", chain: ChainModel, label: dict[int, str]) -> None:
    """Guide friction on the load: Coulomb μ·(moving mass)·g + seals (a horizontal axis), viscous as given."""
    load = chain.bodies[-1]
    moving = load.value     # the translating mass (table, carriages, belt) before any merge
    motor = spec.parts[0]
    attraction = getattr(motor, "attraction_force", None) or 0.0   # an iron-core linear motor's magnets
    for i, p in enumerate(spec.parts):
        if p.kind != "guide":
            continue
        coulomb = p.friction_coefficient * (moving * GRAVITY + attraction) + (p.seal_friction or 0.0)
        entry: dict[str, Any] = {"between": [load.name, "ground"], "coulomb": coulomb,
                                 "viscous": p.viscous_damping or 0.0,
                                 "rule": f"{label[i]}: μ·m·g = {p.friction_coefficient:g} × {moving:.6g} kg × "
                                         f"{GRAVITY} m/s² (+ attraction {attraction:g} N) + seals {p.seal_friction or 0.0:g} N"}
        chain.frictions[p.name or ("guides" if "guides" not in chain.frictions else f"guides_{i}")] = entry


def _merge(chain: ChainModel, k: int, reason: str) -> None:
    """Make spring ``k`` rigid: its two bodies become one in the load-side body's coordinate."""
    up, down = chain.bodies[k], chain.bodies[k + 1]
    spring = chain.springs.pop(k)
    factor = (up.gain / down.gain) ** 2          # an inertia of ``up`` seen in ``down``'s coordinate
    down.value += up.value * factor
    down.parts[:0] = [f"{what} (× {factor:.6g}, referred)" if factor != 1.0 else what for what in up.parts]
    chain.bodies.pop(k)
    for name, fr in chain.frictions.items():
        if fr["between"][0] == up.name:
            fr["between"][0] = down.name
    if k > 0:
        prev = chain.springs[k - 1]
        prev.between = (prev.between[0], down.name)
        prev.ratio *= spring.ratio
        prev.stiffness /= spring.ratio ** 2
        if prev.damping is not None:
            prev.damping /= spring.ratio ** 2
    chain.home = {walked: (down.name if now == up.name else now) for walked, now in chain.home.items()}
    chain.notes.append(f"{spring.name} made rigid ({reason}): {up.name} lumped into {down.name}")


def _massless(chain: ChainModel) -> None:
    """Springs with infinite stiffness (a nut at its bearing, a part without stiffness at 'rigid') merge."""
    k = 0
    while k < len(chain.springs):
        if math.isinf(chain.springs[k].stiffness):
            _merge(chain, k, "infinite stiffness")
        else:
            k += 1


def _referred_stiffness(chain: ChainModel, k: int) -> float:
    return chain.springs[k].stiffness * chain.bodies[k + 1].gain ** 2


def _own_frequencies(chain: ChainModel) -> None:
    """Each spring's own frequency: the chain split at it, each side rigid (motor coordinate)."""
    for k, s in enumerate(chain.springs):
        ja = sum(b.referred for b in chain.bodies[: k + 1])
        jb = sum(b.referred for b in chain.bodies[k + 1:])
        s.frequency_hz = math.sqrt(_referred_stiffness(chain, k) * (1.0 / ja + 1.0 / jb)) / (2.0 * math.pi)


def _reduce(spec: "ComponentsSpec", chain: ChainModel) -> None:
    _own_frequencies(chain)
    if spec.detail == "rigid":
        while chain.springs:
            _merge(chain, 0, "detail 'rigid'")
    elif spec.detail == "auto":
        limit = spec.bandwidth_multiple * spec.bandwidth  # type: ignore[operator]
        k = 0
        while k < len(chain.springs):
            f = chain.springs[k].frequency_hz
            if f is not None and f >= limit:
                _merge(chain, k, f"own frequency {f:.4g} Hz ≥ {spec.bandwidth_multiple:g} × {spec.bandwidth:g} Hz")
            else:
                k += 1
        _own_frequencies(chain)
    elif spec.detail == "2-mass":
        _two_mass(chain)
        _own_frequencies(chain)


def _two_mass(chain: ChainModel) -> None:
    """One spring, the series of every compliance; each body between goes to the motor side by
    ``1 − c`` and to the load side by ``c`` of its inertia, ``c`` the compliance between the motor and it
    over the total (the static deflection shape, docs/components.md)."""
    if not chain.springs:
        raise fail("detail '2-mass' needs at least one compliance in the chain; use 'rigid'", "detail", "2-mass")
    if len(chain.springs) == 1:
        return
    compliances = [1.0 / _referred_stiffness(chain, k) for k in range(len(chain.springs))]
    total = sum(compliances)
    first, last = chain.bodies[0], chain.bodies[-1]
    j_motor, j_load = first.referred, last.referred
    parts_motor, parts_load = list(first.parts), list(last.parts)
    c = 0.0
    side: dict[str, str] = {}
    for k, body in enumerate(chain.bodies[1:-1], start=1):
        c += compliances[k - 1]
        share = c / total
        side[body.name] = first.name if share < 0.5 else last.name
        j_motor += (1.0 - share) * body.referred
        j_load += share * body.referred
        parts_motor.append(f"{body.name}: {1 - share:.4f} of {body.referred:.6g} kg*m^2 (referred)")
        parts_load.append(f"{body.name}: {share:.4f} of its inertia (referred)")
    names = [s.name for s in chain.springs]
    gain = last.gain
    spring = ChainSpring("transmission", (first.name, last.name), gain, 1.0 / total / gain ** 2,
                         "series of " + ", ".join(names))
    chain.bodies = [ChainBody(first.name, first.kind, j_motor / first.gain ** 2, first.gain, parts_motor),
                    ChainBody(last.name, last.kind, j_load / gain ** 2, gain, parts_load)]
    chain.springs = [spring]
    chain.home = {walked: side.get(now, now) for walked, now in chain.home.items()}
    for fr in chain.frictions.values():
        fr["between"][0] = last.name
    chain.notes.append(f"detail '2-mass': {', '.join(names)} in series as one spring")


def _damp(spec: "ComponentsSpec", chain: ChainModel) -> None:
    """A spring without a damping of its own gets a loss proportional to its stiffness, ``c = 2ζ·k/ω``,
    ``ω`` the frequency of the chain's mode whose strain energy lies most in that spring: that mode then
    has the damping ratio ζ (the others a little more or less, by ``ω_i/ω`` times their share of strain
    in the spring; docs/components.md). Modes of the undamped chain in the motor's coordinate."""
    if not chain.springs:
        return
    j = np.array([b.referred for b in chain.bodies])
    k = np.array([_referred_stiffness(chain, i) for i in range(len(chain.springs))])
    n = len(j)
    stiff = np.zeros((n, n))
    for i, ki in enumerate(k):
        stiff[i:i + 2, i:i + 2] += ki * np.array([[1.0, -1.0], [-1.0, 1.0]])
    scale = 1.0 / np.sqrt(j)
    w2, v = np.linalg.eigh(scale[:, None] * stiff * scale[None, :])
    shapes = scale[:, None] * v                      # mass-normalised mode shapes, columns
    strain = k[:, None] * (shapes[:-1, :] - shapes[1:, :]) ** 2   # spring × mode
    omega = np.sqrt(np.clip(w2, 0.0, None))
    flexible = omega > 1e-6 * omega.max()
    for i, s in enumerate(chain.springs):
        if s.damping is not None and chain.detail != "2-mass":
            continue
        share = np.where(flexible, strain[i] / np.where(flexible, strain.sum(axis=0), 1.0), -1.0)
        w = float(omega[int(np.argmax(share))])
        s.damping = 2.0 * spec.damping_ratio * s.stiffness / w
        s.rule += f"; damping 2ζ·k/ω, ζ = {spec.damping_ratio:g}, ω = 2π·{w / (2 * math.pi):.6g} Hz (its mode)"


def _sensors(spec: "ComponentsSpec", chain: ChainModel, hosts: list[tuple[Any, str, float]]) -> None:
    """Sensors on the bodies they ended up in: a sensor whose body was lumped into another reads through
    the rigid ratio between them (``ratio``, and ``stretch = "rotational"`` for an encoder on a
    translating body)."""
    bodies = {b.name: b for b in chain.bodies}
    linear = spec.parts[0].kind == "linear-motor"
    have_encoder = False

    def geared(walked: str, gain: float, own: str) -> dict[str, Any]:
        host = bodies[chain.home[walked]]
        entry: dict[str, Any] = {"body": host.name}
        if host.kind != own or abs(gain / host.gain - 1.0) > 1e-15:
            entry.update(ratio=gain / host.gain, stretch=own)
        return entry

    for p, walked, gain in hosts:
        if p.kind == "encoder":
            have_encoder = True
            entry = {**geared(walked, gain, "rotational"), "counts_per_revolution": p.resolution}
            chain.sensors[p.name or _free(chain.sensors, "encoder")] = entry
        else:
            entry = {**geared(walked, gain, "translational"), "resolution": p.resolution}
            chain.sensors[p.name or _free(chain.sensors, "scale")] = entry
    if not linear and not have_encoder:
        motor = next(iter(chain.home))
        chain.sensors[_free(chain.sensors, "encoder")] = geared(motor, 1.0, "rotational")
        chain.notes.append("no encoder part: sensor 'encoder' reads the motor shaft (no quantization)")


def _free(used: dict[str, Any], name: str) -> str:
    out, n = name, 2
    while out in used:
        out, n = f"{name}_{n}", n + 1
    return out


def _lumped(chain: ChainModel) -> LumpedSpec:
    bodies = {b.name: ({"mass": b.value} if b.kind == "translational" else {"inertia": b.value})
              for b in chain.bodies}
    couplings = {s.name: {"between": list(s.between), "ratios": [s.ratio, 1.0], "stiffness": s.stiffness,
                          "damping": s.damping or 0.0} for s in chain.springs}
    frictions = {name: {k: v for k, v in fr.items() if k != "rule"} for name, fr in chain.frictions.items()}
    return LumpedSpec.model_validate({"bodies": bodies, "couplings": couplings, "frictions": frictions,
                                      "actuators": {"motor": chain.actuator}, "sensors": chain.sensors})


