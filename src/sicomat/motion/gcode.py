"""A small G-code subset (G00 G01 G02 G03 G17 G90 G91 G21 G94, F X Y Z I J N, M02 M30) read into a Path."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import ModelError
from .path import Arc, Line, Path, Segment

__all__ = ["GCodeError", "parse_gcode", "SUPPORTED_G", "SUPPORTED_WORDS"]

SUPPORTED_G = "G00 G01 G02 G03 G17 G90 G91"
"""The G-codes with an effect (G21 and G94, the only modes read, are accepted too)."""
SUPPORTED_WORDS = "G F X Y Z I J N, M02 M30"
MM = 1e-3                     # the file is in millimetres
MM_PER_MIN = 1e-3 / 60.0      # F words

_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
_G_REASONS = {
    4: "dwell is not supported", 9: "exact stop is not supported",
    18: "only the XY plane (G17) is supported", 19: "only the XY plane (G17) is supported",
    20: "inch programs are not supported; write the program in millimetres (G21)",
    28: "reference-point return is not supported", 30: "reference-point return is not supported",
    40: "cutter compensation is not supported", 41: "cutter compensation is not supported",
    42: "cutter compensation is not supported",
    43: "tool length compensation is not supported", 44: "tool length compensation is not supported",
    49: "tool length compensation is not supported",
    52: "local coordinate systems are not supported", 53: "machine coordinates are not supported",
    54: "work offsets are not supported", 55: "work offsets are not supported",
    56: "work offsets are not supported", 57: "work offsets are not supported",
    58: "work offsets are not supported", 59: "work offsets are not supported",
    61: "exact-stop mode is not supported (corners always stop)",
    64: "continuous-path mode is not supported (tangent junctions are always crossed at speed)",
    92: "setting the coordinate system is not supported",
    93: "inverse-time feed is not supported; only feed per minute (G94)",
    95: "feed per revolution is not supported; only feed per minute (G94)",
}
_G_REASONS.update({code: "canned cycles are not supported" for code in (73, 74, 76, *range(80, 90))})
_M_REASONS = {0: "program stop is not supported", 1: "optional stop is not supported",
              3: "spindle commands have no meaning for the feed-axis simulation",
              4: "spindle commands have no meaning for the feed-axis simulation",
              5: "spindle commands have no meaning for the feed-axis simulation",
              6: "tool change is not supported", 7: "coolant commands are not supported",
              8: "coolant commands are not supported", 9: "coolant commands are not supported"}
_LETTER_REASONS = {
    "K": "K (centre along Z) is not supported: arcs are in the XY plane (G17), give I and J",
    "R": "arcs by radius (R) are not supported; give the centre with I and J",
    "S": "spindle speed has no meaning for the feed-axis simulation",
    "T": "tool selection is not supported", "H": "tool offsets are not supported",
    "D": "tool offsets are not supported", "O": "program numbers are not supported",
    "P": "parameters of dwells and cycles are not supported", "Q": "cycle parameters are not supported",
    "L": "repetitions and subprograms are not supported",
    "A": "rotary axes are not supported", "B": "rotary axes are not supported",
    "C": "rotary axes are not supported", "U": "secondary axes are not supported",
    "V": "secondary axes are not supported", "W": "secondary axes are not supported",
}


class GCodeError(ModelError):
    """A G-code program outside the supported subset, or invalid.

    The message reads ``"<source>: line <n>: word '<word>': <why>"``; ``line`` (1-based, physical
    line of the text) and ``word`` are also attributes.
    """

    def __init__(self, message: str, *, source: str | None = None, line: int | None = None,
                 word: str | None = None) -> None:
        self.line = line
        self.word = word
        super().__init__(f"word {word!r}: {message}" if word else message, source=source,
                         path=f"line {line}" if line is not None else None)

    def with_source(self, source: str) -> "GCodeError":
        """The same error, located in ``source``."""
        err = GCodeError("", source=source, line=self.line)
        err.message, err.word = self.message, self.word
        err.args = (err._format(),)
        return err


@dataclass
class _State:
    """The interpreter's modal state (positions in metres)."""

    programmed: np.ndarray          # where the program believes the tool is
    actual: np.ndarray              # where the last segment really ended (an arc ends on its circle)
    motion: tuple[int, str] | None = None    # (G code, the word as written)
    absolute: bool = True
    feed: float | None = None
    segments: list[Segment] = field(default_factory=list)
    feeds: list[float] = field(default_factory=list)


def _strip(text: str, err) -> str:
    """The line without its comments: ``( ... )`` and everything after ``;``."""
    out, depth = [], False
    for ch in text:
        if depth:
            depth = ch != ")"
        elif ch == "(":
            depth = True
        elif ch == ";":
            break
        else:
            out.append(ch)
    if depth:
        raise err("comment '(' is not closed on this line")
    return "".join(out).strip()


def _words(text: str, err) -> list[tuple[str, str]]:
    words, pos = [], 0
    while pos < len(text):
        if text[pos].isspace():
            pos += 1
            continue
        m = _WORD.match(text, pos)
        if not m:
            token = text[pos:].split()[0]
            raise err("cannot read this word: expected a letter followed by a number", token)
        words.append((m.group(1).upper(), m.group(2)))
        pos = m.end()
    return words


def _code(letter: str, number: str, err) -> int:
    value = float(number)
    if value != int(value) or value < 0:
        raise err(f"{letter}-code not supported; supported: {SUPPORTED_G}", letter + number)
    return int(value)


def _line_words(words, axes: str, err):
    """Sort one line's words into motion code, modes, feed, axis targets and centre offsets."""
    motion = None
    modes: dict[str, bool] = {}
    values: dict[str, float] = {}
    written: dict[str, str] = {}
    for letter, number in words:
        word = letter + number
        if letter == "G":
            code = _code(letter, number, err)
            if code in (0, 1, 2, 3):
                if motion is not None:
                    raise err("two motion codes on one line", word)
                motion = (code, word)
            elif code in (90, 91):
                if "absolute" in modes and modes["absolute"] != (code == 90):
                    raise err("G90 and G91 on one line", word)
                modes["absolute"] = code == 90
            elif code not in (17, 21, 94):
                why = _G_REASONS.get(code, "G-code not supported")
                raise err(f"{why}; supported: {SUPPORTED_G}", word)
        elif letter == "M":
            code = _code(letter, number, err)
            if code not in (2, 30):
                raise err(f"{_M_REASONS.get(code, 'M-code not supported')}; supported: M02 M30 (end of program)",
                          word)
            modes["end"] = True
        elif letter == "N":
            continue
        elif letter in "FXYZIJ":
            if letter in values:
                raise err(f"{letter} appears twice on one line", word)
            if letter == "Z" and "Z" not in axes:
                raise err(f"axis Z is not among the program's axes {axes!r}", word)
            values[letter] = float(number)
            written[letter] = word
            if letter == "F" and values["F"] <= 0:
                raise err("the feed must be > 0 (mm/min)", word)
        else:
            why = _LETTER_REASONS.get(letter, "unknown word")
            raise err(f"{why}; supported words: {SUPPORTED_WORDS}", word)
    return motion, modes, values, written


def _move(state: _State, motion: tuple[int, str], values: dict, written: dict, axes: str, rapid_feed,
          err) -> None:
    code, word = motion
    target = state.programmed.copy()
    for k, letter in enumerate(axes):
        if letter in values:
            target[k] = values[letter] * MM + (0.0 if state.absolute else state.programmed[k])
    if code == 0:
        if rapid_feed is None:
            raise err("G00 needs the machine's rapid rate: pass rapid_feed= (m/s) to parse_gcode", word)
        feed = rapid_feed
    else:
        if state.feed is None:
            raise err("no feed rate: program F (mm/min) before the first G01, G02 or G03", word)
        feed = state.feed
    segment: Segment
    if code in (0, 1):
        if "I" in values or "J" in values:
            raise err(f"I and J give an arc's centre and need G02 or G03 (G0{code} is active)",
                      written.get("I", written.get("J")))
        if np.linalg.norm(target - state.actual) == 0.0:
            state.programmed = target
            return
        segment = Line(tuple(state.actual), tuple(target))
    else:
        if "I" not in values and "J" not in values:
            raise err("an arc needs its centre: I and/or J (incremental from the start point, mm)", word)
        center = state.programmed[:2] + np.array([values.get("I", 0.0), values.get("J", 0.0)]) * MM
        try:
            segment = Arc(tuple(state.actual), tuple(target), tuple(center), clockwise=code == 2)
        except ModelError as exc:
            raise err(exc.message, word) from None
    state.segments.append(segment)
    state.feeds.append(feed)
    state.programmed = target
    state.actual = segment.point(np.array([segment.length]))[0]


def parse_gcode(text: str, source: str = "<string>", *, rapid_feed: float | None = None,
                start: Sequence[float] | None = None, axes: str = "XYZ") -> Path:
    """Read a G-code program (a small subset) into a :class:`~sicomat.motion.path.Path` with per-segment feeds.

    Supported: G00 (at ``rapid_feed``), G01, G02 (clockwise), G03 (counter-clockwise) with the centre
    given by I, J incremental from the arc's start point (in G90 and G91 alike; an arc with no X/Y
    is a full circle); G17 (the only plane), G90/G91 (absolute/incremental, G90 at start), G21 and
    G94 (millimetres, feed per minute: the only modes, accepted as no-ops); F (mm/min), X Y Z (mm),
    N line numbers, comments ``( ... )`` and after ``;``, blank lines, ``%`` lines, and M02/M30 (end
    of program: later lines are ignored). Modal codes and F persist across lines like a real CNC.
    Moves that do not move are skipped. Everything becomes SI: mm → m, mm/min → m/s.

    Parameters
    ----------
    text : str
        The program.
    source : str
        Name used in error messages, e.g. the file name.
    rapid_feed : float, optional
        Path velocity of G00 moves (m/s); a G00 without it is an error.
    start : sequence of float, optional
        Tool position (m) before the first line; default the origin.
    axes : {"XYZ", "XY"}
        Axes of the returned path; with ``"XY"`` a Z word is an error.

    Returns
    -------
    Path
        ``feeds`` in m/s, ``axis_names`` ``("x", "y", "z")`` or ``("x", "y")``.

    Raises
    ------
    GCodeError
        (a :class:`~sicomat.errors.ModelError`) on any word outside the subset, a feed move before any
        F, ``F0``, an arc whose start and end radii differ (see :class:`~sicomat.motion.path.Arc`), a helix,
        a program with no move; the message gives ``source``, the line number, the word and why.

    Examples
    --------
    >>> p = parse_gcode("G90 G17 G01 X10 F600\\nG03 X20 Y10 I0 J10\\nM30")
    >>> round(p.length * 1e3, 6), round(p.feeds[0], 6)
    (25.707963, 0.01)
    """
    axes = axes.upper()
    if axes not in ("XY", "XYZ"):
        raise ModelError("axes must be 'XY' or 'XYZ'", value=axes, has_value=True)
    if rapid_feed is not None and not (np.isfinite(rapid_feed) and rapid_feed > 0):
        raise ModelError("rapid_feed must be a finite number > 0 (m/s)", value=rapid_feed, has_value=True)
    origin = np.zeros(len(axes)) if start is None else np.asarray(start, dtype=float)
    if origin.shape != (len(axes),):
        raise ModelError(f"start must have {len(axes)} coordinates (m)", value=tuple(origin), has_value=True)
    state = _State(programmed=origin.copy(), actual=origin.copy())
    for number, raw in enumerate(text.splitlines(), start=1):
        def err(message: str, word: str | None = None, _line: int = number) -> GCodeError:
            return GCodeError(message, source=source, line=_line, word=word)

        body = _strip(raw, err)
        if not body or body == "%":
            continue
        motion, modes, values, written = _line_words(_words(body, err), axes, err)
        state.absolute = modes.get("absolute", state.absolute)
        if "F" in values:
            state.feed = values["F"] * MM_PER_MIN
        if motion is not None:
            state.motion = motion
        if any(k in values for k in axes + "IJ"):
            if state.motion is None:
                first = next(k for k in axes + "IJ" if k in values)
                raise err("no motion mode: program G00, G01, G02 or G03 first", written[first])
            _move(state, state.motion, values, written, axes, rapid_feed, err)
        elif motion is not None and motion[0] in (2, 3):
            raise err("an arc needs its centre: I and/or J (incremental from the start point, mm)", motion[1])
        if modes.get("end"):
            break
    if not state.segments:
        raise GCodeError("the program has no move", source=source)
    return Path(tuple(state.segments), feeds=tuple(state.feeds), axis_names=tuple(axes.lower()))
