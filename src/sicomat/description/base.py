"""Shared pieces of the model-file schema: the frozen base model, names, quantities with units."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError

from .units import UNITS, parse_quantity

__all__ = ["Spec", "Name", "quantity", "fail", "Mass", "Inertia", "NonNegativeMass",
           "NonNegativeInertia", "Length", "LinearStiffness", "LinearDamping", "TorsionalDamping",
           "Time", "NonNegativeTime", "Frequency", "Gain", "Current", "Voltage", "Resistance",
           "Inductance", "Fraction"]

NAME_PATTERN = r"^[A-Za-z][A-Za-z0-9_\-]*$"
Name = Annotated[str, Field(pattern=NAME_PATTERN)]


class Spec(BaseModel):
    """Base of every schema class: unknown keys are errors, instances are immutable, every float is
    finite (TOML has ``inf`` and ``nan`` literals)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def quantity(kind: str) -> BeforeValidator:
    """A validator parsing a number or a string with units to SI (see :data:`sicomat.description.units.UNITS`)."""
    unit = UNITS[kind]
    return BeforeValidator(lambda v: parse_quantity(v, unit))


def fail(message: str, subpath: str, value: Any = None, **ctx: Any) -> PydanticCustomError:
    """A validation error located at ``subpath`` below the validating model (see :mod:`.modelfile`)."""
    try:
        text = message.format(value=repr(value) if isinstance(value, str) else value, **ctx)
    except (KeyError, IndexError, ValueError):
        text = message
    return PydanticCustomError("sicomat", text.replace("{", "(").replace("}", ")"),
                               {"subpath": subpath, "value": value})


Mass = Annotated[float, quantity("mass"), Field(gt=0)]
Inertia = Annotated[float, quantity("inertia"), Field(gt=0)]
NonNegativeMass = Annotated[float, quantity("mass"), Field(ge=0)]
NonNegativeInertia = Annotated[float, quantity("inertia"), Field(ge=0)]
Length = Annotated[float, quantity("length"), Field(gt=0)]
LinearStiffness = Annotated[float, quantity("linear_stiffness"), Field(ge=0)]
LinearDamping = Annotated[float, quantity("linear_damping"), Field(ge=0)]
TorsionalDamping = Annotated[float, quantity("torsional_damping"), Field(ge=0)]
Time = Annotated[float, quantity("time"), Field(gt=0)]
NonNegativeTime = Annotated[float, quantity("time"), Field(ge=0)]
Frequency = Annotated[float, quantity("frequency"), Field(gt=0)]
Gain = Annotated[float, quantity("inverse_time"), Field(gt=0)]
"""A controller gain in 1/s: zero opens the loop it closes, so it must be > 0."""
Current = Annotated[float, quantity("current"), Field(gt=0)]
Voltage = Annotated[float, quantity("voltage"), Field(gt=0)]
Resistance = Annotated[float, quantity("resistance"), Field(ge=0)]
Inductance = Annotated[float, quantity("inductance"), Field(ge=0)]
Fraction = Annotated[float, quantity("fraction"), Field(ge=0, le=1)]
