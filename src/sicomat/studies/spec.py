"""The study file (``sicomat study STUDY.toml``): its schema and the checks made before any work.

A study is a base model file, parameters varied by the key paths of ``--set``, the analyses run on every
variant, optional constraints on their metrics and optional Pareto objectives (``docs/studies.md``).
Every refusal is one :class:`~sicomat.errors.ModelError` naming the study file and the key
(``parameters.1.range``), raised by :func:`load_study` before a single variant is computed.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ..errors import ModelError

__all__ = ["ANALYSIS_NAMES", "ParameterSpec", "StudySpec", "Constraint", "load_study", "study_from_dict",
           "split_quantity", "MAX_VARIANTS"]

ANALYSIS_NAMES = ("modal", "tune", "margins", "simulate", "circle", "size")
"""The analyses a study may run on each variant, in the order they run (a tuned controller is used by
the analyses after ``tune``)."""

MAX_VARIANTS = 10_000_000
"""Largest study accepted: the inputs of every variant are generated on the client before any work."""

MAX_STUDY_BYTES = 1024 ** 2
"""Largest study file read (1 MiB): a study is a few hundred bytes of TOML."""

_QUANTITY = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*")


def split_quantity(value: Any) -> tuple[float, str]:
    """``"300 kg"`` → ``(300.0, "kg")``, ``2.5`` → ``(2.5, "")``; a :class:`ValueError` for anything else.

    >>> split_quantity("10 mm/rev")
    (10.0, 'mm/rev')
    """
    if isinstance(value, bool):
        raise ValueError("expected a number or a string with units, not a boolean")
    if isinstance(value, (int, float)):
        number = float(value)
        unit = ""
    elif isinstance(value, str) and (match := _QUANTITY.fullmatch(value)):
        number, unit = float(match.group(1)), match.group(2)
    else:
        raise ValueError("expected a number or a string '<number> <unit>' such as '300 kg'")
    if not math.isfinite(number):
        raise ValueError("expected a finite number")
    return number, unit


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Scalar = float | int | str | bool


class ParameterSpec(_Strict):
    """One ``[[parameters]]`` table: a key path and how its values are chosen."""

    path: str
    values: list[Scalar] | None = None
    range: list[float | int | str] | None = None
    logrange: list[float | int | str] | None = None
    distribution: Literal["normal", "uniform", "lognormal"] | None = None
    mean: float | int | str | None = None
    std: float | int | str | None = None
    low: float | int | str | None = None
    high: float | int | str | None = None
    samples: int | None = None
    catalogue: str | None = None
    where: list[str] = []
    relative: bool = False

    @field_validator("path")
    @classmethod
    def _path(cls, value: str) -> str:
        if not re.fullmatch(r"[A-Za-z0-9_\-]+(\.[A-Za-z0-9_\-]+)*", value):
            raise ValueError("expected a key path of --set, e.g. 'axes.X.mechanics.bodies.load.mass'")
        return value

    @model_validator(mode="after")
    def _one_way(self) -> "ParameterSpec":
        ways = [k for k in ("values", "range", "logrange", "distribution", "catalogue") if getattr(self, k) is not None]
        if len(ways) != 1:
            raise ValueError("give exactly one of values, range, logrange, distribution or catalogue"
                             + (f" (found {', '.join(ways)})" if ways else ""))
        way = ways[0]
        drawn = ("mean", "std", "low", "high", "samples")
        if way != "distribution" and any(getattr(self, k) is not None for k in drawn):
            given = [k for k in drawn if getattr(self, k) is not None]
            raise ValueError(f"{', '.join(given)} belong to a distribution; this parameter has {way}")
        if way != "catalogue" and self.where:
            raise ValueError("where filters a catalogue list; give catalogue = '<kind>'")
        if way == "catalogue" and self.relative:
            raise ValueError("a catalogue list is a list of ids: it cannot be relative")
        return self

    @property
    def way(self) -> str:
        """How the values are chosen: ``values``, ``range``, ``logrange``, ``distribution`` or ``catalogue``."""
        return next(k for k in ("values", "range", "logrange", "distribution", "catalogue")
                    if getattr(self, k) is not None)

    @property
    def drawn(self) -> bool:
        """Drawn at random (a distribution) rather than a grid axis."""
        return self.distribution is not None


_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w.\-]*)\s*(>=|<=|==|>|<)\s*(?![<>=])(.+?)\s*$")
_NUMBER_UNIT = re.compile(r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\d\s.+\-].*)")


class Constraint(_Strict):
    """``METRIC OPERATOR BOUND``, the bound a number (in the metric's unit), a number with its unit (``80 Hz``,
    ``10 um``: converted to the column's unit by the study's plan, :meth:`in_unit`), ``true``/``false`` or another
    metric (``size.peak_torque <= size.peak_torque.limit``)."""

    text: str
    metric: str
    operator: str
    bound: float | bool | str
    unit: str | None = None     # the bound's unit as written; None once converted (or a plain number)

    @classmethod
    def parse(cls, text: str) -> "Constraint":
        match = _CONSTRAINT.match(text)
        if not match:
            raise ValueError("expected 'METRIC OPERATOR BOUND' with an operator among >=, <=, >, <, ==, "
                             "e.g. 'modal.f1_hz >= 80'")
        metric, operator, raw = match.groups()
        bound: float | bool | str
        if raw in ("true", "false"):
            bound = raw == "true"
            if operator != "==":
                raise ValueError("compare a true/false metric with ==")
        else:
            unit = None
            try:
                bound = float(raw)
            except ValueError:
                quantity = _NUMBER_UNIT.fullmatch(raw)
                if quantity:
                    bound, unit = float(quantity.group(1)), quantity.group(2).strip()
                elif not re.fullmatch(r"[A-Za-z_][\w.\-]*", raw):
                    raise ValueError(f"the bound {raw!r} is neither a number (in the metric's unit, or with its "
                                     "unit: '80 Hz'), true/false, nor a metric name") from None
                else:
                    bound = raw
            if isinstance(bound, float) and not math.isfinite(bound):
                raise ValueError("the bound must be finite")
            return cls(text=text, metric=metric, operator=operator, bound=bound, unit=unit)
        return cls(text=text, metric=metric, operator=operator, bound=bound)

    def in_unit(self, unit: str | None) -> "Constraint":
        """This constraint with its bound converted to ``unit`` (the metric's column unit as the table labels
        it: ``Hz``, ``°``, ``dB``, ``%``, an SI unit such as ``m``, ``N·m``, ``kg·m²``, ``1``; None when the
        column has no unit); itself when the bound has no unit. A ValueError says why a unit does not fit."""
        if self.unit is None:
            return self
        assert isinstance(self.bound, float)
        if unit is None:
            raise ValueError(f"{self.metric} has no unit to convert {self.unit!r} to: give the bound as a plain "
                             "number")
        if unit in ("dB", "%"):     # logarithmic or a percentage of the metric itself: written as such, or not
            if self.unit.replace("percent", "%") != unit:
                raise ValueError(f"{self.metric} is in {unit}: write the bound in {unit} (got {self.unit!r})")
            return self.model_copy(update={"unit": None})
        from ..description.units import Unit, parse_quantity

        si = {"°": "degree", "1": ""}.get(unit, unit.replace("·", "*").replace("²", "**2"))
        bound = parse_quantity(f"{self.bound!r} {self.unit}", Unit(si, f"{self.metric}'s unit ({unit})",
                                                                    radians_optional=si == "1/s"))
        return self.model_copy(update={"bound": bound, "unit": None})

    def metrics(self) -> list[str]:
        """The metrics the constraint reads."""
        return [self.metric] + ([self.bound] if isinstance(self.bound, str) else [])


class TuneOptions(_Strict):
    """``[tune]``: the frequency approach's targets (as ``sicomat tune``; units allowed)."""

    velocity_crossover: float | str | None = None      # unset: TuningTargets' defaults, as sicomat tune's
    velocity_phase_margin: float | str | None = None
    position_phase_margin: float | str | None = None
    position_crossover: float | str | None = None
    min_gain_margin: float | str | None = None


class SimulateOptions(_Strict):
    """``[simulate]``: the move simulated (default the axis's trajectory) and its duration."""

    move: float | str | None = None
    max_velocity: float | str | None = None
    max_acceleration: float | str | None = None
    duration: float | str | None = None


class CircleOptions(_Strict):
    """``[circle]``: the ISO 230-4 circle test's radius, feed and model."""

    radius: float | str = "20 mm"
    feed: float | str = "10 m/min"
    model: Literal["decoupled", "coupled", "nonlinear"] | None = None


class SizeOptions(_Strict):
    """``[size]``: the sizing check's move (default the axis's trajectory) and inertia-ratio limit."""

    move: float | str | None = None
    inertia_ratio_limit: float = Field(default=10.0, gt=0, allow_inf_nan=False)   # as sicomat size's option


class ParetoSpec(_Strict):
    """``[pareto]``: the objectives, each a metric or an input, maximised or minimised."""

    maximize: list[str] = []
    minimize: list[str] = []

    @model_validator(mode="after")
    def _two(self) -> "ParetoSpec":
        names = self.maximize + self.minimize
        if len(names) < 2:
            raise ValueError("give at least two objectives between maximize and minimize")
        if len(set(names)) != len(names):
            raise ValueError("an objective is listed twice")
        return self

    @property
    def objectives(self) -> list[tuple[str, str]]:
        """``(column, "max"|"min")`` in the file's order, maximised first."""
        return [(n, "max") for n in self.maximize] + [(n, "min") for n in self.minimize]


class StudySpec(_Strict):
    """A study file, validated (the base model's path resolved against the study file's folder)."""

    base: str
    seed: int = Field(default=0, ge=0)       # numpy's seed sequences take no negative seed
    analyses: list[str]
    axis: str | None = None
    parameters: list[ParameterSpec]
    constraints: list[str] = []
    pareto: ParetoSpec | None = None
    format: Literal["parquet", "csv"] = "parquet"
    chunk_size: int | None = None
    tune: TuneOptions = TuneOptions()
    simulate: SimulateOptions = SimulateOptions()
    circle: CircleOptions = CircleOptions()
    size: SizeOptions = SizeOptions()
    name: str | None = None
    description: str | None = None

    @field_validator("analyses")
    @classmethod
    def _analyses(cls, value: list[str]) -> list[str]:
        if not value:
            raise ValueError(f"expected at least one of {', '.join(ANALYSIS_NAMES)}")
        for name in value:
            if name not in ANALYSIS_NAMES:
                raise ValueError(f"unknown analysis {name!r}; expected any of {', '.join(ANALYSIS_NAMES)}")
        if len(set(value)) != len(value):
            raise ValueError("an analysis is listed twice")
        return [name for name in ANALYSIS_NAMES if name in value]   # the order they run in

    @field_validator("parameters")
    @classmethod
    def _parameters(cls, value: list[ParameterSpec]) -> list[ParameterSpec]:
        if not value:
            raise ValueError("expected at least one [[parameters]] table")
        paths = [p.path for p in value]
        twice = sorted({p for p in paths if paths.count(p) > 1})
        if twice:
            raise ValueError(f"the key path {twice[0]} is varied twice")
        return value

    @field_validator("chunk_size")
    @classmethod
    def _chunk(cls, value: int | None) -> int | None:
        if value is not None and not 1 <= value <= 100_000:
            raise ValueError("expected a chunk size of 1 to 100000 variants")
        return value

    @field_validator("constraints")
    @classmethod
    def _constraints(cls, value: list[str]) -> list[str]:
        for text in value:
            Constraint.parse(text)
        return value

    def parsed_constraints(self) -> list[Constraint]:
        return [Constraint.parse(text) for text in self.constraints]


def constraints_in_units(spec: StudySpec, unit_of: Callable[[str], str | None],
                         source: str) -> tuple[Constraint, ...]:
    """The study's constraints with every bound written with a unit (``modal.f1_hz >= 80 Hz``) converted to its
    column's unit (``unit_of(column)``), or a :class:`ModelError` naming the constraint."""
    out = []
    for k, constraint in enumerate(spec.parsed_constraints()):
        try:
            out.append(constraint.in_unit(unit_of(constraint.metric)))
        except ValueError as exc:
            raise ModelError(str(exc), source=source, path=f"constraints.{k}", value=constraint.text) from None
    return tuple(out)


def load_study(path: str | Path) -> tuple[StudySpec, Path]:
    """The study file at ``path`` validated, and the base model's path (relative to the study's folder).

    Only the file's own shape is checked here; :func:`sicomat.studies.variants.plan_study` checks the
    parameters against the base model (key paths, values, catalogue lists, metrics of the constraints)."""
    import tomllib

    from ..io.modelfile import read_text_bounded

    source = str(path)
    try:
        text = read_text_bounded(path, MAX_STUDY_BYTES, "a study file")
    except FileNotFoundError:
        raise ModelError("no such study file", source=source) from None
    except IsADirectoryError:
        raise ModelError("a folder, not a study file", source=source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read the study file ({exc.__class__.__name__})", source=source) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError(f"not a valid TOML file: {exc}", source=source) from None
    except (RecursionError, ValueError) as exc:
        raise ModelError(f"cannot read the study file ({exc})", source=source) from None
    spec = study_from_dict(data, source)
    base = (Path(path).parent / spec.base)
    return spec, base


_UNION_TAG = re.compile(r"float|int|str|bool|(?:list|dict|tuple|function-\w+)\[.*\]")


def study_from_dict(data: dict[str, Any], source: str | None = None) -> StudySpec:
    """Validate a study's data; a :class:`ModelError` names the first wrong key."""
    try:
        return StudySpec.model_validate(data)
    except ValidationError as exc:
        error = exc.errors()[0]
        # pydantic names the member of a union it tried ("values.0.float"): not a key of the file
        loc = ".".join(str(part) for part in error["loc"] if not _UNION_TAG.fullmatch(str(part)))
        message = error["msg"].removeprefix("Value error, ")
        if error["type"] == "extra_forbidden":
            message = "unknown key" + _known_keys(error["loc"])
        elif error["type"] == "missing":
            message = "missing key"
        value = error.get("input") if error["type"] not in ("missing",) else None
        if isinstance(value, dict):
            value = None
        raise ModelError(message, source=source, path=loc or None, value=value) from None


def _known_keys(loc: tuple[Any, ...]) -> str:
    """``; expected one of ...`` for an unknown key at ``loc``."""
    model: Any = StudySpec
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part) if hasattr(model, "model_fields") else None
        if field is None:
            return ""
        annotation = field.annotation
        args = getattr(annotation, "__args__", ())
        model = next((a for a in (annotation, *args) if isinstance(a, type) and issubclass(a, BaseModel)), None)
        if model is None:
            return ""
    return "; expected one of " + ", ".join(model.model_fields)
