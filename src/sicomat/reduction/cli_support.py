"""What ``sicomat reduce`` does, as one library call: options in, :class:`ReductionResult` out."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..model import Axis, Machine
    from .error import ReductionResult

__all__ = ["reduce_command", "parse_band", "parse_keep", "METHODS"]

METHODS = ("modal", "balanced", "balanced-dc", "schur", "hankel", "physical")
"""Accepted ``--method`` values. ``balanced`` uses the frequency-limited ("partial") Gramians when a
band is given, ``balanced-dc`` is the singular-perturbation variant (keeps the static gain),
``schur`` the balancing-free Schur method, ``hankel`` the optimal Hankel-norm approximation."""

_OPTION = {"order": "--order", "keep": "--keep", "band_hz": "--band", "method": "--method"}


def parse_band(band: str | Sequence[float] | None) -> tuple[float, float] | None:
    """``"LOW_HZ:HIGH_HZ"`` (or a pair of numbers) as ``(low_hz, high_hz)``, checked.

    Examples
    --------
    >>> parse_band("0:200")
    (0.0, 200.0)
    """
    from .error import check_band

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
    if keep is None:
        return None
    items = [keep] if isinstance(keep, str) else list(keep)
    names = [part.strip() for item in items for part in str(item).split(",")]
    names = [n for n in names if n]
    if not names:
        raise ModelError("the keep-list is empty; expected body names separated by commas",
                         source="--keep", value=",".join(items) if items else "")
    return names


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
    from .modal import spectral_split

    split = spectral_split(plant)
    poles = split.flexible.poles()
    return split.rigid.n + int(np.sum(np.abs(poles) <= 2 * 2 * np.pi * band_hz[1]))


def reduce_command(machine: "Machine", axis: str | None, method: str, order: int | None,
                   keep: str | Sequence[str] | None, band: str | Sequence[float] | None) -> "ReductionResult":
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
        the balanced methods without an order, a band keeps the modes up to twice its upper limit.
    keep : str, sequence of str or None
        Bodies to keep (``physical`` only); ``"a,b"`` strings are split at commas.
    band : str, (float, float) or None
        Band of interest ``"LOW_HZ:HIGH_HZ"`` or ``(low_hz, high_hz)``: band errors for every
        method, frequency-limited Gramians for ``balanced``, the stiff-spring rule for ``physical``.

    Returns
    -------
    ReductionResult
        For ``physical``, ``result.machine`` is the machine with the reduced axis (for
        ``--write``: :func:`sicomat.modelfile.save_model`); ``None`` for the other methods.

    Raises
    ------
    ModelError
        Unknown method or axis, order larger than the model or smaller than its rigid part, empty
        keep-list, unknown body names, band with low ≥ high; located at the option
        (``source="--order"`` ...), for the CLI's one-line message and exit status 2.
    """
    from ..mechanics import build_mechanics
    from . import balanced as bal
    from .modal import modal_truncation
    from .physical import physical_reduction, reduced_machine

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
    from ..conditioning import check_axis_mechanics

    check_axis_mechanics(name, ax.mechanics)     # a reduction of unresolvable poles means nothing
    try:
        if method == "physical":
            result = physical_reduction(ax.mechanics, keep_list, order=order, band_hz=band_hz, tool=_tool(ax))
            return dataclasses.replace(result, machine=reduced_machine(machine, name, result.spec,
                                                                       merged_into=result.merged_into))
        plant = build_mechanics(ax.mechanics).state_space()
        if order is None:
            if band_hz is None:
                raise ModelError(f"--method {method} needs --order N (or --band LOW:HIGH to keep the "
                                 "modes up to twice the band)", source="--order")
            order = min(_order_for_band(plant, band_hz), plant.n_states)
        if method == "modal":
            return modal_truncation(plant, order, band_hz=band_hz)
        if method == "balanced":
            if band_hz is not None:
                return bal.frequency_limited_truncation(plant, order, band_hz)
            return bal.balanced_truncation(plant, order)
        if method == "balanced-dc":
            return bal.balanced_truncation(plant, order, match_dc=True, band_hz=band_hz)
        if method == "schur":
            return bal.schur_truncation(plant, order, band_hz=band_hz)
        return bal.hankel_norm_approximation(plant, order, band_hz=band_hz)
    except ModelError as exc:
        if exc.source is None and exc.path in _OPTION:
            option = _OPTION[exc.path]
            if exc.path == "keep" and keep_list is None:
                option = "--order" if order is not None else ("--band" if band_hz is not None else "--keep")
            raise _as_option(exc, option) from None
        raise
