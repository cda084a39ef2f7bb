"""Motion: setpoint profiles, S-curves, paths and their interpolation, G-code, contour error and the
ISO 230-4 circle evaluation (kinematics: no simulation here)."""

from .circle import CircleResult, ReversalSpike, evaluate_circle, least_squares_circle
from .contour import contour_error, segment_distance
from .gcode import GCodeError, parse_gcode, SUPPORTED_G, SUPPORTED_WORDS
from .interpolator import AxisSetpoint, PathSamples, interpolate
from .path import Line, Arc, Path, CircleTestPath, circle_test_path, RADIUS_RTOL, RADIUS_ATOL
from .setpoints import (SetpointProfile, Profile, profile_from_spec, lowers, step_profile, ramp_profile, trapezoid_profile)
from .trajectory import JerkProfile, scurve_profile, scurve_sequence, scurve_durations

__all__ = [
    "CircleResult",
    "ReversalSpike",
    "evaluate_circle",
    "least_squares_circle",
    "contour_error",
    "segment_distance",
    "GCodeError",
    "parse_gcode",
    "SUPPORTED_G",
    "SUPPORTED_WORDS",
    "Line",
    "Arc",
    "Path",
    "PathSamples",
    "AxisSetpoint",
    "CircleTestPath",
    "interpolate",
    "circle_test_path",
    "RADIUS_RTOL",
    "RADIUS_ATOL",
    "SetpointProfile",
    "Profile",
    "profile_from_spec",
    "lowers",
    "step_profile",
    "ramp_profile",
    "trapezoid_profile",
    "JerkProfile",
    "scurve_profile",
    "scurve_sequence",
    "scurve_durations",
]
