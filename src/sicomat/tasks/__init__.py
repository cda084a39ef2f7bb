"""The verbs that the command line (and later the web workbench and studies) share: options in,
result objects or JSON payloads out."""

from .analysis import bode_payload, margins_payload, write_tuned, response_verdict, verdict_subject
from .reduce import (reduce_command, write_reduced, parse_band, parse_keep, parse_signals, default_transfer, default_band, METHODS)
from .simulate import choose_profile, simulate_payload, diverged_payload, check_magnification, STEP_FIGURES

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
    "check_magnification",
    "STEP_FIGURES",
]
