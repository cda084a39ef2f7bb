"""Servo-motor datasheet conventions and their consistency checks (kT ≈ √3·kE, T_mech, I0·kT = M0).

Vendors quote the same constants in different conventions; the converters below bring them to one
(SI, three-phase, sinusoidal, star-equivalent): torque constant ``kT`` in N·m per A **rms** of phase
current, back-EMF constant ``kE`` in V **line-to-line rms** per rad/s of the shaft (V·s/rad), resistance
**per phase** of the star equivalent. Sources and derivations in ``docs/components.md``.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass

from ..errors import ModelError

from .parts import CurrentBasis, EmfBasis, ResistanceBasis

__all__ = [
    "DATASHEET_TOLERANCE",
    "KE_PER",
    "KT_PER",
    "RESISTANCE_PER",
    "ConsistencyWarning",
    "back_emf_line_rms",
    "datasheet_warnings",
    "expected_torque_constant",
    "mechanical_time_constant",
    "per_krpm_to_per_rad_s",
    "phase_resistance",
    "torque_constant_rms",
]

# the datasheet conventions: the catalogue schema's words (one vocabulary for entries and checks)
KT_PER: tuple[str, ...] = typing.get_args(CurrentBasis)
KE_PER: tuple[str, ...] = typing.get_args(EmfBasis)
RESISTANCE_PER: tuple[str, ...] = typing.get_args(ResistanceBasis)
DATASHEET_TOLERANCE = 0.10
"""Relative tolerance of the checks: datasheet values carry ±10 % (Beckhoff AM8000 and Emerson
PACMotion manuals, "Definitions": "The data can have a tolerance of +/- 10 %")."""


def _choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ModelError(f"unknown {name} convention {value!r}; expected one of {', '.join(allowed)}",
                         path=name, value=value)


def torque_constant_rms(value: float, per: str = "rms") -> float:
    """kT per A rms from a datasheet's kT (``per = "rms"`` or ``"peak"`` of the phase current).

    ``T = kT_rms·I_rms = kT_pk·I_pk`` and ``I_pk = √2·I_rms`` (sinusoidal), so ``kT_rms = √2·kT_pk``.
    """
    _choice("torque_constant_per", per, KT_PER)
    return value * math.sqrt(2.0) if per == "peak" else value


def back_emf_line_rms(value: float, per: str = "line-to-line-rms") -> float:
    """kE line-to-line rms (V·s/rad) from a datasheet's kE in V·s/rad of the given convention.

    Star connection, sinusoidal EMF: ``E_ll = √3·E_ph`` and ``E_rms = E_pk/√2``. Convert V/1000 min⁻¹ first
    with :func:`per_krpm_to_per_rad_s`.
    """
    _choice("back_emf_per", per, KE_PER)
    line = value * math.sqrt(3.0) if per.startswith("phase") else value
    return line / math.sqrt(2.0) if per.endswith("peak") else line


def phase_resistance(value: float, per: str = "phase") -> float:
    """Resistance per phase of the star equivalent from a datasheet's value (``"phase"`` or ``"line-to-line"``:
    terminal to terminal). Star: two phases between terminals, ``R_ph = R_ll/2``; a delta winding measured
    terminal to terminal gives the same star equivalent ``R_ll/2``.
    """
    _choice("resistance_per", per, RESISTANCE_PER)
    return value / 2.0 if per == "line-to-line" else value


def per_krpm_to_per_rad_s(value: float) -> float:
    """A constant per 1000 min⁻¹ (e.g. kE in V/1000 rpm) to per rad/s: × 60/(2π·1000)."""
    return value * 60.0 / (2.0 * math.pi * 1000.0)


def expected_torque_constant(back_emf_constant: float) -> float:
    """kT (per A rms) that a kE (line-to-line rms, V·s/rad) implies: ``kT = √3·kE``.

    Power balance of the three phases at the q-axis current (no reluctance torque, no saturation, no iron
    loss): ``T·ω = 3·E_ph,rms·I_rms`` with ``E_ph,rms = kE_ll,rms·ω/√3``, so ``kT = 3·kE/√3 = √3·kE``
    (Siemens SIMOTICS and Beckhoff AM8000 configuration manuals state kT and kE in these conventions).
    """
    return math.sqrt(3.0) * back_emf_constant


def mechanical_time_constant(phase_resistance: float, rotor_inertia: float, torque_constant: float) -> float:
    """``T_mech = 3·R_ph·J/kT²`` (s), R per phase (star), kT per A rms (Siemens SIMOTICS configuration
    manuals, "Description of terms": T_mech = 3·R_ph·J_mot/kT²).

    It is ``J·R/k²`` of the equivalent DC motor: the copper loss ``3·R_ph·I_rms²`` at ``T = kT·I_rms`` is
    ``(3·R_ph/kT²)·T²``. Per A peak: ``1.5·R_ph·J/kT_pk²``; terminal resistance: ``1.5·R_ll·J/kT²``.
    """
    return 3.0 * phase_resistance * rotor_inertia / torque_constant**2


@dataclass(frozen=True)
class ConsistencyWarning:
    """One datasheet check that failed: ``ratio`` = stated / implied, outside ``1 ± tolerance``."""

    name: str
    ratio: float
    tolerance: float
    message: str


def _check(name: str, stated: float, implied: float, tolerance: float, what: str) -> ConsistencyWarning | None:
    ratio = stated / implied
    if abs(ratio - 1.0) <= tolerance:
        return None
    return ConsistencyWarning(name, ratio, tolerance,
                              f"{what}: stated/implied = {ratio:.3f}, outside 1 ± {tolerance:g} "
                              "(check the datasheet's conventions: per A rms or peak, line or phase)")


def datasheet_warnings(*, torque_constant: float, back_emf_constant: float | None = None,
                       phase_resistance: float | None = None, rotor_inertia: float | None = None,
                       mechanical_time_constant: float | None = None, stall_current: float | None = None,
                       stall_torque: float | None = None,
                       tolerance: float = DATASHEET_TOLERANCE) -> list[ConsistencyWarning]:
    """The consistency checks of a motor's datasheet values, in the conventions of this module (SI, kT per
    A rms, kE line-to-line rms in V·s/rad, R per phase); a check runs only when its values are given.

    - ``kT_stated / (√3·kE)``;
    - ``T_mech,stated / (3·R_ph·J/kT²)``;
    - ``M0 / (I0·kT)`` (stall torque, stall current rms).

    Returns one :class:`ConsistencyWarning` per ratio outside ``1 ± tolerance`` (empty when consistent).
    """
    if not tolerance > 0:
        raise ModelError(f"tolerance must be > 0, got {tolerance!r}", path="tolerance", value=tolerance)
    given = {"torque_constant": torque_constant, "back_emf_constant": back_emf_constant,
             "phase_resistance": phase_resistance, "rotor_inertia": rotor_inertia,
             "mechanical_time_constant": mechanical_time_constant, "stall_current": stall_current,
             "stall_torque": stall_torque}
    for key, value in given.items():
        if value is not None and not value > 0:
            raise ModelError(f"{key} must be > 0 (SI), got {value!r}", path=key, value=value)
    found: list[ConsistencyWarning | None] = []
    if back_emf_constant is not None:
        found.append(_check("kT_kE", torque_constant, expected_torque_constant(back_emf_constant), tolerance,
                            "torque constant against √3 × back-EMF constant"))
    if mechanical_time_constant is not None and phase_resistance is not None and rotor_inertia is not None:
        implied = 3.0 * phase_resistance * rotor_inertia / torque_constant**2
        found.append(_check("T_mech", mechanical_time_constant, implied, tolerance,
                            "mechanical time constant against 3·R_ph·J/kT²"))
    if stall_current is not None and stall_torque is not None:
        found.append(_check("M0", stall_torque, stall_current * torque_constant, tolerance,
                            "stall torque against stall current × torque constant"))
    return [w for w in found if w is not None]
