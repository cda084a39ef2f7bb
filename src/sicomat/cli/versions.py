"""``sicomat version``: the versions that decide a result, for a bug report."""

from __future__ import annotations

import platform
from importlib import metadata

__all__ = ["versions"]

_LIBRARIES = ("numpy", "scipy", "control", "numba", "pydantic", "pint", "matplotlib", "pandas")


def versions() -> dict[str, str]:
    """``{"sicomat": ..., "python": ..., "numpy": ..., ...}``; a library not installed reads ``"missing"``."""
    from .. import __version__

    out = {"sicomat": __version__, "python": platform.python_version()}
    for name in _LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "missing"
    return out
