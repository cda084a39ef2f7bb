"""The work of a study on a worker: a chunk of variants, each analysis through the verbs the CLI uses.

:func:`run_chunk` is what a Dask task runs (an importable, module-level function of picklable values).
Each variant's model is built from the base file's data and its settings (:func:`~sicomat.io.modelfile.
model_from_data`); the analyses run in the order of :data:`~sicomat.studies.spec.ANALYSIS_NAMES`, and after
``tune`` the others use the tuned controller. The simulations of the chunk's variants that share a structure
(same move, same loop timing) run in one compiled :func:`~sicomat.simulation.simulate_batch` call. A variant
that fails keeps the metrics computed before the failure and gets its message in ``error``; the chunk never
fails for it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING, Any, Callable

from ..errors import ModelError, SicomatError
from .options import StudyOptions

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Sequence

    from ..description.machine import Machine
    from .spec import Constraint

__all__ = ["METRICS", "UNITS", "SIZE_CHECKS", "metric_names", "Chunk", "ChunkResult", "run_chunk",
           "constraints_hold"]

_LOOP = ("phase_margin_deg", "gain_margin_db", "crossover_hz", "bandwidth_hz", "delay_margin", "modulus_margin")

SIZE_CHECKS = ("peak_torque", "peak_force", "rms_torque", "rms_force", "max_speed", "back_emf", "peak_current",
               "voltage", "inertia_ratio", "coupling_torque", "coupling_speed", "gearbox_input_speed",
               "gearbox_torque", "screw_critical_speed", "screw_max_speed")
"""Every check ``sicomat size`` makes (``tasks/size_checks.py``; a test holds the two lists together)."""

METRICS: dict[str, dict[str, str]] = {
    "modal": {"modal.f1_hz": "f", "modal.f2_hz": "f", "modal.f3_hz": "f", "modal.zeta1": "f",
              "modal.f_meca_hz": "f", "modal.moving_mass": "f"},
    "tune": {"tune.targets_met": "b", "tune.stable": "b", "tune.Kp": "f", "tune.Kp_normalized": "f",
             "tune.Ti": "f", "tune.Kv": "f",
             **{f"tune.{loop}_{m}": "f" for loop in ("velocity", "position")
                for m in ("phase_margin_deg", "gain_margin_db", "crossover_hz", "bandwidth_hz")}},
    "margins": {**{f"margins.{loop}.{m}": "f" for loop in ("velocity", "position") for m in _LOOP},
                "margins.stable": "b"},
    "simulate": {"simulate.max_following_error": "f", "simulate.rms_following_error": "f",
                 "simulate.final_error": "f", "simulate.settling_time": "f", "simulate.overshoot_percent": "f",
                 "simulate.max_effort": "f", "simulate.diverged": "b", "simulate.stable": "b"},
    "circle": {"circle.circular_deviation": "f", "circle.max_contour_error": "f",
               "circle.rms_contour_error": "f", "circle.radial_deviation_min": "f",
               "circle.radial_deviation_max": "f", "circle.servo_mismatch": "f", "circle.stable": "b"},
    "size": {"size.ok": "b", **{f"size.{c}{suffix}": kind for c in SIZE_CHECKS
                                for suffix, kind in (("", "f"), (".limit", "f"), (".ok", "b"))}},
}
"""Each analysis's metrics by column name and type (``f`` float, NaN when undefined; ``b`` true/false/missing).
The names follow the ``--json`` unit rule (``docs/conventions.md``): a name without a unit suffix holds an SI
value (m, s, kg, ...; :data:`UNITS` says which), a suffix names a unit that is not SI (``_hz``, ``_deg``,
``_db``)."""

UNITS: dict[str, str] = {
    "modal.zeta1": "1", "modal.moving_mass": "kg",
    "tune.Kp_normalized": "1/s", "tune.Ti": "s", "tune.Kv": "1/s",
    **{f"margins.{loop}.delay_margin": "s" for loop in ("velocity", "position")},
    **{f"margins.{loop}.modulus_margin": "1" for loop in ("velocity", "position")},
    **{f"simulate.{k}": "m" for k in ("max_following_error", "rms_following_error", "final_error")},
    "simulate.settling_time": "s", "simulate.max_effort": "N",
    **{f"circle.{k}": "m" for k in ("circular_deviation", "max_contour_error", "rms_contour_error",
                                      "radial_deviation_min", "radial_deviation_max", "servo_mismatch")},
    **{f"size.{c}{suffix}": unit for c, unit in (
        ("peak_torque", "N·m"), ("rms_torque", "N·m"), ("coupling_torque", "N·m"), ("gearbox_torque", "N·m"),
        ("peak_force", "N"), ("rms_force", "N"), ("back_emf", "V"), ("voltage", "V"), ("peak_current", "A"),
        ("inertia_ratio", "1"), ("coupling_speed", "rad/s"), ("gearbox_input_speed", "rad/s"),
        ("screw_critical_speed", "rad/s"), ("screw_max_speed", "rad/s")) for suffix in ("", ".limit")},
}
"""The SI unit of each metric whose name carries none (the others: Hz, degrees, dB, true/false; ``size.*``
in the check's unit: N or N·m, rad/s or m/s, V, A, 1; ``simulate.max_effort`` in N, or N·m for a torque
actuator (the plan labels it so); ``tune.Kp`` in the model's physical unit, effort per
axis velocity: N·s/m, N·m·s/m, N·m·s/rad). On a rotary axis (its coordinate in rad) ``modal.moving_mass`` is an
inertia in kg·m² (the study's plan labels it so)."""


def metric_names(analyses: list[str], machine: "Machine | None" = None, axis: str | None = None) -> list[str]:
    """The metric columns of ``analyses``, in the order they run."""
    return [name for analysis in analyses for name in METRICS[analysis]]


@dataclass(frozen=True)
class Chunk:
    """One Dask task: variants ``first`` … ``first + len(settings) - 1`` of a study."""

    index: int
    first: int
    settings: tuple[tuple[str, ...], ...]
    base_data: dict[str, Any]
    base_source: str
    options: StudyOptions
    threads: int | None = None
    catalog_folders: tuple[str, ...] = ()


@dataclass(frozen=True)
class ChunkResult:
    """The rows of a chunk (one dict per variant, in order) and the seconds its work took on the worker."""

    index: int
    rows: list[dict[str, Any]]
    compute_s: float


@dataclass
class _Variant:
    row: dict[str, Any]
    machine: Any = None
    loop: Any = None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def run_chunk(chunk: Chunk) -> ChunkResult:
    """Every analysis of the study on the chunk's variants (the function each Dask task runs)."""
    from ..io.modelfile import model_from_data

    start = time.perf_counter()
    if chunk.threads is not None:
        _limit_threads(chunk.threads)
    opts = chunk.options
    names = metric_names(list(opts.analyses))
    variants = [_Variant({"variant": chunk.first + i, **{n: None for n in names}}) for i in range(len(chunk.settings))]
    catalogue = None
    if chunk.catalog_folders:   # the client's `sicomat --catalog DIR` folders (the worker has no such state)
        from ..catalogue.resolve import default_catalogue

        catalogue = default_catalogue(chunk.catalog_folders)

    def build(v: _Variant, settings: tuple[str, ...]) -> None:
        v.machine = model_from_data(chunk.base_data, settings, source=chunk.base_source, base_valid=True,
                                    catalogue=catalogue)

    for v, settings in zip(variants, chunk.settings):
        _attempt(v, "model", partial(build, v, settings))
    needs_loop = any(a in opts.analyses for a in ("tune", "margins", "simulate", "modal"))
    for v in variants:
        if v.ok and needs_loop:
            _attempt(v, "model", partial(_build_loop, v, opts))
    for analysis in opts.analyses:
        if analysis == "simulate":
            _simulate(variants, opts)
            continue
        for v in variants:
            if v.ok:
                _attempt(v, analysis, partial(_ANALYSES[analysis], v, opts))
    rows = []
    for v in variants:
        v.row["error"] = v.error
        rows.append(v.row)
    return ChunkResult(chunk.index, rows, time.perf_counter() - start)


def _limit_threads(n: int) -> None:
    """One worker process per core: its compiled kernels use ``n`` threads (numba's pool)."""
    try:
        import numba

        numba.set_num_threads(max(1, min(n, int(getattr(numba.config, "NUMBA_NUM_THREADS", n)))))
    except (ImportError, ValueError):   # pragma: no cover - numba is a dependency
        pass


def _attempt(v: _Variant, analysis: str, work: Callable[[], object]) -> None:
    try:
        work()
    except SicomatError as exc:
        v.error = f"{analysis}: {exc}"
    except Exception as exc:  # noqa: BLE001 - a variant's failure is a row, never a crashed study
        v.error = f"{analysis}: internal error {exc.__class__.__name__}: {exc}"


def _build_loop(v: _Variant, opts: StudyOptions) -> None:
    from ..servo.loop import build_servo_loop

    if v.machine.axes[opts.axis].controller is not None:
        v.loop = build_servo_loop(v.machine, opts.axis)


def _nan(x: Any) -> float:
    return math.nan if x is None else float(x)


def _modal(v: _Variant, opts: StudyOptions) -> None:
    from ..robotics.lowering import axis_mechanics

    # the loop's own mechanics when there is a loop (axis_mechanics built it): its modes, computed once, also
    # serve the tuning's and the margins' frequency grids
    mech = v.loop.mechanics if v.loop is not None else axis_mechanics(v.machine, opts.axis)
    result = mech.modes()
    flexible = sorted((m for m in result.modes if not m.rigid), key=lambda m: m.undamped_hz)
    for k in range(3):
        v.row[f"modal.f{k + 1}_hz"] = flexible[k].undamped_hz if k < len(flexible) else math.nan
    v.row["modal.zeta1"] = flexible[0].damping_ratio if flexible else math.nan
    v.row["modal.f_meca_hz"] = _nan(result.f_meca_hz)
    if v.loop is not None:   # the moving mass referred to the axis: phi' M phi, phi the rigid motion per unit axis
        phi, _ = mech.rigid_motion(mech.actuator(v.loop.actuator).vector, v.loop.tool)
        v.row["modal.moving_mass"] = float(phi @ mech.mass @ phi)


def _tune(v: _Variant, opts: StudyOptions) -> None:
    from ..tasks.analysis import tuned_machine
    from ..tuning.frequency import TuningTargets, tune_frequency

    given: dict[str, Any] = {key: value for key, value in opts.tune.items() if value is not None}
    if "position_crossover" in given:      # a position crossover instead of the position phase margin
        given["position_phase_margin"] = None
    targets = replace(TuningTargets(), **given)   # the rest: TuningTargets' defaults (45°, 80°, 6 dB, 2π f_meca/4)
    result = tune_frequency(v.loop, targets, suggest_notch=False)
    g, a = result.tuned, result.achieved
    two_pi = 2 * math.pi
    v.row.update({"tune.targets_met": bool(result.targets_met), "tune.stable": result.stable,
                  "tune.Kp": g.Kp, "tune.Kp_normalized": g.Kp_normalized, "tune.Ti": g.Ti, "tune.Kv": g.Kv})
    for loop in ("velocity", "position"):
        bandwidth = getattr(a, f"{loop}_bandwidth_rad_s")
        v.row.update({f"tune.{loop}_phase_margin_deg": getattr(a, f"{loop}_phase_margin_deg"),
                      f"tune.{loop}_gain_margin_db": getattr(a, f"{loop}_gain_margin_db"),
                      f"tune.{loop}_crossover_hz": getattr(a, f"{loop}_crossover_rad_s") / two_pi,
                      f"tune.{loop}_bandwidth_hz": _nan(bandwidth) / two_pi})
    v.loop = result.tuned_loop()
    v.machine = tuned_machine(v.machine, opts.axis, {"Kp": g.Kp, "Kp_normalized": g.Kp_normalized, "Ti": g.Ti,
                                                     "Kv": g.Kv})


def _margins(v: _Variant, opts: StudyOptions) -> None:
    from ..frequency.loops import LoopAnalysis
    from ..frequency.margins import stability_margins
    from ..servo.stability import loop_verdict

    an = LoopAnalysis.of(v.loop)
    for loop in ("velocity", "position"):
        m = stability_margins(an.response(f"{loop}-open"))
        v.row.update({f"margins.{loop}.phase_margin_deg": m.phase_margin_deg,
                      f"margins.{loop}.gain_margin_db": m.gain_margin_db,
                      f"margins.{loop}.crossover_hz": m.gain_crossover_rad_s / (2 * math.pi),
                      f"margins.{loop}.bandwidth_hz": _nan(m.bandwidth_rad_s) / (2 * math.pi),
                      f"margins.{loop}.delay_margin": m.delay_margin_s,
                      f"margins.{loop}.modulus_margin": m.modulus_margin})
    v.row["margins.stable"] = loop_verdict(v.loop, an=an).stable


def _profile(v: _Variant, opts: StudyOptions, move: float | None):
    from ..tasks.simulate import choose_profile

    profile, duration = choose_profile(v.machine.axes[opts.axis].trajectory, None,
                                       None if move is None else move * 1e3, opts.max_velocity, opts.max_acceleration)
    return profile, (opts.duration if opts.duration is not None else duration)


def _simulate(variants: list[_Variant], opts: StudyOptions) -> None:
    """The chunk's simulations, those of one structure (move, loop timing, sensor) in one compiled call."""
    groups: dict[Any, list[tuple[_Variant, Any, float]]] = {}
    for v in variants:
        if not v.ok:
            continue
        try:
            profile, duration = _profile(v, opts, opts.move)
        except SicomatError as exc:
            v.error = f"simulate: {exc}"
            continue
        loop = v.loop
        trajectory = v.machine.axes[opts.axis].trajectory
        key = (repr(trajectory), duration, loop.base_period, loop.position_ratio, loop.controller.position_sensor)
        groups.setdefault(key, []).append((v, profile, duration))
    for members in groups.values():
        try:
            _simulate_group(members)
        except Exception:  # noqa: BLE001 - structures differ (friction links, filters, delays), or one variant
            # fails (a memory limit, a model error): one call each, each failure a row with its message
            for member in members:
                _attempt(member[0], "simulate", partial(_simulate_group, [member]))


def _simulate_group(members: list[tuple[_Variant, Any, float]]) -> None:
    from ..servo.stability import loop_verdict
    from ..simulation import simulate_batch

    _, profile, duration = members[0]
    batch = simulate_batch([v.loop for v, _, _ in members], profile, duration, nonlinear=True)
    for k, (v, _, _) in enumerate(members):
        # sicomat simulate's "stable": the linear loop's poles (margins.stable when margins ran on this same
        # loop), no saturation-bound limit cycle, no divergence
        linear = v.row.get("margins.stable")
        linear = loop_verdict(v.loop).stable if linear is None else linear
        v.row["simulate.stable"] = bool(linear) and not batch.limit_cycle[k] and not batch.diverged[k]
        v.row.update({"simulate.max_following_error": float(batch.max_following_error[k]),
                      "simulate.rms_following_error": float(batch.rms_following_error[k]),
                      "simulate.final_error": float(batch.final_error[k]),
                      "simulate.settling_time": float(batch.settling_time[k]),
                      "simulate.overshoot_percent": float(batch.overshoot_percent[k]),
                      "simulate.max_effort": float(batch.max_effort[k]),
                      "simulate.diverged": bool(batch.diverged[k])})


def _circle(v: _Variant, opts: StudyOptions) -> None:
    from ..tasks.circle import circle_report

    test, payload, _ = circle_report(v.machine, opts.circle_radius, opts.circle_feed, model=opts.circle_model)
    for key in ("circular_deviation", "max_contour_error", "radial_deviation_min", "radial_deviation_max",
                "servo_mismatch"):
        v.row[f"circle.{key}"] = _nan(payload.get(key))
    if test.run is not None:
        v.row["circle.rms_contour_error"] = test.run.to_dict()["rms_contour_error"]
    v.row["circle.stable"] = payload.get("stable")


def _size(v: _Variant, opts: StudyOptions) -> None:
    from ..tasks.size import size_axis

    result = size_axis(v.machine, opts.axis, move_mm=None if opts.size_move is None else opts.size_move * 1e3,
                       inertia_ratio_limit=opts.inertia_ratio_limit)
    v.row["size.ok"] = result.ok
    for check in result.checks:
        if check.name in SIZE_CHECKS:
            v.row.update({f"size.{check.name}": _nan(check.value), f"size.{check.name}.limit": _nan(check.limit),
                          f"size.{check.name}.ok": check.ok})


_ANALYSES: dict[str, Callable[[_Variant, StudyOptions], None]] = {
    "modal": _modal, "tune": _tune, "margins": _margins, "circle": _circle, "size": _size}


def constraints_hold(row: dict[str, Any], constraints: "Sequence[Constraint]") -> bool:
    """Whether every constraint holds on ``row``; a missing or NaN value fails its constraint."""
    for c in constraints:
        value = row.get(c.metric)
        bound = row.get(c.bound) if isinstance(c.bound, str) else c.bound
        if value is None or bound is None or _isnan(value) or _isnan(bound):
            return False
        if isinstance(c.bound, bool) or isinstance(value, bool):
            if bool(value) != bool(bound):
                return False
            continue
        ok = {">=": value >= bound, "<=": value <= bound, ">": value > bound, "<": value < bound,
              "==": value == bound}[c.operator]
        if not ok:
            return False
    return True


def _isnan(x: Any) -> bool:
    return isinstance(x, float) and math.isnan(x)
