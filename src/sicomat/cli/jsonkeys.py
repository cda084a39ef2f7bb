"""The unit rule of ``--json`` output: a key without a unit suffix holds an SI value (s, m, m/s, N, kg,
rad/s for an angular frequency); a suffix names a unit that is not SI (``_hz``, ``_deg``, ``_db``,
``_percent``, ``_mm_min``, ``_samples``).

Older keys that carry an SI suffix (``duration_s``, ``bandwidth_rad_s``, ...) are kept, deprecated,
and every JSON object gets the rule's name beside them (:data:`SI_NAMES`); the table is the one in
``docs/conventions.md``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["SI_NAMES", "with_si_names"]

#: deprecated key (SI value, SI unit in the name) -> the key of the rule, same value
SI_NAMES: dict[str, str] = {
    "duration_s": "duration",
    "step_s": "time_step",
    "wall_time_s": "wall_time",
    "equivalent_delay_s": "equivalent_delay",
    "delay_margin_s": "delay_margin",
    "delay_margins_s": "delay_margins",
    "gain_crossover_rad_s": "gain_crossover",
    "phase_crossover_rad_s": "phase_crossover",
    "modulus_margin_rad_s": "modulus_margin_omega",
    "bandwidth_rad_s": "bandwidth",
    "velocity_crossover_rad_s": "velocity_crossover",
    "position_crossover_rad_s": "position_crossover",
    "velocity_bandwidth_rad_s": "velocity_bandwidth",
    "position_bandwidth_rad_s": "position_bandwidth",
    "elapsed_s": "elapsed",
}


def with_si_names(value: Any) -> Any:
    """``value`` with, in every mapping, the rule's key inserted after each deprecated one (same value);
    a mapping that already has the rule's key keeps its own."""
    if isinstance(value, dict):
        out: dict[Any, Any] = {}
        for key, item in value.items():
            out[key] = with_si_names(item)
            twin = SI_NAMES.get(key)
            if twin is not None and twin not in value:
                out[twin] = out[key]
        return out
    if isinstance(value, (list, tuple)):
        return [with_si_names(v) for v in value]
    return value
