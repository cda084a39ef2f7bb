"""Memory budget: estimate the size of large results before allocating them, refuse what cannot fit.

A simulation keeps every signal at every base step, a path interpolation every sample, an analysis
of a loop with a long computation delay a dense matrix with one state per delayed sample: an
innocent-looking option (``--duration 1e6``, a 1 ns sample period, ``velocity_delay = 1000000``)
asks for terabytes. The work estimates its size first and raises :class:`~sicomat.errors.ResourceError`
above the limit: 2 GiB by default, or the environment variable ``SICOMAT_MAX_MEMORY`` (bytes, or a
number with a unit: ``"8 GiB"``, ``"500 MB"``).
"""

from __future__ import annotations

import math
import os
import re

from .errors import ModelError, ResourceError

__all__ = ["DEFAULT_MAX_MEMORY", "ENVIRONMENT_VARIABLE", "max_memory", "require_memory", "require_dense",
           "format_bytes"]

DEFAULT_MAX_MEMORY = 2 * 1024 ** 3
"""Default limit of one piece of work's estimated memory (bytes): 2 GiB."""

ENVIRONMENT_VARIABLE = "SICOMAT_MAX_MEMORY"

_FACTORS = {"": 1, "b": 1, "kb": 1e3, "mb": 1e6, "gb": 1e9, "tb": 1e12,
            "kib": 1024, "mib": 1024 ** 2, "gib": 1024 ** 3, "tib": 1024 ** 4}
_SIZE = re.compile(r"\s*(\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*([A-Za-z]*)\s*")


def max_memory() -> float:
    """The limit in bytes: ``SICOMAT_MAX_MEMORY`` when set, else :data:`DEFAULT_MAX_MEMORY`.

    Examples
    --------
    >>> os.environ["SICOMAT_MAX_MEMORY"] = "8 GiB"; max_memory() == 8 * 1024 ** 3
    True
    >>> del os.environ["SICOMAT_MAX_MEMORY"]; max_memory() == DEFAULT_MAX_MEMORY
    True
    """
    text = os.environ.get(ENVIRONMENT_VARIABLE, "").strip()
    if not text:
        return float(DEFAULT_MAX_MEMORY)
    match = _SIZE.fullmatch(text)
    factor = _FACTORS.get(match.group(2).lower()) if match else None
    value = float(match.group(1)) * factor if match and factor is not None else math.nan
    if not (math.isfinite(value) and value > 0):
        raise ModelError("expected a memory size in bytes, or with a unit such as '8 GiB' or '500 MB'",
                         source=ENVIRONMENT_VARIABLE, value=text)
    return value


def format_bytes(n: float) -> str:
    """``n`` bytes for a message: ``"7.45 GiB"``.

    Examples
    --------
    >>> format_bytes(8e9), format_bytes(512), format_bytes(3 * 1024 ** 2)
    ('7.45 GiB', '512 B', '3 MiB')
    """
    for unit, size in (("TiB", 1024 ** 4), ("GiB", 1024 ** 3), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def require_memory(nbytes: float, what: str, detail: str = "") -> None:
    """Raise :class:`~sicomat.errors.ResourceError` when ``nbytes`` (an estimate) exceeds the limit.

    Parameters
    ----------
    nbytes : float
        Estimated size of the work's arrays (bytes).
    what : str
        The work, for the message ("this simulation").
    detail : str
        How the estimate is made up ("8000000000 steps x 14 values x 8 bytes").
    """
    limit = max_memory()
    if not nbytes <= limit:     # also refuses a NaN estimate
        how = f" ({detail})" if detail else ""
        raise ResourceError(f"{what} needs about {format_bytes(nbytes)}{how}, more than the limit of "
                            f"{format_bytes(limit)}; make it smaller, or raise the limit with the environment "
                            f"variable {ENVIRONMENT_VARIABLE} (e.g. {ENVIRONMENT_VARIABLE}='16 GiB')")


def require_dense(n_states: int, what: str, why: str = "", copies: int = 4) -> None:
    """:func:`require_memory` for dense ``n_states x n_states`` matrices (``copies`` of them alive at
    once: the system matrix, its powers or eigenvectors, the workspace of LAPACK)."""
    n = float(n_states)
    require_memory(8.0 * copies * n * n, what,
                   f"{n_states} states{f' ({why})' if why else ''}: {copies} dense matrices of 8-byte numbers")
