"""Quantities with units at the model-file boundary: parse with pint, return SI floats."""

from __future__ import annotations

import math
import re
from functools import lru_cache
from typing import Any

__all__ = ["parse_quantity", "Unit", "UNITS"]


class Unit:
    """An expected physical dimension: its SI unit (pint syntax) and a name for messages.

    ``radians_optional``: the value may be written per radian where its SI unit has none (a gain
    in 1/s written in rad/s), radians then being dimensionless.
    """

    __slots__ = ("si", "name", "radians_optional")

    def __init__(self, si: str, name: str, *, radians_optional: bool = False) -> None:
        self.si = si
        self.name = name
        self.radians_optional = radians_optional

    def __repr__(self) -> str:
        return f"Unit({self.si!r}, {self.name!r})"


# The dimensions used in model files, by key. Radians are dimensionless (as in pint).
UNITS: dict[str, Unit] = {
    "mass": Unit("kg", "a mass (kg)"),
    "inertia": Unit("kg*m**2", "a moment of inertia (kg*m^2)"),
    "length": Unit("m", "a length (m)"),
    "first_moment": Unit("kg*m", "a first moment of mass (kg*m)"),
    "angle": Unit("rad", "an angle (rad)"),
    "time": Unit("s", "a time (s)"),
    "frequency": Unit("Hz", "a frequency (Hz)"),
    "force": Unit("N", "a force (N)"),
    "torque": Unit("N*m", "a torque (N*m)"),
    "linear_stiffness": Unit("N/m", "a linear stiffness (N/m)"),
    "torsional_stiffness": Unit("N*m/rad", "a torsional stiffness (N*m/rad)"),
    "linear_damping": Unit("N*s/m", "a linear damping coefficient (N*s/m)"),
    "torsional_damping": Unit("N*m*s/rad", "a torsional damping coefficient (N*m*s/rad)"),
    "dimensionless": Unit("", "a plain number"),
    "fraction": Unit("", "a fraction from 0 to 1 (or a percentage such as '80 %')"),
    "inverse_time": Unit("1/s", "a gain in 1/s", radians_optional=True),
    "velocity": Unit("m/s", "a velocity (m/s)"),
    "acceleration": Unit("m/s**2", "an acceleration (m/s^2)"),
    "jerk": Unit("m/s**3", "a jerk (m/s^3)"),
    "current": Unit("A", "a current (A)"),
    "voltage": Unit("V", "a voltage (V)"),
    "resistance": Unit("ohm", "a resistance (ohm)"),
    "inductance": Unit("H", "an inductance (H)"),
    "force_constant": Unit("N/A", "a force constant (N/A)"),
    "torque_constant": Unit("N*m/A", "a torque constant (N*m/A)"),
    "linear_emf": Unit("V*s/m", "a back-EMF constant (V*s/m)"),
    "rotary_emf": Unit("V*s/rad", "a back-EMF constant (V*s/rad)"),
    "linear_velocity_gain": Unit("N*s/m", "a velocity gain (N*s/m)"),
    "rotary_velocity_gain": Unit("N*m*s/rad", "a velocity gain (N*m*s/rad)"),
    "radius": Unit("m/rad", "a radius or lead per radian (m/rad, e.g. '25 mm' or '10 mm/rev')"),
    "inverse_radius": Unit("rad/m", "a ratio in rad/m"),
}


@lru_cache(maxsize=1)
def _registry():
    import pint

    ureg: pint.UnitRegistry[Any] = pint.UnitRegistry()
    ureg.define("@alias revolution = rev")
    return ureg


def parse_quantity(value: Any, unit: Unit) -> float:
    """Return ``value`` in SI units of ``unit`` as a float.

    Parameters
    ----------
    value : float, int or str
        A plain number (already SI) or a string with units such as ``"3667 kg"`` or ``"10 mm/rev"``.
    unit : Unit
        The expected dimension.

    Raises
    ------
    ValueError
        Unknown unit, wrong dimension, non-finite number or wrong type.

    Examples
    --------
    >>> parse_quantity("3000 rpm", Unit("rad/s", "an angular speed"))   # 100 π, to 15 digits
    314.159265358979
    >>> parse_quantity(2.5, UNITS["mass"])
    2.5
    """
    if isinstance(value, bool):
        raise ValueError(f"expected {unit.name}, a number or a string with units")
    if isinstance(value, (int, float)):
        try:
            result = float(value)
        except OverflowError:   # an integer beyond the float range (TOML integers are unbounded)
            raise ValueError(f"expected a finite value for {unit.name}; the number is too large") from None
    elif isinstance(value, str):
        # unit conversion leaves last-digit noise ("9 ms" -> 0.009000000000000001): keep 15 digits
        result = float(f"{_parse_string(value, unit):.15g}")
    else:
        raise ValueError(f"expected {unit.name}, a number or a string with units")
    if not math.isfinite(result):
        raise ValueError(f"expected a finite value for {unit.name}")
    if result != 0 and not MAGNITUDES[0] <= abs(result) <= MAGNITUDES[1]:
        raise ValueError(f"expected {unit.name} of magnitude {MAGNITUDES[0]:g} to {MAGNITUDES[1]:g} in SI units: "
                         "the analyses multiply up to three model values, which must stay finite in double "
                         "precision")
    return result


MAGNITUDES = (1e-100, 1e100)
"""Magnitudes a non-zero quantity may have (SI): a product of three stays within 1e-300 … 1e300,
inside the normal doubles (2.2e-308 … 1.8e308). No machine-tool value comes near either end."""


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"

_NUMBER_THEN_UNIT = re.compile(rf"\s*({_NUMBER})(?:\s*([^\W\d_].*?|%)|\s+(1/\S.*?))\s*")
"""``"<number> <unit expression>"`` whose unit part starts with a letter (or is ``%``), or is a
reciprocal ``1/...`` after a space (``"24.8 1/s"``, a gain): the number then multiplies the whole unit
expression, so its value is ``number * (1 <unit> in SI)``, one pint conversion per distinct unit."""


_PLAIN_NUMBER = re.compile(rf"\s*{_NUMBER}\s*")


def _parse_string(text: str, unit: Unit) -> float:
    """``text`` in SI units of ``unit``; the common form ``"<number> <unit>"`` costs one pint
    conversion per distinct unit (cached), e.g. for thousands of model variants."""
    if _PLAIN_NUMBER.fullmatch(text) and not _is_dimensionless(unit.si):
        raise _no_unit(text, unit)
    match = _NUMBER_THEN_UNIT.fullmatch(text)
    if match:
        factor = _unit_factor(match.group(2) or match.group(3), unit.si, unit.radians_optional)
        if factor is not None:
            return float(match.group(1)) * factor
    return _parse_with_pint(text, unit)


@lru_cache(maxsize=512)
def _unit_factor(unit_text: str, si: str, radians_optional: bool = False) -> float | None:
    """SI value of one ``unit_text`` when the conversion is a plain factor, else None (offset
    units such as degC, unknown units, wrong dimensions: the full parse reports those)."""
    try:
        expected = Unit(si, "", radians_optional=radians_optional)
        one = _parse_with_pint(f"1 {unit_text}", expected)
        two = _parse_with_pint(f"2 {unit_text}", expected)
    except ValueError:
        return None
    return one if two == 2.0 * one else None


def _parse_with_pint(text: str, unit: Unit) -> float:
    import pint

    ureg = _registry()
    try:
        quantity = ureg.Quantity(text.strip())
    except pint.errors.UndefinedUnitError as exc:
        names = ", ".join(repr(n) for n in exc.unit_names) if isinstance(exc.unit_names, (tuple, list)) else repr(exc.unit_names)
        raise ValueError(f"unknown unit {names}; expected {unit.name}") from None
    except Exception:
        shown = text if len(text) <= 80 else f"{text[:80]}..."
        raise ValueError(f"cannot read {shown!r} as a quantity; expected {unit.name}") from None
    if not isinstance(quantity, ureg.Quantity) or not dict(quantity.unit_items()):  # "3667", "2*3"
        if not _is_dimensionless(unit.si):
            raise _no_unit(text, unit)
        return float(quantity.magnitude if isinstance(quantity, ureg.Quantity) else quantity)
    try:
        magnitude = float(quantity.to(unit.si or "dimensionless").magnitude)
    except pint.errors.DimensionalityError:
        found = _dimension_words(quantity)
        raise ValueError(f"expected {unit.name}; the value has dimension {found}") from None
    return _angle_factor(quantity, unit) * magnitude


def _is_dimensionless(si: str) -> bool:
    return not si or _registry().Quantity(1, si).dimensionless and _radian_exponent(si) == 0


def _no_unit(text: str, unit: Unit) -> ValueError:
    number = text.strip()
    return ValueError(f"a number in quotes has no unit; expected {unit.name}: write it without quotes "
                      f"for SI ({number}, in {unit.si}) or with its unit ('{number} {unit.si}')")


_TURNS = ("turn", "revolutions_per_minute", "revolutions_per_second")
"""pint's names of the revolution-based angle units (``rev``, ``revolution``, ``cycle`` are aliases of
``turn``; ``rpm``, ``rps``)."""


def _radian_exponent(units: Any) -> float:
    """The power of radian in ``units`` (a pint quantity or unit text) once reduced to root units:
    pint treats radians as dimensionless, so a dimension check alone cannot see them."""
    quantity = units if not isinstance(units, str) else _registry().Quantity(1, units or "dimensionless")
    return dict(quantity.to_root_units().unit_items()).get("radian", 0)


def _angle_factor(quantity, unit: Unit) -> float:
    """The factor that makes pint's conversion of ``quantity`` to ``unit.si`` right with angles.

    pint takes radians as dimensionless, so ``rad/s`` and ``rpm`` "convert" to Hz with the
    magnitude in rad/s, and a stiffness in N·m/rad passes for a torque. The rules: an angular
    frequency (rad/s, deg/s) for a frequency in Hz is divided by 2π; a rotational speed (rpm,
    rev/s) is refused for a frequency; a frequency in Hz for an angular frequency (rad/s) is
    multiplied by 2π and refused for a gain in 1/s (cycles or radians per second?); otherwise a
    value may leave out the expected radians (``"25 mm"`` for m/rad) but carries no others.
    """
    expected = _radian_exponent(unit.si)
    given = _radian_exponent(quantity)
    names = [name for name, _ in quantity.unit_items()]
    hertz = any(name.endswith("hertz") for name in names)
    per_time = dict(quantity.dimensionality) == {"[time]": -1}
    if per_time and "Hz" in unit.si:
        if any(turn in name for name in names for turn in _TURNS):   # also "krpm"
            raise ValueError(f"a rotational speed (rpm, rev/s) is not {unit.name}; write the frequency in Hz, "
                             "or as an angular frequency in rad/s")
        return 1.0 / (2.0 * math.pi) if given == 1 else 1.0
    if per_time and hertz and given == 0:
        if expected == 1:          # an angular frequency written in Hz
            return 2.0 * math.pi
        if unit.radians_optional:
            raise ValueError(f"a frequency in Hz is ambiguous for {unit.name} (cycles or radians per second?); "
                             "write it in 1/s or rad/s")
    if given in (0, expected):
        return 1.0
    if unit.radians_optional and expected == 0 and given == 1 and \
            all(name.endswith("radian") or _radian_exponent(name) == 0 for name in names):
        return 1.0                 # "240 rad/s" for a gain in 1/s
    raise ValueError(f"expected {unit.name}; the unit has an angle (rad, deg, rev) the quantity does not have")


def _dimension_words(quantity) -> str:
    dims = dict(quantity.dimensionality)
    if not dims:
        return "dimensionless"
    return " * ".join(f"{k.strip('[]')}^{v:g}" if v != 1 else k.strip("[]") for k, v in dims.items())


@lru_cache(maxsize=256)
def si_unit(unit_text: str) -> str | None:
    """The SI unit (as :data:`UNITS` writes it) of the quantity ``unit_text`` measures: ``"mm"`` → ``"m"``,
    ``"t"`` → ``"kg"``, ``"kN/um"`` → ``"N/m"``; None when unknown, dimensionless or ambiguous (a study's table
    labels its inputs with it).

    >>> si_unit("kN/um"), si_unit("t"), si_unit("furlong/fortnight"), si_unit("1/s")   # 1/s: Hz or a gain?
    ('N/m', 'kg', 'm/s', None)
    """
    import pint

    ureg = _registry()
    try:
        quantity = ureg.Quantity(1, unit_text)
    except (pint.errors.PintError, ValueError, TypeError, AttributeError, AssertionError):
        return None
    if quantity.dimensionless:
        return None
    found = []
    for unit in UNITS.values():
        if not unit.si or unit.si in found:
            continue
        if ureg.Quantity(1, unit.si).dimensionality == quantity.dimensionality \
                and _radian_exponent(unit.si) == _radian_exponent(quantity):
            found.append(unit.si)
    return found[0] if len(found) == 1 else None
