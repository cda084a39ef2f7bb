"""A study's variants: each parameter's levels, checked against the base model, and the variants as settings.

Grid parameters (``values``, ``range``, ``logrange``, ``catalogue``) combine as a Cartesian product, the last
parameter varying fastest; the ``samples`` draws of the distributions (all drawn together, one vector per
sample) are crossed with the grid: variant ``i`` is grid point ``i // samples`` with draw ``i % samples``, so
every design point sees the same draws (common random numbers, ``docs/studies.md``). Parameter ``k``'s draws
come from ``numpy.random.default_rng([seed, k])``: the same study and seed give the same variants, and
adding a parameter leaves the others' draws as they were.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError, SicomatError
from ..io.modelfile import value_at
from .spec import MAX_VARIANTS, ParameterSpec, StudySpec, constraints_in_units, split_quantity

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine

__all__ = ["Parameter", "StudyPlan", "plan_study"]

CHECKED_LEVELS = 64
"""Grid levels of one parameter validated one by one against the base model before any work (all of
them up to this count; beyond it the first and last 32): a bad value is refused up front rather than
failing every variant that uses it."""


@dataclass(frozen=True)
class Parameter:
    """One varied key path: its settings (what ``--set`` receives) and the table's input values (SI, or
    the catalogue id), ``drawn`` for a distribution (indexed by sample) else a grid axis (by level)."""

    index: int
    path: str
    settings: tuple[Any, ...]
    inputs: np.ndarray
    drawn: bool
    unit: str | None = None


@dataclass(frozen=True)
class StudyPlan:
    """Everything the workers need: the base model's data, the parameters' levels and the variant count."""

    spec: StudySpec
    source: str
    base_path: Path
    base_data: dict[str, Any]
    axis: str
    parameters: tuple[Parameter, ...]
    samples: int
    grid_shape: tuple[int, ...]
    metrics: tuple[str, ...] = field(default=())
    rotary: bool = False
    torque: bool = False
    options: Any = None
    constraints: tuple[Any, ...] = ()   # the study's constraints, bounds in their columns' units

    def column_unit(self, name: str) -> str | None:
        """The unit of a column of the table (an SI unit for a name without a unit suffix, else the suffix's:
        Hz, °, dB, %), None when it has none (a ratio, a gain in the model's units, true/false)."""
        from ..plots.study_table import suffix_unit

        return self.units().get(name) or suffix_unit(name)

    def units(self) -> dict[str, str]:
        """The SI unit of each column whose name carries none (inputs and metrics), for the figures' labels."""
        from .analyses import UNITS

        out = {p.path: p.unit for p in self.parameters if p.unit}
        out.update({m: UNITS[m] for m in self.metrics if m in UNITS})
        if self.rotary:
            out["modal.moving_mass"] = "kg·m²"
        if self.torque:
            out["simulate.max_effort"] = "N·m"
        return out

    @property
    def variants(self) -> int:
        return math.prod(self.grid_shape) * self.samples   # Python integers: no overflow on a huge grid

    def _levels(self, variant: int) -> list[int]:
        grid, sample = divmod(int(variant), self.samples)
        out = []
        for size in reversed(self.grid_shape):
            grid, digit = divmod(grid, size)
            out.append(digit)
        digits = iter(reversed(out))
        return [sample if p.drawn else next(digits) for p in self.parameters]

    def settings(self, variant: int) -> list[str]:
        """The ``KEY=VALUE`` overrides of ``variant``."""
        return [f"{p.path}={_toml(p.settings[level])}" for p, level in zip(self.parameters, self._levels(variant))]

    def inputs(self, first: int, stop: int) -> dict[str, np.ndarray]:
        """The table's input columns of variants ``first`` to ``stop - 1``."""
        idx = np.arange(first, stop)
        grid, sample = np.divmod(idx, self.samples)
        digits: list[np.ndarray] = []
        for size in reversed(self.grid_shape):
            grid, digit = np.divmod(grid, size)
            digits.append(digit)
        grid_digits = iter(reversed(digits))
        return {p.path: p.inputs[sample if p.drawn else next(grid_digits)] for p in self.parameters}


def _toml(value: Any) -> str:
    """``value`` as the right-hand side of ``--set KEY=VALUE`` (a TOML value, written by tomli_w: its
    escapes of quotes, backslashes and control characters)."""
    import tomli_w

    if isinstance(value, np.generic):
        value = value.item()
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def plan_study(spec: StudySpec, base: Path, source: str) -> StudyPlan:
    """Check the study against its base model and generate the parameters' levels; every refusal is a
    :class:`ModelError` naming the study file (``source``) and the key, before any variant is computed."""
    from ..io.modelfile import _read_text, _read_toml, dump_data, model_from_data

    if not base.is_file():
        raise ModelError(f"the base model {base} is not a file", source=source, path="base", value=spec.base)
    base_data = _read_toml(_read_text(base), str(base))
    machine = model_from_data(base_data, source=str(base))
    try:
        axis = machine.axis_name(spec.axis)
    except ModelError as exc:
        raise ModelError(exc.message, source=source, path="axis", value=spec.axis) from None
    dumped = dump_data(machine)
    params = []
    for k, p in enumerate(spec.parameters):
        params.append(_parameter(k, p, spec.seed, base_data, dumped, source, str(base)))
    drawn = [(k, p) for k, p in enumerate(spec.parameters) if p.drawn]
    samples = {int(p.samples or 1) for _, p in drawn}
    if len(samples) > 1:
        k = drawn[[int(p.samples or 1) for _, p in drawn].index(max(samples))][0]
        raise ModelError(f"the distributions are drawn together: give them the same samples (found "
                         f"{', '.join(str(s) for s in sorted(samples))})", source=source, path=f"parameters.{k}.samples")
    plan = StudyPlan(spec, source, base, base_data, axis, tuple(params), samples.pop() if samples else 1,
                     tuple(len(p.settings) for p in params if not p.drawn))
    if plan.variants > MAX_VARIANTS:
        raise ModelError(f"{plan.variants} variants; at most {MAX_VARIANTS} in one study", source=source,
                         path="parameters")
    from .analyses import metric_names
    from .options import analysis_options, check_analyses

    metrics = metric_names(spec.analyses, machine, axis)
    options = analysis_options(spec, axis, source)
    check_analyses(spec, machine, axis, source, options)
    _check_names(spec, metrics, plan.parameters, source)
    plan = StudyPlan(**{**plan.__dict__, "metrics": tuple(metrics), **_axis_kind(machine, axis)})
    constraints = constraints_in_units(spec, plan.column_unit, source)
    return StudyPlan(**{**plan.__dict__, "constraints": constraints, "options": options})


def _axis_kind(machine: "Machine", axis: str) -> dict[str, bool]:
    """``rotary``: the axis's coordinate is an angle (its tool on rotational dofs only); ``torque``: its drive
    applies a torque (the units of the table's labels)."""
    from ..servo.loop import build_servo_loop

    try:
        loop = build_servo_loop(machine, axis)
    except SicomatError:
        return {"rotary": False, "torque": False}
    kinds = {d.kind for d, t in zip(loop.mechanics.dofs, loop.tool) if t != 0}
    return {"rotary": kinds == {"rotational"},
            "torque": loop.mechanics.actuator(loop.actuator).kind != "translational"}


def _check_names(spec: StudySpec, metrics: list[str], params: tuple[Parameter, ...], source: str) -> None:
    """Constraints and objectives name columns of the table, and numeric ones: an input of catalogue ids or
    words (``"fixed-supported"``) has no order (a study that compared one failed once its table was made)."""
    inputs = [p.path for p in params]
    known, words = [*inputs, *metrics], {p.path for p in params if p.inputs.dtype == object}
    names = [(f"constraints.{k}", c.text, name)
             for k, c in enumerate(spec.parsed_constraints()) for name in c.metrics()]
    if spec.pareto is not None:
        names += [(f"pareto.{which}.{k}", name, name) for which in ("maximize", "minimize")
                  for k, name in enumerate(getattr(spec.pareto, which))]
    for path, value, name in names:
        if name not in known:
            raise ModelError(_unknown(name, known, spec.analyses), source=source, path=path, value=value)
        if name in words:
            raise ModelError(f"{name} holds words or catalogue ids, not numbers: constraints and objectives read "
                             "numbers (or true/false)", source=source, path=path, value=value)


def _unknown(name: str, known: list[str], analyses: list[str]) -> str:
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    hint = f"; closest: {', '.join(close)}" if close else f"; the columns are {', '.join(known)}"
    return f"unknown metric {name!r} for the analyses {', '.join(analyses)}{hint} (docs/studies.md, The table)"


def _parameter(k: int, p: ParameterSpec, seed: int, base_data: dict[str, Any], dumped: dict[str, Any],
               source: str, base_source: str) -> Parameter:
    where = f"parameters.{k}"

    def bad(message: str, key: str, value: Any = None) -> ModelError:
        return ModelError(message, source=source, path=f"{where}.{key}", value=value)

    base_value = value_at(dumped, p.path)
    if p.relative and not (isinstance(base_value, (int, float)) and not isinstance(base_value, bool)):
        raise bad(f"relative values multiply the base model's value at {p.path}, which is "
                  + ("not given" if base_value is None else f"not a number ({base_value!r})"), "relative")
    way = p.way
    if way == "catalogue":
        settings = _catalogue(p, bad)
    elif way == "values":
        if not p.values:
            raise bad("an empty list of values", "values", p.values)
        settings = list(p.values)
    elif way in ("range", "logrange"):
        settings = _range(getattr(p, way), way == "logrange", lambda m, v=None: bad(m, way, v))
    else:
        settings = _draws(p, seed, k, lambda m, key, v=None: bad(m, key, v))
    if p.relative:
        factors = np.array([_number(s, lambda m, v=None: bad(m, way, v)) for s in settings])
        settings = list(float(base_value) * factors)
    inputs = _inputs(p, settings, base_data, source, base_source, where)
    return Parameter(k, p.path, tuple(settings), inputs, p.drawn, _si_unit(p, settings, base_data))


def _si_unit(p: ParameterSpec, settings: list[Any], base_data: dict[str, Any]) -> str | None:
    """The SI unit of the input column (the table's label), from the unit the study file writes (or, for a
    relative parameter, the base model file)."""
    from ..description.units import si_unit

    written = [value_at(base_data, p.path)] if p.relative else [p.mean, p.low] if p.drawn else settings[:1]
    for value in written:
        if isinstance(value, str):
            try:
                _, unit = split_quantity(value)
            except ValueError:
                return None
            return si_unit(unit) if unit else None
    return None


def _number(value: Any, bad) -> float:
    try:
        number, unit = split_quantity(value)
    except ValueError as exc:
        raise bad(str(exc), value) from None
    if unit:
        raise bad("relative values are plain factors (1.1 for +10 %), without a unit", value)
    return number


def _range(spec: list[Any], log: bool, bad) -> list[Any]:
    if len(spec) != 3:
        raise bad("expected [LOW, HIGH, N]", spec)
    low, high, n = spec
    if isinstance(n, bool) or not isinstance(n, int):
        raise bad("the third item N (the number of values) must be an integer", spec)
    if n < 1:
        raise bad(f"an empty range: N = {n}; expected N >= 1", spec)
    if n > MAX_VARIANTS:
        raise bad(f"N = {n} values; at most {MAX_VARIANTS} variants in one study", spec)
    try:
        (lo, unit), (hi, unit_high) = split_quantity(low), split_quantity(high)
    except ValueError as exc:
        raise bad(str(exc), spec) from None
    if unit != unit_high:
        raise bad(f"give both ends in the same unit (found {unit or 'none'!r} and {unit_high or 'none'!r})", spec)
    if log and not (lo > 0 and hi > 0):
        raise bad("a log range needs LOW > 0 and HIGH > 0", spec)
    if n > 1 and lo == hi:
        raise bad(f"an empty range: LOW = HIGH with N = {n}", spec)
    numbers = np.geomspace(lo, hi, n) if log else np.linspace(lo, hi, n)
    return [f"{float(x)!r} {unit}" if unit else float(x) for x in numbers]


def _draws(p: ParameterSpec, seed: int, k: int, bad) -> list[Any]:
    if p.samples is None or p.samples < 1:
        raise bad("expected samples >= 1 (the number of draws)", "samples", p.samples)
    if p.samples > MAX_VARIANTS:
        raise bad(f"{p.samples} draws; at most {MAX_VARIANTS} variants in one study", "samples", p.samples)
    if p.distribution == "uniform":
        if p.low is None or p.high is None or p.mean is not None or p.std is not None:
            raise bad("a uniform distribution takes low and high", "distribution", p.distribution)
        (a, unit), (b, unit_b) = _pair(p.low, p.high, "low", "high", bad)
        if b < a:
            raise bad(f"a negative spread: high ({p.high}) < low ({p.low})", "high", p.high)
        draws = np.random.default_rng([seed, k]).uniform(a, b, p.samples)
    else:
        if p.mean is None or p.std is None or p.low is not None or p.high is not None:
            raise bad(f"a {p.distribution} distribution takes mean and std", "distribution", p.distribution)
        (mean, unit), (std, unit_b) = _pair(p.mean, p.std, "mean", "std", bad)
        if std < 0:
            raise bad("a negative spread: std < 0", "std", p.std)
        rng = np.random.default_rng([seed, k])
        if p.distribution == "normal":
            draws = rng.normal(mean, std, p.samples)
        else:
            if mean <= 0:
                raise bad("a lognormal distribution needs mean > 0", "mean", p.mean)
            sigma2 = math.log1p((std / mean) ** 2)   # mean and std of the variable itself, not of its log
            draws = rng.lognormal(math.log(mean) - sigma2 / 2, math.sqrt(sigma2), p.samples)
    return [f"{float(x)!r} {unit}" if unit else float(x) for x in draws]


def _pair(a: Any, b: Any, name_a: str, name_b: str, bad) -> tuple[tuple[float, str], tuple[float, str]]:
    try:
        first = split_quantity(a)
    except ValueError as exc:
        raise bad(str(exc), name_a, a) from None
    try:
        second = split_quantity(b)
    except ValueError as exc:
        raise bad(str(exc), name_b, b) from None
    if first[1] != second[1]:
        raise bad(f"give {name_a} and {name_b} in the same unit (found {first[1] or 'none'!r} and "
                  f"{second[1] or 'none'!r})", name_b, b)
    return first, second


def _catalogue(p: ParameterSpec, bad) -> list[Any]:
    from ..catalogue.resolve import default_catalogue

    try:
        entries = default_catalogue().select(p.catalogue, p.where)
    except ModelError as exc:
        key = "catalogue" if exc.source == "KIND" else "where"
        raise bad(exc.message, key, exc.value) from None
    if not entries:
        raise bad(f"no {p.catalogue} in the catalogue meets {' and '.join(p.where) or 'the filters'}", "where",
                  p.where)
    return [e.id for e in entries]


def _inputs(p: ParameterSpec, settings: list[Any], base_data: dict[str, Any], source: str, base_source: str,
            where: str) -> np.ndarray:
    """The table's input column: each setting validated on the base model (a grid's levels one by one, up to
    :data:`CHECKED_LEVELS`; a distribution's centre) and read back in SI units."""
    from ..io.modelfile import dump_data, model_from_data

    def read(setting: Any) -> Any:
        item = f"{p.path}={_toml(setting)}"
        try:
            machine = model_from_data(base_data, [item], source=base_source, base_valid=True)
        except SicomatError as exc:
            message = exc.message if isinstance(exc, ModelError) else str(exc)
            located = f" ({exc.path})" if isinstance(exc, ModelError) and exc.path and exc.path != p.path else ""
            raise ModelError(f"{p.path} = {_toml(setting)} does not fit the base model{located}: {message}",
                             source=source, path=f"{where}.path", value=p.path) from None
        return value_at(dump_data(machine), p.path)

    if p.catalogue is not None:
        for i in _checked_indices(len(settings)):
            read(settings[i])
        return np.array(settings, dtype=object)
    checked = {i: read(settings[i]) for i in _checked_indices(len(settings))} if not p.drawn else {}
    probes = list(checked.items())
    if p.drawn:   # the draws are not validated one by one (an outlier fails its own variant): their centre is
        centre = p.mean if p.mean is not None else p.low
        centre = centre if not p.relative else settings[0]
        probes.append((-1, read(centre)))
    factors: dict[str, float] = {}   # unit -> its SI factor, read back from a validated level
    for i, si in probes:
        setting = settings[i] if i >= 0 else (p.mean if p.mean is not None else p.low)
        if isinstance(setting, str) and isinstance(si, (int, float)) and not isinstance(si, bool):
            try:
                number, unit = split_quantity(setting)
            except ValueError:
                continue
            if number != 0:
                factors.setdefault(unit, float(si) / number)
    column: list[Any] = []
    for i, setting in enumerate(settings):
        if i in checked:
            column.append(checked[i])
            continue
        try:
            number, unit = split_quantity(setting)
        except ValueError:
            column.append(setting)
            continue
        column.append(number if not unit else number * factors[unit] if unit in factors else read(setting))
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in column):
        return np.array(column, dtype=float)
    return np.array(column, dtype=object)


def _checked_indices(n: int) -> list[int]:
    half = CHECKED_LEVELS // 2
    return list(range(n)) if n <= CHECKED_LEVELS else [*range(half), *range(n - half, n)]
