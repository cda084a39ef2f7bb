"""Output files: one policy for every file SICOMAT writes, and the atomic write itself.

The policy (``docs/outputs.md``):

- an output is never one of the command's inputs (same file by :func:`os.path.samefile`, so a
  hard link or a symbolic link to the model counts), and two outputs of one command are never the
  same file;
- only a regular file or a new path is replaced: a folder, a device, a named pipe (FIFO) or a
  socket is refused; a symbolic link is followed, and the regular file it points to is replaced
  (the link stays); a link to a missing file is refused;
- the name's extension fits the format (:data:`FORMATS`);
- the file is written to a temporary file next to the target, then renamed over it: nothing is
  half-written, and an error names the path the user gave, never the temporary file.

Every refusal is an :class:`~sicomat.errors.OutputError` (the CLI: one line, exit status 2).
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path
from typing import Callable, Mapping, Optional, Tuple, Union

from ..errors import OutputError

__all__ = ["FORMATS", "atomic_write", "check_output", "check_outputs"]

FORMATS: dict[str, Tuple[str, Tuple[str, ...]]] = {
    "csv": ("a CSV file", (".csv",)),
    "figure": ("a figure", (".png", ".svg", ".pdf")),
    "model": ("a model file", (".toml",)),
    "parquet": ("a Parquet file", (".parquet",)),
    "json": ("a JSON file", (".json",)),
}
"""Output kinds: a description and the accepted extensions (compared ignoring case)."""

PathLike = Union[str, "os.PathLike[str]"]


def check_outputs(outputs: Mapping[str, Tuple[Optional[PathLike], str]],
                  inputs: Mapping[str, Optional[PathLike]] = {}) -> None:
    """Check all outputs of one command before any work is done.

    Parameters
    ----------
    outputs : mapping
        Option name (e.g. ``"--out"``) to ``(path or None, kind)``, kind a key of :data:`FORMATS`;
        ``None`` paths (option not given) are skipped.
    inputs : mapping
        What each input is (e.g. ``"the model file"``) to its path (``None`` skipped).

    Raises
    ------
    OutputError
        Two outputs name the same file, or one of them breaks the policy (:func:`check_output`).

    Examples
    --------
    >>> check_outputs({"--out": ("run.csv", "csv"), "--plot": ("run.csv", "figure")})
    Traceback (most recent call last):
    ...
    sicomat.errors.OutputError: run.csv: --out and --plot name the same file; give each output its own file
    """
    given = [(option, Path(path), kind) for option, (path, kind) in outputs.items() if path is not None]
    for i, (option, path, _) in enumerate(given):
        for other, earlier, _ in given[:i]:
            if _same_file(path, earlier):
                raise OutputError(f"{path}: {other} and {option} name the same file; "
                                  "give each output its own file")
    for option, path, kind in given:
        check_output(path, kind, option=option, inputs=inputs)


def check_output(path: PathLike, kind: Optional[str] = None, *, option: Optional[str] = None,
                 inputs: Mapping[str, Optional[PathLike]] = {}) -> Path:
    """Check that ``path`` may be written as an output of ``kind``; return the file that will be replaced.

    The returned path is ``path`` itself, or for a symbolic link the real file it points to.

    Raises
    ------
    OutputError
        Wrong extension; an existing folder, device, FIFO or socket; a link to a missing file; one
        of ``inputs``; a missing folder or one that cannot be written. The message starts with
        ``path`` as given and says what was expected.
    """
    given = Path(path)
    what = f"{option} " if option else ""
    target = Path(os.path.realpath(given)) if given.is_symlink() else given
    for label, source in inputs.items():
        if source is not None and _same_file(target, Path(source)):
            raise OutputError(f"{given}: {what}would replace {label} this command reads; an output never "
                              "replaces an input, choose another file")
    if kind is not None:
        _check_extension(given, given, what, kind)
    if target != given and not target.exists():
        raise OutputError(f"{given}: {what}is a symbolic link to a missing file ({target}); expected a "
                          "regular file, a link to one, or a new name")
    try:
        st: Optional[os.stat_result] = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{given}: {what}cannot be checked ({_reason(exc)})") from None
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"{given}: {what}is {_file_type(st.st_mode)}, not a regular file; an output only "
                              "replaces a regular file or creates a new one")
        if not os.access(target, os.W_OK):
            raise OutputError(f"{given}: {what}is read-only; expected a file that may be replaced")
    if kind is not None and target != given:
        _check_extension(given, target, what, kind)
    folder = target.parent
    if not folder.is_dir():
        problem = "is not a folder" if folder.exists() else "does not exist"
        raise OutputError(f"{given}: {what}cannot be written: the folder '{folder}' {problem}")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{given}: {what}cannot be written: the folder '{folder}' is not writable "
                          "(permission denied or read-only file system)")
    return target


def atomic_write(path: PathLike, write: Callable[[str], object], suffix: Optional[str] = None, *,
                 kind: Optional[str] = None, inputs: Mapping[str, Optional[PathLike]] = {}) -> Path:
    """Check ``path`` (:func:`check_output`), call ``write(temporary_path)``, then rename the result over it.

    The temporary file sits in the target's folder (``suffix``: its extension, default the
    target's, for writers that choose the format by name). A replaced file keeps its permission
    bits; a new one gets the usual ``0o666`` less the umask. On any failure the temporary file is
    removed and the target is left as it was.

    Returns
    -------
    Path
        ``path`` as given.

    Raises
    ------
    OutputError
        The policy refuses ``path``, or the system refuses to write it (the reason, e.g. "No space
        left on device", follows the path the user gave).
    """
    given = Path(path)
    target = check_output(given, kind, inputs=inputs)
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    except OSError as exc:
        raise OutputError(f"{given}: cannot be written ({_reason(exc)})") from None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix or target.suffix or ".tmp",
                                   dir=target.parent)
    except OSError as exc:
        raise OutputError(f"{given}: cannot be written ({_reason(exc)})") from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"{given}: cannot be written ({_reason(exc)})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return given


def _check_extension(given: Path, name: Path, what: str, kind: str) -> None:
    description, extensions = FORMATS[kind]
    if name.suffix.lower() in extensions:
        return
    expected = ", ".join(extensions[:-1]) + " or " + extensions[-1] if len(extensions) > 1 else extensions[0]
    got = f"'{name.suffix}'" if name.suffix else "no extension"
    where = "" if name == given else f" (the link points to {name})"
    raise OutputError(f"{given}: {what}writes {description}; expected a name ending in {expected}, "
                      f"got {got}{where}")


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet): the same only if both name one path
        return os.path.realpath(a) == os.path.realpath(b)


def _file_type(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def _reason(exc: OSError) -> str:
    """The system's reason, without the file name it carries (that may be the temporary file)."""
    return exc.strerror or str(exc) or exc.__class__.__name__
