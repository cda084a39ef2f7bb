"""The electric drive (paper II.D): q-axis current loop as a first-order lag, current and voltage limits."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..description.servo import DriveSpec

__all__ = ["DriveModel", "drive_model"]


@dataclass(frozen=True)
class DriveModel:
    """A drive lowered to numbers: ``τ di/dt = i_ref − i``, effort ``= Kt i`` on the actuator.

    ``i_peak``, ``u_max``, ``resistance``, ``ke`` and ``wl`` are the parameters of the
    speed-dependent current limit (``wl`` = electrical speed per mechanical speed × inductance).
    """

    tau: float
    kt: float
    i_peak: float
    u_max: float
    resistance: float
    ke: float
    wl: float

    def current_bounds(self, speed: float) -> tuple[float, float]:
        """Admissible current interval at a speed (rad/s or m/s): peak current ∩ voltage circle.

        Solves ``(R i + Ke w)² + (wl w i)² ≤ U²`` for ``i`` (python reference of the kernel's op).

        Examples
        --------
        >>> DriveModel(1e-3, 1.0, 10.0, 100.0, 2.0, 1.0, 0.0).current_bounds(60.0)
        (-10.0, 10.0)
        >>> DriveModel(1e-3, 1.0, 100.0, 100.0, 2.0, 1.0, 0.0).current_bounds(60.0)
        (-80.0, 20.0)
        """
        lo, hi = -self.i_peak, self.i_peak
        if np.isfinite(self.u_max):
            a = self.resistance ** 2 + (self.wl * speed) ** 2
            b = 2.0 * self.resistance * self.ke * speed
            c = (self.ke * speed) ** 2 - self.u_max ** 2
            if a > 0:
                disc = b * b - 4 * a * c
                if disc < 0:  # the back-EMF alone exceeds the supply: brake as hard as possible
                    i = -b / (2 * a)
                    return float(np.clip(i, lo, hi)), float(np.clip(i, lo, hi))
                root = np.sqrt(disc)
                lo, hi = max(lo, (-b - root) / (2 * a)), min(hi, (-b + root) / (2 * a))
        return float(lo), float(hi)


def drive_model(spec: DriveSpec, rotational: bool) -> DriveModel:
    """Lower a drive description; ``rotational`` says whether the actuator drives an inertia."""
    if spec.pole_pairs is not None:
        electrical = float(spec.pole_pairs)
    elif spec.pole_pitch is not None:
        electrical = np.pi / spec.pole_pitch
    else:
        electrical = 0.0
    return DriveModel(
        tau=spec.tau, kt=spec.force_constant,
        i_peak=spec.peak_current if spec.peak_current is not None else np.inf,
        u_max=spec.supply_voltage if spec.supply_voltage is not None else np.inf,
        resistance=spec.resistance, ke=spec.ke, wl=electrical * spec.inductance)
