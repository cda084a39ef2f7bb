"""The package's exceptions: one base class, each subclass also a builtin."""

from __future__ import annotations

__all__ = ["SicomatError", "ModelError", "AnalysisError", "OutputError", "ResourceError"]


class SicomatError(Exception):
    """Base class of every error SICOMAT raises on purpose."""


class ModelError(SicomatError, ValueError):
    """A model description (file, override or Python value) is invalid.

    Parameters
    ----------
    message : str
        What was found and what was expected.
    source : str, optional
        Where the model came from: a file path, or ``"--set"`` for a command-line override.
    path : str, optional
        Dotted key path inside the model, e.g. ``"axes.X.mechanics.bodies.load.mass"``.
    value : object, optional
        The offending value as written.
    """

    def __init__(self, message: str, *, source: str | None = None, path: str | None = None,
                 value: object = None, has_value: bool = False) -> None:
        self.message = message
        self.source = source
        self.path = path
        self.value = value
        self.has_value = has_value or value is not None
        super().__init__(self._format())

    def _format(self) -> str:
        parts = []
        if self.source:
            parts.append(_short(str(self.source)))
        if self.path:
            parts.append(_short(self.path))
        where = ": ".join(parts)
        what = self.message
        if self.has_value:
            what = f"{what} (got {_short(repr(self.value))})"
        return f"{where}: {what}" if where else what

    def with_source(self, source: str) -> "ModelError":
        """The same error, located in ``source``."""
        return ModelError(self.message, source=source, path=self.path, value=self.value,
                          has_value=self.has_value)


def _short(text: str, limit: int = 200) -> str:
    """``text`` cut to ``limit`` characters for a one-line message (a 60 000-character ``--set``
    value is echoed by its start and its length)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


class AnalysisError(SicomatError, RuntimeError):
    """An analysis cannot be carried out on a valid model (e.g. no actuator to excite it)."""


class OutputError(SicomatError, OSError):
    """An output file (figure, CSV, model) cannot be written where it was asked for."""


class ResourceError(SicomatError, MemoryError):
    """A piece of work would need more memory than allowed (see :mod:`sicomat.budget`); raised from
    an estimate, before anything is allocated."""
