"""Discrete blocks of the CNC controller (paper II.E): PI / IP velocity law, filters, differencing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..description.servo import FilterSpec

__all__ = ["DiscreteSS", "velocity_law", "filter_block", "difference_block", "continuous_filter"]


@dataclass(frozen=True, eq=False)
class DiscreteSS:
    """``x+ = A x + B u``, ``y = C x + D u`` at one sample period."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray


def velocity_law(structure: str, kp: float, ti: float, period: float, tracking_time: float | None) -> DiscreteSS:
    """The velocity controller as a discrete block with state ``z`` = integral action (N or N·m).

    Inputs ``(e, e_int, u_sat − u, v_meas)``: the velocity error, the error that feeds the
    integrator (gated by clamping anti-windup), the saturation excess (back-calculation with
    tracking time ``tracking_time``; ``None`` disables it) and the measured velocity.

    - PI: ``u = Kp e + z``;  IP: ``u = z − Kp v_meas`` (proportional action on the measurement only).
    - ``z+ = z + (Kp T / Ti) e_int + (T / Tt)(u_sat − u)`` (forward Euler, as CNCs implement it).
    """
    back = period / tracking_time if tracking_time else 0.0
    A = np.array([[1.0]])
    B = np.array([[0.0, kp * period / ti, back, 0.0]])
    C = np.array([[1.0]])
    D = np.array([[kp, 0.0, 0.0, 0.0]]) if structure == "P-PI" else np.array([[0.0, 0.0, 0.0, -kp]])
    return DiscreteSS(A, B, C, D)


def difference_block(period: float) -> DiscreteSS:
    """Velocity from the sampled position: ``v_k = (p_k − p_{k−1}) / T``."""
    return DiscreteSS(np.array([[0.0]]), np.array([[1.0]]), np.array([[-1.0 / period]]),
                      np.array([[1.0 / period]]))


def continuous_filter(spec: FilterSpec, prewarp_period: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (descending powers of s) of a filter; optionally prewarped."""
    w = 2 * np.pi * spec.frequency
    if prewarp_period:
        w = 2.0 / prewarp_period * np.tan(w * prewarp_period / 2.0)
    if spec.type == "low-pass":
        return np.array([w * w]), np.array([1.0, 2 * spec.damping * w, w * w])
    zeta_p = spec.width / 2.0
    zeta_z = spec.depth * zeta_p
    return np.array([1.0, 2 * zeta_z * w, w * w]), np.array([1.0, 2 * zeta_p * w, w * w])


def filter_block(spec: FilterSpec, period: float) -> DiscreteSS:
    """The filter discretised with Tustin's transform, prewarped at its frequency.

    Raises ``ValueError`` when the frequency is at or above the Nyquist frequency.
    """
    if spec.frequency >= 0.5 / period:
        raise ValueError(f"filter frequency {spec.frequency:g} Hz is not below the Nyquist frequency "
                         f"{0.5 / period:g} Hz of its loop")
    import scipy.signal

    num, den = continuous_filter(spec, prewarp_period=period)
    numd, dend, _ = scipy.signal.cont2discrete((num, den), period, method="bilinear")
    A, B, C, D = scipy.signal.tf2ss(np.ravel(numd), np.ravel(dend))
    return DiscreteSS(A, B, C, D)
