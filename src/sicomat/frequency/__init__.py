"""Frequency analysis of a servo loop (stage 4): sampled and analog loop responses, margins and
bandwidth."""

from .loops import LOOPS, LoopAnalysis, loop_response, default_omega
from .margins import (Margins, stability_margins, closed_loop, sensitivity, closed_loop_bandwidth, margins_warnings)

__all__ = [
    "LOOPS",
    "LoopAnalysis",
    "loop_response",
    "default_omega",
    "Margins",
    "stability_margins",
    "closed_loop",
    "sensitivity",
    "closed_loop_bandwidth",
    "margins_warnings",
]
