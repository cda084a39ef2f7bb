"""What ``sicomat reduce`` does, as one library call: options as text in, :class:`ReductionResult` out.

The work is :func:`sicomat.reduction.methods.reduce`; this adds the band written as text
(``"LOW_HZ:HIGH_HZ"``) and the reduced model file. Errors are located at the parameter
(``ModelError.path``: ``"order"``, ``"band"``...), as the core's are.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from ..errors import ModelError
from ..reduction.methods import METHODS, default_band, default_transfer, names

if TYPE_CHECKING:  # pragma: no cover
    import os

    from ..description.machine import Machine
    from ..reduction.error import ReductionResult

__all__ = ["reduce_command", "write_reduced", "parse_band", "parse_keep", "parse_signals", "default_transfer",
           "default_band", "METHODS"]


def parse_band(band: str | Sequence[float] | None) -> tuple[float, float] | None:
    """``"LOW_HZ:HIGH_HZ"`` (or a pair of numbers) as ``(low_hz, high_hz)``, checked; errors are
    located at the parameter ``band``.

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
            raise ModelError("expected LOW_HZ:HIGH_HZ, e.g. 0:200", path="band", value=band) from None
        if any(math.isfinite(b) and b != 0 and not 1e-100 <= abs(b) <= 1e100 for b in values):
            raise ModelError("expected frequencies of magnitude 1e-100 to 1e100 Hz (or 0), like every value",
                             path="band", value=band)
        band = values
    try:
        return check_band(band)
    except ModelError as exc:
        raise ModelError(exc.message, path="band", value=exc.value, has_value=exc.has_value) from None


def parse_keep(keep: str | Sequence[str] | None) -> list[str] | None:
    """``"a,b,c"`` (or a list of names, each possibly comma-separated) as a list of body names."""
    return names(keep, "keep", "the keep-list is empty; expected body names separated by commas")


def parse_signals(signals: str | Sequence[str] | None, parameter: str) -> list[str] | None:
    """``"a,b"`` (or a list of names, each possibly comma-separated) as a list of signal names."""
    return names(signals, parameter, "expected signal names separated by commas")


def reduce_command(machine: "Machine", axis: str | None, method: str, order: int | None,
                   keep: str | Sequence[str] | None, band: str | Sequence[float] | None,
                   inputs: str | Sequence[str] | None = None,
                   outputs: str | Sequence[str] | None = None) -> "ReductionResult":
    """Reduce one axis of a machine, as ``sicomat reduce`` does: :func:`sicomat.reduction.methods.reduce`
    with ``band`` also as ``"LOW_HZ:HIGH_HZ"`` text (:func:`parse_band`).

    Raises
    ------
    ModelError
        As :func:`~sicomat.reduction.methods.reduce`, located at the parameter (``path="order"``...;
        the command line names its option instead).
    """
    from ..reduction.methods import reduce

    if method not in METHODS:
        raise ModelError(f"unknown method; expected one of {', '.join(METHODS)}", path="method", value=method)
    return reduce(machine, method, order, axis=axis, keep=keep, band=parse_band(band), inputs=inputs,
                  outputs=outputs)


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
