"""The progress bar of long commands: rich, on stderr, only when stderr is a terminal.

The library reports progress through a plain callback (:mod:`sicomat.progress`); :func:`progress_bar`
turns it into a rich bar. The bar appears only if the work lasts longer than :data:`DELAY` (a short
tuning does not flash one), is transient (gone when the work ends, before any result is printed),
never touches stdout (``--json`` stays one JSON object) and is not drawn at all when stderr is not a
terminal (a pipe, a file, a CI log).
"""

from __future__ import annotations

import sys
import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING, Iterator, Optional

if TYPE_CHECKING:  # pragma: no cover
    from rich.progress import Progress, TaskID

__all__ = ["progress_bar", "DELAY"]

DELAY = 0.5  # s of work before the bar appears


def _stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # closed or replaced stream
        return False


def _console():
    from rich.console import Console

    return Console(stderr=True)


class _Bar:
    """A callback ``(task, done, total)`` that drives a rich Progress started after :data:`DELAY`; one
    line, showing the latest task (a new task replaces the previous one)."""

    def __init__(self, console) -> None:
        self._console = console
        self._lock = threading.Lock()
        self._progress: "Progress | None" = None
        self._task_id: "TaskID | None" = None
        self._state: tuple[str, float, Optional[float]] | None = None
        self._closed = False
        self._timer = threading.Timer(DELAY, self._show)
        self._timer.daemon = True
        if DELAY > 0:
            self._timer.start()
        else:  # no delay: the bar is there before the work starts
            self._show()

    def _show(self) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        with self._lock:
            if self._closed:
                return
            self._progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                                      MofNCompleteColumn(), TimeElapsedColumn(), console=self._console,
                                      transient=True, redirect_stdout=False, redirect_stderr=False)
            task, done, total = self._state or ("working", 0, None)
            self._task_id = self._progress.add_task(task, total=total)
            self._progress.update(self._task_id, completed=done)   # add_task's `completed` is typed int
            self._progress.start()

    def __call__(self, task: str, done: float, total: Optional[float]) -> None:
        with self._lock:
            self._state = (task, done, total)
            if self._progress is not None and self._task_id is not None:
                self._progress.update(self._task_id, description=task, completed=done, total=total)

    def close(self) -> None:
        self._timer.cancel()
        with self._lock:
            self._closed = True
            if self._progress is not None:
                self._progress.stop()
                self._progress = None


@contextmanager
def progress_bar() -> Iterator[Optional["_Bar"]]:
    """A progress callback for the library calls inside the block (``None`` when stderr is not a
    terminal); the bar is removed when the block ends, before the command prints its result."""
    if not _stderr_is_terminal():
        yield None
        return
    bar = _Bar(_console())
    try:
        yield bar
    finally:
        bar.close()
