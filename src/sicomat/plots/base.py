"""The one figure base: a headless matplotlib Figure (no pyplot) and the atomic save. The figures
themselves are by topic: :mod:`.modes`, :mod:`.time`, :mod:`.frequency`, :mod:`.motion`. Computing
never happens in ``plots/``."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["new_figure", "save_figure"]


def new_figure(**kwargs: Any) -> "Figure":
    """A matplotlib ``Figure`` (no pyplot, so no GUI backend and no global state), with the
    constrained layout unless ``layout`` is given; the keywords are ``Figure``'s."""
    from matplotlib.figure import Figure

    kwargs.setdefault("layout", "constrained")
    return Figure(**kwargs)


def save_figure(fig: "Figure", path: str | os.PathLike) -> Path:
    """Save ``fig`` to ``path`` atomically, under the output policy (``docs/outputs.md``); the
    format is the name's extension: .png, .svg or .pdf."""
    from ..io.atomic import atomic_write, check_output

    target = check_output(path, "figure")
    suffix = target.suffix.lower()
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format=suffix[1:], dpi=120), suffix=suffix,
                        kind="figure")
