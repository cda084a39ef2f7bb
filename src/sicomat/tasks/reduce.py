"""What ``sicomat reduce`` does, as one library call: options in, :class:`ReductionResult` out."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    import os

    from ..description.machine import Axis, Machine
    from ..reduction.error import ReductionResult

__all__ = ["reduce_command", "write_reduced", "parse_band", "parse_keep", "parse_signals", "default_transfer",
           "default_band", "METHODS"]

METHODS = ("modal", "balanced", "balanced-dc", "schur", "hankel", "physical")
"""Accepted ``--method`` values. ``balanced`` uses the frequency-limited ("partial") Gramians when a
band is given, ``balanced-dc`` is the singular-perturbation variant (keeps the static gain),
``schur`` the balancing-free Schur method, ``hankel`` the optimal Hankel-norm approximation."""

_OPTION = {"order": "--order", "keep": "--keep", "band_hz": "--band", "method": "--method",
           "inputs": "--inputs", "outputs": "--outputs"}


def parse_band(band: str | Sequence[float] | None) -> tuple[float, float] | None:
    """``"LOW_HZ:HIGH_HZ"`` (or a pair of numbers) as ``(low_hz, high_hz)``, checked.

    Examples
    --------
    >>> parse_band("0:200")
    (0.0, 200.0)
    """
    from ..reduction.error import check_band

    if band is None:
        return None
    if isinstance(band, str):
        parts = band.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            values = (float(parts[0]), float(parts[1]))
        except ValueError:
            raise ModelError("expected LOW_HZ:HIGH_HZ, e.g. 0:200", source="--band", value=band) from None
        if any(math.isfinite(b) and b != 0 and not 1e-100 <= abs(b) <= 1e100 for b in values):
            raise ModelError("expected frequencies of magnitude 1e-100 to 1e100 Hz (or 0), like every value",
                             source="--band", value=band)
        band = values
    try:
        return check_band(band)
    except ModelError as exc:
        raise _as_option(exc, "--band") from None


def parse_keep(keep: str | Sequence[str] | None) -> list[str] | None:
    """``"a,b,c"`` (or a list of names, each possibly comma-separated) as a list of body names."""
    return _names(keep, "--keep", "the keep-list is empty; expected body names separated by commas")


def parse_signals(names: str | Sequence[str] | None, option: str) -> list[str] | None:
    """``"a,b"`` (or a list of names, each possibly comma-separated) as a list of signal names."""
    return _names(names, option, "expected signal names separated by commas")


def _names(value: str | Sequence[str] | None, option: str, empty: str) -> list[str] | None:
    """Comma-separated names of an option (a string or a list of them); ``empty`` when there are none."""
    if value is None:
        return None
    items = [value] if isinstance(value, str) else list(value)
    names = [part.strip() for item in items for part in str(item).split(",")]
    names = [n for n in names if n]
    if not names:
        raise ModelError(empty, source=option, value=",".join(str(i) for i in items))
    return names


def default_transfer(axis: "Axis") -> tuple[list[str], list[str], str]:
    """The transfer ``sicomat reduce`` reduces when none is chosen: ``(inputs, outputs, why)``.

    The one the loops close around: the drive's actuator (``drive.actuator``, or the mechanics'
    only one, as :func:`sicomat.servo.loop.build_servo_loop` chooses it) to the controller's position
    sensor. Without a controller: the driven actuator (every actuator without a drive) to every
    position sensor (every sensor if there is none), so that metres are never mixed with m/s.
    """
    lumped = axis.mechanics.to_lumped()
    actuators, sensors = list(lumped.actuators), lumped.sensors
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


def default_band(axis: "Axis") -> tuple[tuple[float, float] | None, str]:
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
    f_meca = build_mechanics(axis.mechanics).modes().f_meca_hz
    if f_meca is None:
        return None, "a rigid mechanics"
    return (0.0, 10.0 * f_meca), "10 × f_meca"


def _as_option(exc: ModelError, option: str) -> ModelError:
    return ModelError(exc.message, source=option, value=exc.value, has_value=exc.has_value)


def _tool(axis: "Axis") -> str | None:
    if axis.tool is not None:
        return axis.tool
    if axis.controller is not None:
        lumped = axis.mechanics.to_lumped()
        sensor = lumped.sensors.get(axis.controller.position_sensor)
        return sensor.body if sensor is not None else None
    return None


def _order_for_band(plant, band_hz: tuple[float, float]) -> int:
    """States of the modes up to twice the band's upper limit (rigid part included)."""
    from ..reduction.modal import spectral_split

    split = spectral_split(plant)
    poles = split.flexible.poles()
    return split.rigid.n + int(np.sum(np.abs(poles) <= 2 * 2 * np.pi * band_hz[1]))


def reduce_command(machine: "Machine", axis: str | None, method: str, order: int | None,
                   keep: str | Sequence[str] | None, band: str | Sequence[float] | None,
                   inputs: str | Sequence[str] | None = None,
                   outputs: str | Sequence[str] | None = None) -> "ReductionResult":
    """Reduce one axis of a machine, as ``sicomat reduce`` does.

    Parameters
    ----------
    machine : Machine
        The loaded model.
    axis : str or None
        Axis name (``None``: the first axis).
    method : str
        One of :data:`METHODS`.
    order : int or None
        Number of states of the reduced model (two per body for ``physical``). For ``modal`` and
        the balanced methods without an order, a band keeps the modes up to twice its upper limit;
        without either, the band is :func:`default_band` (used for the order and the reported
        band errors only: ``balanced`` keeps the ordinary Gramians). An order that would split a
        complex pole pair is rounded down, with a ``warnings`` entry.
    keep : str, sequence of str or None
        Bodies to keep (``physical`` only); ``"a,b"`` strings are split at commas.
    band : str, (float, float) or None
        Band of interest ``"LOW_HZ:HIGH_HZ"`` or ``(low_hz, high_hz)``: band errors for every
        method, frequency-limited Gramians for ``balanced``, the stiff-spring rule for ``physical``.
    inputs, outputs : str, sequence of str or None
        The transfer to reduce: actuator and sensor names (``"a,b"`` strings are split at commas);
        by default :func:`default_transfer`, the one the loops close around. The result's
        ``inputs``/``outputs`` (and a note for the default) say which.

    Returns
    -------
    ReductionResult
        For ``physical``, ``result.machine`` is the machine with the reduced axis (for
        ``--write``: :func:`sicomat.io.modelfile.save_model`); ``None`` for the other methods.

    Raises
    ------
    ModelError
        Unknown method or axis, order larger than the model or smaller than its rigid part, empty
        keep-list, unknown body names, band with low ≥ high; located at the option
        (``source="--order"`` ...), for the CLI's one-line message and exit status 2.
    """
    from ..mechanics.lumped import build_mechanics
    from ..reduction import balanced as bal
    from ..reduction.modal import modal_truncation
    from ..reduction.physical import physical_reduction, reduced_machine

    if method not in METHODS:
        raise ModelError(f"unknown method; expected one of {', '.join(METHODS)}", source="--method",
                         value=method)
    band_hz = parse_band(band)
    keep_list = parse_keep(keep)
    if order is not None and (isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1):
        raise ModelError("expected a positive whole number of states", source="--order", value=order)
    if keep_list is not None and method != "physical":
        raise ModelError("--keep names bodies for --method physical; give --order N for this method",
                         source="--keep", value=",".join(keep_list))
    name = machine.axis_name(axis)
    ax = machine.axes[name]
    from ..mechanics.lumped import check_axis_mechanics

    check_axis_mechanics(name, ax.mechanics)     # a reduction of unresolvable poles means nothing
    ins, outs = parse_signals(inputs, "--inputs"), parse_signals(outputs, "--outputs")
    notes: list[str] = []
    if ins is None or outs is None:
        default_ins, default_outs, why = default_transfer(ax)
        chosen = [f"{option} {','.join(names)}" for option, given, names in
                  (("--inputs", ins, default_ins), ("--outputs", outs, default_outs)) if given is None]
        notes.append(f"{' '.join(chosen)} by default ({why})")
        ins = default_ins if ins is None else ins
        outs = default_outs if outs is None else outs
    try:
        if method == "physical":
            result = physical_reduction(ax.mechanics, keep_list, order=order, band_hz=band_hz, tool=_tool(ax),
                                        inputs=ins, outputs=outs)
            assert result.spec is not None   # a physical reduction always gives the reduced mechanics table
            return dataclasses.replace(result, machine=reduced_machine(machine, name, result.spec,
                                                                       merged_into=result.merged_into),
                                       notes=(*notes, *result.notes))
        plant = build_mechanics(ax.mechanics).state_space()
        gramian_band = band_hz           # a band given by the user also selects the partial Gramians
        if order is None:
            if band_hz is None:
                band_hz, why = default_band(ax)
                if band_hz is None:
                    order = plant.n_states
                    notes.append(f"no --order or --band: {why}, every state kept")
                else:
                    order = min(_order_for_band(plant, band_hz), plant.n_states)
                    notes.append(f"no --order or --band: the band of interest is 0-{band_hz[1]:.6g} Hz ({why}); "
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
        if exc.source is None and exc.path in _OPTION:
            option = _OPTION[exc.path]
            if exc.path == "keep" and keep_list is None:
                option = "--order" if order is not None else ("--band" if band_hz is not None else "--keep")
            raise _as_option(exc, option) from None
        raise


def write_reduced(result: "ReductionResult", path: "str | os.PathLike", based_on: "str | os.PathLike | None" = None,
                  axis: str | None = None):
    """Write the machine of a physical reduction (``sicomat reduce --write``).

    With ``based_on`` (the reduced model file) the file is that file's text edited: the reduced
    axis's surviving bodies, couplings and frictions keep their lines (a changed value keeps its
    unit, marked ``# was``), merged-away ones are removed with their lines, new entries are plain SI
    numbers; a header names the source and the method and says what is not kept.
    """
    from ..io.modelfile import save_model

    if result.machine is None:
        raise ModelError("only the physical method gives a model file; the others give a state space",
                         source="--write", value=str(path))
    header = None
    if based_on is not None:
        onto = ", ".join(result.spec.bodies) if result.spec is not None else "fewer bodies"
        header = (f"Reduced by `sicomat reduce --method physical` from {based_on}"
                  + (f", axis {axis}" if axis else "") + f": bodies regrouped onto {onto}.\n"
                  "Kept: the rest of the file as written. Changed values are marked '# was'; merged-away\n"
                  "bodies, couplings and frictions are removed with their lines; new entries are plain SI\n"
                  "numbers. Not kept: comments are the original's and may describe the unreduced model.")
    return save_model(result.machine, path, based_on=based_on, header=header)
