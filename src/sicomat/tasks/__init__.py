"""The verbs that the command line (and later the web workbench and studies) share: parameters in,
result objects or JSON payloads out. No command-line option names here: errors are located at the
parameter (``ModelError.path``), and the CLI maps each to its option (``sicomat.cli._common.OPTIONS``)."""

from .analysis import bode_payload, margins_payload, write_tuned, response_verdict, verdict_subject
from .reduce import (reduce_command, write_reduced, parse_band, parse_keep, parse_signals, default_transfer, default_band, METHODS)
from .simulate import choose_profile, simulate_payload, diverged_payload, simulate_gcode, STEP_FIGURES
from .modemap import ModeMap, mode_map, machine_at
from .workspace_map import WorkspaceModeMap, workspace_mode_map
from .tune_positions import StrokeTuning, PositionMargins, tune_over_stroke

__all__ = [
    "bode_payload",
    "margins_payload",
    "write_tuned",
    "response_verdict",
    "verdict_subject",
    "reduce_command",
    "write_reduced",
    "parse_band",
    "parse_keep",
    "parse_signals",
    "default_transfer",
    "default_band",
    "METHODS",
    "choose_profile",
    "simulate_payload",
    "diverged_payload",
    "simulate_gcode",
    "STEP_FIGURES",
    "ModeMap",
    "mode_map",
    "machine_at",
    "WorkspaceModeMap",
    "workspace_mode_map",
    "StrokeTuning",
    "PositionMargins",
    "tune_over_stroke",
]
