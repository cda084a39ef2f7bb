"""``sicomat circle``: the ISO 230-4 circle test of a machine, and for a ``[robot]`` machine what the coupling
of its axes adds to the contour error.

A machine of independent axes is simulated axis by axis (the only model it has). A robot machine is
simulated three ways (:data:`sicomat.simulation.paths.PATH_MODELS`): each axis alone on its decoupled
linearisation reading its own tool sensor (the way each axis is tuned), every axis together on the coupled
linearisation reading the tool point, and every axis together on the nonlinear dynamics (the inertia
matrix and Coriolis forces along the circle). The report's figures are those of ``model`` (default: the
nonlinear run, the most complete model) and ``coupling`` compares the three.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Machine
    from ..progress import ProgressCallback
    from ..simulation.paths import CircleTest

__all__ = ["circle_report", "COMPARED"]

COMPARED = ("circular_deviation", "max_contour_error", "radial_deviation_min", "radial_deviation_max",
            "servo_mismatch")
"""The figures ``coupling`` compares across the models (m)."""


def _figures(test: "CircleTest") -> dict[str, Any]:
    """One model's line of the comparison: the figures (None when it has none), the verdict, the run's time."""
    payload = test.to_dict()
    out: dict[str, Any] = {key: payload.get(key) for key in COMPARED}
    out["max_following_error"] = {name: axis.get("max_following_error") for name, axis in payload["axes"].items()}
    out["stable"] = payload.get("stable")
    out["wall_time_s"] = payload.get("wall_time_s")
    return out


def _difference(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float | None]:
    """``a - b`` figure by figure (None where either has none)."""
    return {key: (a[key] - b[key] if a.get(key) is not None and b.get(key) is not None else None)
            for key in ("circular_deviation", "max_contour_error")}


def circle_report(machine: "Machine", radius: float, feed: float, *, clockwise: bool = True,
                  feedforward: str | None = None, model: str | None = None,
                  progress: "ProgressCallback | None" = None) -> tuple["CircleTest", dict[str, Any], dict[str, "CircleTest"]]:
    """The circle test of ``machine`` (radius m, feed m/s): the test of ``model``, its JSON payload, and every
    model's test by name.

    ``model``: one of ``decoupled``, ``coupled``, ``nonlinear`` (default: ``nonlinear`` for a robot machine,
    ``decoupled`` for one of independent axes or with closed loops, which have no other). The payload is
    :meth:`CircleTest.to_dict` plus ``"model"`` and, for a robot machine, ``"coupling"``:
    ``{"decoupled": {...}, "coupled": {...}, "nonlinear": {...}, "added_by_coupling": {...},
    "added_by_linear_coupling": {...}, "added_by_large_motion": {...}}`` — per model the figures of
    :data:`COMPARED` (m), each axis's largest following error and the verdict; ``added_by_coupling`` =
    nonlinear - decoupled (what the decoupled linearisation misses), split into
    ``added_by_linear_coupling`` = coupled - decoupled (the axes' inertial and elastic coupling, the tool
    point's offsets from the axes: an Abbe error) and ``added_by_large_motion`` = nonlinear - coupled (the
    configuration-dependent inertia and the Coriolis forces over the circle), each for the circular
    deviation and the largest contour error.
    """
    from ..simulation.paths import PATH_MODELS, circle_test

    if model is not None and model not in PATH_MODELS:
        raise ModelError(f"expected one of {', '.join(PATH_MODELS)}", path="model", value=model)
    spec = machine.robot
    robot = spec is not None and not (spec.links is not None and spec.links < len(spec.frames))
    if not robot and model not in (None, "decoupled"):
        why = ("a machine with closed loops has no coupled path model yet (docs/robotics.md, 'Not built yet')"
               if spec is not None else "this machine's axes are independent")
        raise ModelError(f"the coupled and nonlinear models need a machine described by a [robot] section without "
                         f"closed loops; {why} (its only model: decoupled)", path="model", value=model)
    chosen = model or ("nonlinear" if robot else "decoupled")
    models = PATH_MODELS if robot else ("decoupled",)
    tests = {name: circle_test(machine, radius, feed, clockwise=clockwise, feedforward=feedforward,
                               progress=progress, model=name) for name in models}
    payload = tests[chosen].to_dict()
    payload["model"] = chosen
    if robot:
        lines = {name: _figures(test) for name, test in tests.items()}
        payload["coupling"] = {**lines,
                               "added_by_coupling": _difference(lines["nonlinear"], lines["decoupled"]),
                               "added_by_linear_coupling": _difference(lines["coupled"], lines["decoupled"]),
                               "added_by_large_motion": _difference(lines["nonlinear"], lines["coupled"])}
    return tests[chosen], payload, tests
