"""Drive-train physics: stiffness, inertia and speed limits of ball screws, belts, gearboxes, racks.

Free functions, SI in and out. A lead or a pitch radius is a ratio in m/rad (``docs/conventions.md``):
a lead of ``p`` metres per revolution is ``lead = p / (2π)``, so ``(2π/p)² = 1/lead²``. The rules and
their sources are written out in ``docs/components.md``; every function's docstring states its formula.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from ..errors import ModelError

__all__ = [
    "MOUNTINGS",
    "STEEL_DENSITY",
    "STEEL_SHEAR_MODULUS",
    "STEEL_YOUNGS_MODULUS",
    "WHIRL_FACTORS",
    "belt_axis_stiffness",
    "belt_span_stiffness",
    "critical_speed",
    "dn_speed_limit",
    "gearbox_stiffness_at_input",
    "inertia_at_input",
    "linear_belt_spans",
    "omega_belt_spans",
    "parallel_stiffness",
    "pinion_pitch_radius",
    "pulley_inertia",
    "reflected_inertia",
    "rotating_equivalent_mass",
    "screw_axial_stiffness",
    "screw_inertia",
    "screw_torsional_stiffness",
    "series_stiffness",
    "shaft_axial_stiffness",
    "torsional_to_translational",
    "translational_to_torsional",
]

STEEL_DENSITY = 7850.0
"""kg/m³; THK uses γ = 7.85·10⁻⁶ kg/mm³ for the screw shaft."""
STEEL_YOUNGS_MODULUS = 2.06e11
"""Pa; THK and NSK use E = 2.06·10⁵ N/mm² for the screw shaft."""
STEEL_SHEAR_MODULUS = 7.9e10
"""Pa; G = E / (2(1 + ν)) with ν = 0.3 gives 7.92·10¹⁰ (Shigley, Table A-5: 79.3 GPa for carbon steel)."""

MOUNTINGS = ("fixed-fixed", "fixed-supported", "fixed-free")
"""The ball-screw mountings of the model file (``mounting``), the fixed bearing at the motor side."""

WHIRL_FACTORS = {"fixed-free": 1.8751, "supported-supported": math.pi, "fixed-supported": 3.9266,
                 "fixed-fixed": 4.7300}
"""λ, the first root βL of the Euler–Bernoulli beam's frequency equation for each pair of end conditions
(Blevins, *Formulas for Natural Frequency and Mode Shape*, Table 8-1; THK's λ = 1.875, 3.142, 3.927, 4.73)."""


def _check_positive(name: str, value: float, *, zero: bool = False) -> None:
    if not (value > 0 or (zero and value == 0)) or math.isnan(value):
        raise ModelError(f"{name} must be {'≥ 0' if zero else '> 0'} (SI), got {value!r}", path=name, value=value)


def _check_mounting(mounting: str, allowed: Iterable[str] = MOUNTINGS) -> None:
    allowed = tuple(allowed)
    if mounting not in allowed:
        raise ModelError(f"unknown mounting {mounting!r}; expected one of {', '.join(allowed)}",
                         path="mounting", value=mounting)


def series_stiffness(*stiffnesses: float) -> float:
    """Springs in series: ``1/k = Σ 1/kᵢ``. An infinite stiffness (a rigid element) adds nothing."""
    if not stiffnesses:
        raise ModelError("series_stiffness needs at least one stiffness")
    for k in stiffnesses:
        _check_positive("stiffness", k)
    compliance = sum(0.0 if math.isinf(k) else 1.0 / k for k in stiffnesses)
    return math.inf if compliance == 0.0 else 1.0 / compliance


def parallel_stiffness(*stiffnesses: float) -> float:
    """Springs in parallel (they share one displacement): ``k = Σ kᵢ``."""
    for k in stiffnesses:
        _check_positive("stiffness", k, zero=True)
    return float(sum(stiffnesses))


def torsional_to_translational(torsional_stiffness: float, radius: float) -> float:
    """A torsional stiffness (N·m/rad) seen at a translation through ``x = radius·θ``: ``k = k_t / r²``.

    For a ball screw ``radius = lead = p/(2π)`` (m/rad), so ``k = k_t·(2π/p)²``; for a pinion or a pulley
    it is the pitch radius. Energy: ``½ k_t θ² = ½ k x²`` with ``θ = x/r``.
    """
    _check_positive("radius", radius)
    return torsional_stiffness / radius**2


def translational_to_torsional(stiffness: float, radius: float) -> float:
    """A translational stiffness (N/m) seen at the rotation: ``k_t = k·r²`` (the inverse of the above)."""
    _check_positive("radius", radius)
    return stiffness * radius**2


def _shaft_ea(root_diameter: float, length: float, position: float, mounting: str,
              youngs_modulus: float) -> float:
    """``E·A`` of the screw shaft (``A`` from the root diameter), after checking the mounting, the sizes and
    that the nut lies on the shaft (``0 ≤ position ≤ length``)."""
    _check_mounting(mounting)
    _check_positive("root_diameter", root_diameter)
    _check_positive("length", length)
    if not 0.0 <= position <= length:
        raise ModelError(f"nut position {position!r} m is outside the screw length [0, {length!r}] m",
                         path="position", value=position)
    return youngs_modulus * math.pi * root_diameter**2 / 4.0


# --------------------------------------------------------------------------- ball screw
def shaft_axial_stiffness(root_diameter: float, length: float, position: float, mounting: str, *,
                          youngs_modulus: float = STEEL_YOUNGS_MODULUS) -> float:
    """Axial stiffness of the screw shaft alone between its fixed bearing(s) and the nut (N/m).

    ``A = π d_r²/4`` from the **root** diameter (THK, NSK: "screw shaft thread minor diameter"; the thread
    lands carry little axial load). ``x = position`` is the nut's distance from the fixed (motor-side)
    bearing, ``0 ≤ x ≤ L``, ``L = length`` the distance between the bearings.

    - fixed–supported, fixed–free: ``k = A·E/x`` (only the segment between the fixed bearing and the nut
      carries the load; the supported end floats axially). Infinite at ``x = 0``.
    - fixed–fixed: ``k = A·E·L/(a·b)``, ``a = x``, ``b = L − x``: the two segments in parallel,
      ``A·E/a + A·E/b``. Smallest at mid-stroke, ``4·A·E/L``; infinite at either bearing.

    Sources: THK General Catalog, Ball Screw, "Axial rigidity of the screw shaft" (Ks = A·E/(1000·L) and
    A·E·L/(1000·a·b), L in mm); NSK Precision Machine Components, "Rigidity of the screw shaft".
    Assumptions: uniform shaft of the root diameter, no pretension loss, the bearings rigid here (see
    :func:`screw_axial_stiffness` for them).
    """
    ea = _shaft_ea(root_diameter, length, position, mounting, youngs_modulus)
    if mounting == "fixed-fixed":
        a, b = position, length - position
        return math.inf if a == 0.0 or b == 0.0 else ea * length / (a * b)
    return math.inf if position == 0.0 else ea / position


def screw_axial_stiffness(root_diameter: float, length: float, position: float, mounting: str, *,
                          nut_stiffness: float, bearing_stiffness: float,
                          youngs_modulus: float = STEEL_YOUNGS_MODULUS) -> float:
    """Axial stiffness of the screw assembly between the frame and the nut (N/m): shaft, nut and bearing(s).

    - fixed–supported, fixed–free: ``1/k = 1/k_shaft + 1/k_nut + 1/k_bearing`` with ``k_shaft = A·E/x``
      (THK: "Axial rigidity of the feed screw system", 1/K = 1/Ks + 1/Kn + 1/Kb (+ 1/Kh, housing, left to
      the user's bearing value)).
    - fixed–fixed (derived here): the nut is held by two paths in parallel, each a shaft segment in series
      with its own fixed bearing: ``k_path1 = 1/(a/(A·E) + 1/k_b)``, ``k_path2 = 1/(b/(A·E) + 1/k_b)``, then
      the nut in series: ``1/k = 1/k_nut + 1/(k_path1 + k_path2)``. With rigid bearings it reduces to
      ``A·E·L/(a·b)`` in series with the nut. ``bearing_stiffness`` is that of ONE fixed support (each is a
      preloaded angular-contact pair that takes load both ways, so both act in tension and compression).
      THK's simpler form (one bearing in series with ``A·E·L/(a·b)``) is never stiffer than this one
      (``f(s) = 1/(1/s + 1/k_b)`` is concave with ``f(0) = 0``, so ``f(a') + f(b') ≥ f(a' + b')``): with a
      rigid shaft it gives ``k_b`` where both preloaded bearings give ``2·k_b``.
    """
    _check_positive("nut_stiffness", nut_stiffness)
    _check_positive("bearing_stiffness", bearing_stiffness)
    if mounting != "fixed-fixed":
        shaft = shaft_axial_stiffness(root_diameter, length, position, mounting, youngs_modulus=youngs_modulus)
        return series_stiffness(shaft, nut_stiffness, bearing_stiffness)
    ea = _shaft_ea(root_diameter, length, position, mounting, youngs_modulus)
    paths = [series_stiffness(math.inf if seg == 0.0 else ea / seg, bearing_stiffness)
             for seg in (position, length - position)]
    return series_stiffness(nut_stiffness, parallel_stiffness(*paths))


def screw_torsional_stiffness(root_diameter: float, length: float, *,
                              shear_modulus: float = STEEL_SHEAR_MODULUS) -> float:
    """Torsional stiffness of the screw shaft between the motor-side end and the nut (N·m/rad).

    ``k_t = G·J_p/l = G·π·d_r⁴/(32·l)`` (Shigley, *Mechanical Engineering Design*, §4-12, θ = T·l/(G·J)),
    ``l = length`` from the motor-side (driven) end to the nut, root diameter (a lower bound: the lands
    add a little). Seen at the table through the lead: :func:`torsional_to_translational` ``(k_t, lead)``
    = ``k_t·(2π/p)²``. Infinite at ``l = 0``.
    """
    _check_positive("root_diameter", root_diameter)
    _check_positive("length", length, zero=True)
    return math.inf if length == 0.0 else shear_modulus * math.pi * root_diameter**4 / (32.0 * length)


def screw_inertia(diameter: float, length: float, *, density: float = STEEL_DENSITY) -> float:
    """Moment of inertia of the screw shaft about its axis (kg·m²): ``J = π·ρ·L·d⁴/32``, a solid cylinder.

    ``diameter`` is the **nominal** (outer) diameter, as THK ("Moment of inertia of a cylinder", screw
    shaft outer diameter) and the vendors' per-metre inertia tables do; the root diameter would
    underestimate it (the thread ridge is between the two, and (d_r/d)⁴ is ~0.7 for a 32×10 screw).
    ``length`` is the whole shaft (journals included if the caller adds them).
    """
    _check_positive("diameter", diameter)
    _check_positive("length", length)
    return math.pi * density * length * diameter**4 / 32.0


def reflected_inertia(mass: float, radius: float) -> float:
    """A translating mass seen at the rotating shaft: ``J_eq = m·r²`` (kg·m²).

    Ball screw: ``r = lead = p/(2π)``, ``J_eq = m (p/2π)²`` (THK, "Moment of inertia of a linearly moving
    object"); rack and pinion, belt: ``r`` the pitch radius. Energy: ``½ m v² = ½ J ω²``, ``v = r ω``.
    """
    _check_positive("mass", mass, zero=True)
    _check_positive("radius", radius)
    return mass * radius**2


def critical_speed(root_diameter: float, span: float, mounting: str, *,
                   youngs_modulus: float = STEEL_YOUNGS_MODULUS, density: float = STEEL_DENSITY) -> float:
    """First whirling (critical) speed of the screw shaft (rad/s), with no safety factor.

    ``ω_c = (λ/l)²·√(E·I/(ρ·A))`` with ``I = π d_r⁴/64``, ``A = π d_r²/4``, so ``√(I/A) = d_r/4``: the
    first bending frequency of a uniform beam of length ``l = span`` between its supports (Blevins, Table
    8-1), λ from :data:`WHIRL_FACTORS`. THK ("Critical speed of the screw shaft") writes the same as
    ``N = 60 λ²/(2π l²)·√(E·I·10³/(γ·A))·0.8`` in min⁻¹ and multiplies by **0.8**: apply that (or the
    vendor's factor) to the value returned. Root diameter; the nut is not counted as a support.
    """
    _check_mounting(mounting, WHIRL_FACTORS)
    _check_positive("root_diameter", root_diameter)
    _check_positive("span", span)
    lam = WHIRL_FACTORS[mounting]
    return (lam / span) ** 2 * (root_diameter / 4.0) * math.sqrt(youngs_modulus / density)


def dn_speed_limit(diameter: float, dn_mm_rpm: float) -> float:
    """The speed (rad/s) at which ``d·n`` reaches the ball-nut's DN limit (``d`` in mm, ``n`` in min⁻¹).

    ``n_max = DN/d_mm`` min⁻¹, returned as ``n_max·2π/60``. ``diameter`` is the ball-centre (≈ nominal)
    diameter. The limit belongs to the nut's recirculation design and is the vendor's (THK lists it per
    model, "DN value"; Engineers Edge, "Critical Speed Ball Screw": 76 200 for standard external return,
    133 300 with solid deflectors, 140 000 for internal transfer): no default is assumed.
    """
    _check_positive("diameter", diameter)
    _check_positive("dn_mm_rpm", dn_mm_rpm)
    return dn_mm_rpm / (diameter * 1e3) * 2.0 * math.pi / 60.0


# --------------------------------------------------------------------------- timing belt
def belt_span_stiffness(specific_stiffness: float, span: float) -> float:
    """A free belt span as a spring (N/m): ``k = c_spec/L_span``; ``c_spec = E·A`` of the belt (N per unit
    strain, the belt maker's "specific stiffness" c_spec, e.g. Gates/Optibelt/BRECOflex tables) and
    ``L_span`` the free length between tangent point and clamp. Infinite at zero length.
    """
    _check_positive("specific_stiffness", specific_stiffness)
    _check_positive("span", span, zero=True)
    return math.inf if span == 0.0 else specific_stiffness / span


def belt_axis_stiffness(specific_stiffness: float, spans: Iterable[float]) -> float:
    """Stiffness of a belt axis at the carriage (N/m), drive pulley held: the spans act in **parallel**.

    Both spans pull on the carriage (the pre-tension keeps the slack side loaded while the load stays
    below it), so ``k = Σ c_spec/L_i``. The teeth meshing and the wrap around the pulleys are left out
    (their compliance goes to the user's stiffness if they know it).
    """
    return parallel_stiffness(*(belt_span_stiffness(specific_stiffness, s) for s in spans))


def linear_belt_spans(position: float, centre_distance: float) -> tuple[float, float]:
    """Span lengths of an end-driven linear belt axis: a closed belt around the drive and the idler
    pulley, the carriage clamped to one strand at ``position`` from the drive pulley.

    Spans ``(x, 2C − x)``: drive→carriage direct, and carriage→idler→back along the other strand→drive
    (the wraps neglected). ``k(x) = c(1/x + 1/(2C − x))`` falls monotonically over ``0 < x ≤ C``: the axis
    is softest at the idler end, ``k = 2c/C``.
    """
    _check_positive("centre_distance", centre_distance)
    if not 0.0 <= position <= centre_distance:
        raise ModelError(f"carriage position {position!r} m is outside [0, {centre_distance!r}] m",
                         path="position", value=position)
    return position, 2.0 * centre_distance - position


def omega_belt_spans(position: float, length: float) -> tuple[float, float]:
    """Span lengths of an omega drive: the belt clamped at both ends of the frame (``length`` between the
    clamps), the drive pulley riding on the carriage at ``position`` from the motor-side clamp.

    Spans ``(x, L − x)``; ``k = c·L/(x(L − x))``, softest at mid-stroke, ``4c/L``.
    """
    _check_positive("length", length)
    if not 0.0 <= position <= length:
        raise ModelError(f"carriage position {position!r} m is outside [0, {length!r}] m",
                         path="position", value=position)
    return position, length - position


def pulley_inertia(radius: float, width: float, *, density: float, bore_radius: float = 0.0) -> float:
    """A pulley as a solid (or bored) disc: ``J = π·ρ·w·(r⁴ − r_b⁴)/2`` (kg·m²). Vendor tables give the
    inertia of a real toothed pulley; use this only when they do not (aluminium 2700, steel 7850 kg/m³).
    """
    _check_positive("radius", radius)
    _check_positive("width", width)
    _check_positive("density", density)
    if not 0.0 <= bore_radius < radius:
        raise ModelError(f"bore radius {bore_radius!r} m must lie in [0, radius = {radius!r} m)",
                         path="bore_radius", value=bore_radius)
    return math.pi * density * width * (radius**4 - bore_radius**4) / 2.0


def rotating_equivalent_mass(inertias: Iterable[float], radii: Iterable[float], belt_mass: float = 0.0) -> float:
    """Translational mass equivalent to rotating parts and the belt (kg): ``m = Σ Jᵢ/rᵢ² + m_belt``.

    Each pulley turns at ``v/rᵢ``, so its kinetic energy is ``½(Jᵢ/rᵢ²)v²``; the whole belt moves at ``v``
    (``m_belt`` = mass per metre × belt length). Add the carriage mass for the axis's moving mass.
    """
    inertias, radii = list(inertias), list(radii)
    if len(inertias) != len(radii):
        raise ModelError(f"{len(inertias)} inertias but {len(radii)} radii")
    _check_positive("belt_mass", belt_mass, zero=True)
    total = belt_mass
    for j, r in zip(inertias, radii, strict=True):
        _check_positive("inertia", j, zero=True)
        _check_positive("radius", r)
        total += j / r**2
    return total


# --------------------------------------------------------------------------- gearbox, rack and pinion
def gearbox_stiffness_at_input(output_stiffness: float, ratio: float) -> float:
    """Torsional stiffness of a gearbox given at its output (the datasheet's C_t21), referred to its input:
    ``k_in = k_out/i²``, ``i = n_in/n_out`` (> 1 for a reducer). Energy: ``θ_out = θ_in/i``.

    Efficiency (η) and backlash stay data: a loss factor and a dead band are not linear-model terms.
    """
    _check_positive("ratio", ratio)
    _check_positive("output_stiffness", output_stiffness)
    return output_stiffness / ratio**2


def inertia_at_input(output_inertia: float, ratio: float) -> float:
    """An inertia on the output shaft referred to the input: ``J_in = J_out/i²`` (same energy argument)."""
    _check_positive("ratio", ratio)
    _check_positive("output_inertia", output_inertia, zero=True)
    return output_inertia / ratio**2


def pinion_pitch_radius(module: float, teeth: int, *, helix_angle: float = 0.0) -> float:
    """Pitch radius of a (helical) pinion (m/rad): ``r = m_n·z/(2·cos β)`` (ISO 53 / DIN 3960 transverse
    module ``m_t = m_n/cos β``). Rack and pinion: ``J_eq = m·r²`` (:func:`reflected_inertia`); the mesh
    stiffness is the vendor's (e.g. in N/µm at the rack) and stays data, referred with
    :func:`translational_to_torsional`.
    """
    _check_positive("module", module)
    if teeth < 1:
        raise ModelError(f"a pinion needs at least one tooth, got {teeth!r}", path="teeth", value=teeth)
    if not 0.0 <= helix_angle < math.pi / 2:
        raise ModelError(f"helix angle {helix_angle!r} rad must lie in [0, π/2)", path="helix_angle",
                         value=helix_angle)
    return module * teeth / (2.0 * math.cos(helix_angle))
