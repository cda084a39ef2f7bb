"""Progress of long work, reported through a plain callback: the library draws nothing itself.

A long function takes ``progress=None`` or a callable ``progress(task, done, total)``: ``task`` says
what is being done (``"simulating 2400 steps"``), ``done`` how much of it (steps, evaluations,
variants, phases), ``total`` how much there is, or ``None`` when that is not known in advance (an
optimiser's evaluations). A task starts with ``done = 0`` and may be followed by another task. The
command line turns these calls into a progress bar on the terminal (:mod:`sicomat.cli.progress`).

>>> seen = []
>>> notify(lambda task, done, total: seen.append((task, done, total)), "modes", 1, 3)
>>> notify(None, "modes", 2, 3)   # no callback: nothing happens
>>> seen
[('modes', 1, 3)]
"""

from __future__ import annotations

from typing import Optional, Protocol

__all__ = ["ProgressCallback", "notify"]


class ProgressCallback(Protocol):
    """``progress(task, done, total)``; ``total`` is ``None`` when unknown."""

    def __call__(self, task: str, done: float, total: Optional[float]) -> None: ...  # pragma: no cover


def notify(progress: ProgressCallback | None, task: str, done: float, total: float | None = None) -> None:
    """Call ``progress(task, done, total)`` if a callback was given."""
    if progress is not None:
        progress(task, done, total)
