"""CSV tables written under the output policy."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from .atomic import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["write_frame_csv"]


def write_frame_csv(frame: "pandas.DataFrame", path: str | os.PathLike) -> Path:
    """Write a DataFrame as CSV atomically, under the output policy (``docs/outputs.md``: a ``.csv``
    name, a new or regular file)."""
    return atomic_write(path, lambda tmp: frame.to_csv(tmp, float_format="%.10g"), kind="csv")
