"""One entry point for every reduction method: :func:`reduce` (a machine's axis, or a plant, in;
a :class:`~sicomat.reduction.error.ReductionResult` out).

Bad arguments raise :class:`~sicomat.errors.ModelError` located at the **parameter** (``path="order"``,
``"keep"``, ``"band"``, ``"method"``, ``"inputs"``, ``"outputs"``): a front end maps the parameter to
its own name for it (the command line to ``--order``...; ``sicomat.cli._common.OPTIONS``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, TYPE_CHECKING, Sequence

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..description.machine import Axis, Machine
    from ..lti.plant import Plant
    from ..mechanics.lumped import Mechanics
    from .error import ReductionResult

__all__ = ["reduce", "METHODS", "default_transfer", "default_band", "names"]

METHODS = ("modal", "balanced", "balanced-dc", "schur", "hankel", "physical")
"""Accepted ``method`` values. ``balanced`` uses the frequency-limited ("partial") Gramians when a
band is given, ``balanced-dc`` is the singular-perturbation variant (keeps the static gain),
``schur`` the balancing-free Schur method, ``hankel`` the optimal Hankel-norm approximation."""

def names(value: str | Sequence[str] | None, parameter: str, empty: str) -> list[str] | None:
    """Comma-separated names (a string or a list of them, each possibly comma-separated) as a list;
    ``None`` stays ``None``; no name at all is an error located at ``parameter``.

    Examples
    --------
    >>> names(["a,b", " c"], "keep", "no names")
    ['a', 'b', 'c']
    """
    if value is None:
        return None
    items = [value] if isinstance(value, str) else list(value)
    found = [part.strip() for item in items for part in str(item).split(",")]
    found = [n for n in found if n]
    if not found:
        raise ModelError(empty, path=parameter, value=",".join(str(i) for i in items))
    return found


def default_transfer(axis: "Axis", mechanics: "Mechanics | None" = None) -> tuple[list[str], list[str], str]:
    """The transfer ``sicomat reduce`` reduces when none is chosen: ``(inputs, outputs, why)``.

    The one the loops close around: the drive's actuator (``drive.actuator``, or the mechanics'
    only one, as :func:`sicomat.servo.loop.build_servo_loop` chooses it) to the controller's position
    sensor. Without a controller: the driven actuator (every actuator without a drive) to every
    position sensor (every sensor if there is none), so that metres are never mixed with m/s.
    """
    sensors: dict[str, Any]
    if axis.mechanics is not None:
        lumped = axis.mechanics.to_lumped()
        actuators, sensors = list(lumped.actuators), dict(lumped.sensors)
    else:                       # a robot's axis: its lowered mechanics (given) names them
        assert mechanics is not None
        actuators, sensors = [a.name for a in mechanics.actuators], {m.name: m for m in mechanics.sensors}
    if axis.drive is not None and actuators:
        inputs = [axis.drive.actuator or actuators[0]]
    else:
        inputs = actuators
    if axis.controller is not None:
        return inputs, [axis.controller.position_sensor], "the drive's actuator to the controller's position sensor"
    position = [name for name, sensor in sensors.items() if sensor.kind == "position"]
    outputs = position or list(sensors)
    what = "position sensors" if position else "sensors"
    return inputs, outputs, f"the {'drive' if axis.drive is not None else 'actuators'} to the {what} (no controller)"


def default_band(axis: "Axis", mechanics: "Mechanics | None" = None) -> tuple[tuple[float, float] | None, str]:
    """The band of interest of ``sicomat reduce MODEL`` without ``--order``, ``--band`` or ``--keep``.

    0 Hz to the Nyquist frequency ``1/(2 Tv)`` of a sampled velocity loop: the controller acts up to
    it, and every mode below twice it (the ``--band`` rule), aliased or not, is one the loop can
    meet. Without a sampled velocity loop: 0 to 10 ``f_meca`` (the first flexible mode the
    actuator and sensors see). ``None`` for a rigid mechanics (nothing to remove).
    """
    from ..mechanics.lumped import build_mechanics

    ctrl = axis.controller
    if ctrl is not None and ctrl.velocity_loop == "discrete":
        return (0.0, 0.5 / ctrl.velocity_period), "the velocity loop's Nyquist frequency"
    mech = build_mechanics(axis.mechanics) if axis.mechanics is not None else mechanics
    assert mech is not None     # a robot's axis comes with its lowered mechanics
    f_meca = mech.modes().f_meca_hz
    if f_meca is None:
        return None, "a rigid mechanics"
    return (0.0, 10.0 * f_meca), "10 × f_meca"


def _tool(axis: "Axis") -> str | None:
    if axis.tool is not None:
        return axis.tool
    if axis.controller is not None and axis.mechanics is not None:
        lumped = axis.mechanics.to_lumped()
        sensor = lumped.sensors.get(axis.controller.position_sensor)
        return sensor.body if sensor is not None else None
    return None


def _order_for_band(plant, band_hz: tuple[float, float]) -> int:
    """States of the modes up to twice the band's upper limit (rigid part included)."""
    from .modal import spectral_split

    split = spectral_split(plant)
    poles = split.flexible.poles()
    return split.rigid.n + int(np.sum(np.abs(poles) <= 2 * 2 * np.pi * band_hz[1]))


def reduce(model: "Machine | Plant", method: str = "balanced", order: int | None = None, *,
           axis: str | None = None, keep: str | Sequence[str] | None = None,
           band: Sequence[float] | None = None, inputs: str | Sequence[str] | None = None,
           outputs: str | Sequence[str] | None = None) -> "ReductionResult":
    """Reduce a model by any of the :data:`METHODS`: the one entry point (``sicomat reduce`` calls it).

    Parameters
    ----------
    model : Machine or Plant
        A loaded model (its axis ``axis``, by default the first, is reduced), or a state space
        (every method but ``physical``, which regroups bodies and needs the mechanics).
    method : str
        One of :data:`METHODS`.
    order : int or None
        Number of states of the reduced model (two per body for ``physical``). For ``modal`` and
        the balanced methods without an order, a band keeps the modes up to twice its upper limit;
        without either, a machine's band is :func:`default_band` (used for the order and the
        reported band errors only: ``balanced`` keeps the ordinary Gramians) and a plant keeps every
        state. An order that would split a complex pole pair is rounded down, with a ``warnings``
        entry.
    keep : str, sequence of str or None
        Bodies to keep (``physical`` only); ``"a,b"`` strings are split at commas.
    band : (float, float) or None
        Band of interest ``(low_hz, high_hz)``: band errors for every method, frequency-limited
        Gramians for ``balanced``, the stiff-spring rule for ``physical``.
    inputs, outputs : str, sequence of str or None
        The transfer to reduce: actuator and sensor names (``"a,b"`` strings are split at commas);
        for a machine by default :func:`default_transfer`, the one the loops close around (a note
        says which); for a plant by default all its inputs and outputs.

    Returns
    -------
    ReductionResult
        For ``physical``, ``result.machine`` is the machine with the reduced axis (for a model
        file: :func:`sicomat.io.modelfile.save_model`); ``None`` for the other methods.

    Raises
    ------
    ModelError
        Unknown method or axis, order larger than the model or smaller than its rigid part, empty
        keep-list, unknown body or signal names, band with low ≥ high; located at the parameter
        (``error.path == "order"`` ...).

    Examples
    --------
    >>> import sicomat
    >>> result = sicomat.reduce(sicomat.load_model("examples/paper_5m4s.toml"), "modal", order=4)
    >>> result.order_before, result.order_after
    (10, 4)
    """
    from ..lti.plant import Plant
    from . import balanced as bal
    from .error import check_band
    from .modal import modal_truncation

    if method not in METHODS:
        raise ModelError(f"unknown method; expected one of {', '.join(METHODS)}", path="method", value=method)
    band_hz = None if band is None else _located(check_band, band, "band")
    keep_list = names(keep, "keep", "the keep-list is empty; expected body names separated by commas")
    if order is not None and (isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1):
        raise ModelError("expected a positive whole number of states", path="order", value=order)
    if keep_list is not None and method != "physical":
        raise ModelError("names bodies for method 'physical'; give an order for this method",
                         path="keep", value=",".join(keep_list))
    ins = names(inputs, "inputs", "expected signal names separated by commas")
    outs = names(outputs, "outputs", "expected signal names separated by commas")
    notes: list[str] = []
    if isinstance(model, Plant):
        if method == "physical":
            raise ModelError("the physical method regroups bodies: give a machine, not a state space",
                             path="method", value=method)
        plant, ax, machine, name, mech = model, None, None, None, None
    else:
        machine = model
        name = machine.axis_name(axis)
        ax = machine.axes[name]
        from ..robotics.lowering import axis_mechanics

        mech = axis_mechanics(machine, name)     # checked: a reduction of unresolvable poles means nothing
        if ins is None or outs is None:
            default_ins, default_outs, why = default_transfer(ax, mech)
            chosen = [f"{parameter} {','.join(found)}" for parameter, given, found in
                      (("inputs", ins, default_ins), ("outputs", outs, default_outs)) if given is None]
            notes.append(f"{' and '.join(chosen)} by default ({why})")
            ins = default_ins if ins is None else ins
            outs = default_outs if outs is None else outs
        plant = None
    try:
        if method == "physical":
            from .physical import physical_reduction, reduced_machine

            # a state space was refused above for this method: the machine, its axis and its name are set
            assert ax is not None and machine is not None and name is not None
            if ax.mechanics is None:
                raise ModelError("physical regrouping regroups lumped bodies; a robot's axis has a full mass "
                                 "matrix (use modal or balanced reduction)", path="method", value=method)
            result = physical_reduction(ax.mechanics, keep_list, order=order, band_hz=band_hz, tool=_tool(ax),
                                        inputs=ins, outputs=outs)
            assert result.spec is not None   # a physical reduction always gives the reduced mechanics table
            return dataclasses.replace(result, machine=reduced_machine(machine, name, result.spec,
                                                                       merged_into=result.merged_into),
                                       notes=(*notes, *result.notes))
        if plant is None:
            assert ax is not None and mech is not None   # no plant given: it comes from the machine's axis
            plant = mech.state_space()
        gramian_band = band_hz           # a band given by the caller also selects the partial Gramians
        if order is None:
            if band_hz is None:
                band_hz, why = default_band(ax, mech) if ax is not None else (None, "no band given")
                if band_hz is None:
                    order = plant.n_states
                    notes.append(f"no order or band given: {why}, every state kept")
                else:
                    order = min(_order_for_band(plant, band_hz), plant.n_states)
                    notes.append(f"no order or band given: the band of interest is 0-{band_hz[1]:.6g} Hz ({why}); "
                                 f"the modes up to twice it are kept: {order} states")
            else:
                order = min(_order_for_band(plant, band_hz), plant.n_states)
        if method == "modal":
            result = modal_truncation(plant, order, band_hz=band_hz, inputs=ins, outputs=outs)
        elif method == "balanced":
            if gramian_band is not None:
                result = bal.frequency_limited_truncation(plant, order, gramian_band, inputs=ins, outputs=outs)
            else:
                result = bal.balanced_truncation(plant, order, band_hz=band_hz, inputs=ins, outputs=outs)
        elif method == "balanced-dc":
            result = bal.balanced_truncation(plant, order, match_dc=True, band_hz=band_hz, inputs=ins, outputs=outs)
        elif method == "schur":
            result = bal.schur_truncation(plant, order, band_hz=band_hz, inputs=ins, outputs=outs)
        else:
            result = bal.hankel_norm_approximation(plant, order, band_hz=band_hz, inputs=ins, outputs=outs)
        return dataclasses.replace(result, notes=(*notes, *result.notes))
    except ModelError as exc:
        if exc.source is None and exc.path in ("band_hz", "keep") and not (exc.path == "keep" and keep_list):
            # the reductors name their own arguments: band_hz is the band; a physical reduction's
            # keep-list derived from the order or the band is about those
            parameter = "band" if exc.path == "band_hz" else (
                "order" if order is not None else ("band" if band_hz is not None else "keep"))
            raise ModelError(exc.message, path=parameter, value=exc.value, has_value=exc.has_value) from None
        raise


def _located(check, value, parameter: str):
    """``check(value)``, its ModelError located at ``parameter``."""
    try:
        return check(value)
    except ModelError as exc:
        raise ModelError(exc.message, path=parameter, value=exc.value, has_value=exc.has_value) from None
