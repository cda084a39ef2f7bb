"""sicomat.motion.gcode.parse_gcode: the supported subset, modal behaviour, units, and one clear error per fault."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from sicomat.errors import ModelError
from sicomat.motion.gcode import GCodeError, parse_gcode
from sicomat.motion import Arc, Line

PROGRAM = """%
(circle test, R 50 mm)
N10 G17 G21 G90 G94
N20 G00 X50 Y0           ; rapid to the start
N30 G01 X60 F2000
N40 G03 X60 Y0 I-60 J0   (full circle, counter-clockwise)
N50 G91 G02 X-10 Y-10 I-10
N60 Y5                   ; modal G02? no: I/J missing -> see test below
M30
G01 X999 (ignored after M30)
%
"""


def _program_without_line_60():
    return PROGRAM.replace("N60 Y5                   ; modal G02? no: I/J missing -> see test below\n", "")


def test_program_geometry_feeds_and_units():
    path = parse_gcode(_program_without_line_60(), "circle.nc", rapid_feed=0.5)
    kinds = [type(s) for s in path.segments]
    assert kinds == [Line, Line, Arc, Arc]
    rapid, feed_line, circle, quarter = path.segments
    # G-code values in mm scaled to m: one rounding each (default rtol 1e-7 is slack; 1e-15 absolute where
    # stated, 1e-12 for sums of lengths with π); centres and sweeps from atan2 of exact points: <= 1 ulp
    assert_allclose(rapid.end, (0.05, 0.0, 0.0))
    assert_allclose(feed_line.end, (0.06, 0.0, 0.0))
    assert_allclose(circle.sweep, 2 * math.pi) and not circle.clockwise
    assert_allclose(circle.radius, 0.06)
    # G91 G02 X-10 Y-10 I-10 from (60, 0): centre (50, 0), end (50, -10): clockwise quarter
    assert quarter.clockwise and quarter.center[:2] == pytest.approx((0.05, 0.0))
    assert_allclose(quarter.sweep, -math.pi / 2, rtol=1e-12)
    assert_allclose(quarter.end, (0.05, -0.01, 0.0), atol=1e-15)
    assert_allclose(path.feeds, [0.5, 2.0 / 60, 2.0 / 60, 2.0 / 60], rtol=1e-15)   # F2000 mm/min
    assert_allclose(path.length, 0.05 + 0.01 + 2 * math.pi * 0.06 + math.pi / 2 * 0.01, rtol=1e-12)
    assert path.axis_names == ("x", "y", "z")


def test_modal_codes_persist_and_incremental_moves():
    path = parse_gcode("G91 G01 X10 F600\nY10\nX-10\nG90 X0 Y0", axes="XY")
    # incremental moves: sums of scaled mm, a few roundings (pytest.approx's default 1e-6 is slack)
    assert [s.end for s in path.segments] == [
        pytest.approx((0.01, 0.0)), pytest.approx((0.01, 0.01)), pytest.approx((0.0, 0.01)),
        pytest.approx((0.0, 0.0))]
    assert path.feeds == pytest.approx([0.01] * 4)
    assert path.dimension == 2


def test_start_position_zero_moves_and_lowercase():
    path = parse_gcode("g1 x0 y0 f100\ng1 x5 y0 z0\nn5 g02 x5 y0 i0 j-5", start=(0.0, 0.0, 0.002))
    # line 1 does not move (skipped); line 2 moves from the start; the arc is a full circle CW
    assert len(path.segments) == 2
    assert path.segments[0].start == (0.0, 0.0, 0.002) and path.segments[0].end == (0.005, 0.0, 0.0)
    # a full circle: atan2 of exact points, pytest.approx default
    assert path.segments[1].sweep == pytest.approx(-2 * math.pi)
    assert path.segments[1].center == pytest.approx((0.005, -0.005, 0.0))


def where(text, rapid_feed=None, axes="XYZ"):
    with pytest.raises(GCodeError) as info:
        parse_gcode(text, "program.nc", rapid_feed=rapid_feed, axes=axes)
    return info.value


def test_unknown_word_message_gives_source_line_word_and_why():
    err = where("G17 G90\nG01 X1 F100\n\n(comment)\nG00 X0\nG01 Y1\nG41 X2 Y2\n", rapid_feed=1.0)
    assert str(err) == ("program.nc: line 7: word 'G41': cutter compensation is not supported; "
                        "supported: G00 G01 G02 G03 G17 G90 G91")
    assert err.line == 7 and err.word == "G41"
    assert isinstance(err, ModelError) and isinstance(err, ValueError)


@pytest.mark.parametrize("text, line, word, match", [
    ("G01 X10\nF100", 1, "G01", "no feed rate: program F"),
    ("G90\nG02 X10 Y10 I5", 2, "G02", "no feed rate"),
    ("G01 X1 F0", 1, "F0", "the feed must be > 0"),
    ("G01 X1 F-100", 1, "F-100", "the feed must be > 0"),
    ("F100\nG01 X10\nG03 X20 Y10 I0 J10.1", 3, "G03", "arc start and end radii differ by"),
    ("F100\nG02 X10 Y10 Z5 I5 J5", 2, "G02", "helical arcs are not supported"),
    ("F100\nG02 X10 Y0", 2, "G02", "an arc needs its centre: I and/or J"),
    ("F100\nG01 X10 I5", 2, "I5", "need G02 or G03"),
    ("G00 X10", 1, "G00", "pass rapid_feed="),
    ("X10 Y10", 1, "X10", "no motion mode"),
    ("G18 G02 X1 I1", 1, "G18", "only the XY plane"),
    ("G20", 1, "G20", "inch programs are not supported"),
    ("G01 G02 X1", 1, "G02", "two motion codes"),
    ("G01 X1 X2 F100", 1, "X2", "X appears twice"),
    ("F100 G02 X10 R5", 1, "R5", "arcs by radius"),
    ("F100 G02 X10 I5 K0", 1, "K0", "K (centre along Z)"),
    ("M03 S1000", 1, "M03", "spindle commands"),
    ("T1 M06", 1, "T1", "tool selection"),
    ("G01 X1 F100 E5", 1, "E5", "unknown word; supported words: G F X Y Z I J N, M02 M30"),
    ("G65 P9000", 1, "G65", "G-code not supported; supported: G00 G01 G02 G03 G17 G90 G91"),
    ("G1.5", 1, "G1.5", "G-code not supported"),
    ("G01 X#1", 1, "X#1", "cannot read this word"),
    ("G01 X1 (no end", 1, None, "comment '(' is not closed"),
])
def test_errors_name_line_word_and_reason(text, line, word, match):
    err = where(text)
    assert err.line == line and err.word == word
    assert str(err).startswith(f"program.nc: line {line}: " + (f"word '{word}': " if word else ""))
    assert match in str(err)


def test_z_word_rejected_for_a_two_axis_program_and_empty_program():
    assert "axis Z is not among" in str(where("G01 X1 Z1 F100", axes="XY"))
    err = where("%\n(nothing)\nG90 G17\nM30\n")
    assert str(err) == "program.nc: the program has no move"


def test_modal_arc_without_centre_on_a_later_line():
    err = where(PROGRAM, rapid_feed=0.5)
    assert err.line == 8 and "an arc needs its centre" in str(err)


def test_with_source_keeps_the_location():
    err = where("G41").with_source("other.nc")
    assert isinstance(err, GCodeError)
    assert str(err).startswith("other.nc: line 1: word 'G41': cutter compensation")


def test_bad_options():
    with pytest.raises(ModelError, match="rapid_feed must be"):
        parse_gcode("G00 X1", rapid_feed=0.0)
    with pytest.raises(ModelError, match="axes must be"):
        parse_gcode("G00 X1", axes="XZ")
    with pytest.raises(ModelError, match="start must have 2 coordinates"):
        parse_gcode("G00 X1", axes="XY", start=(0, 0, 0))
