"""The electric drive lowered to numbers (paper II.D): the current loop's lag, current and voltage limits.

The drive kinds (``type`` in the model file) and their lowering are in :mod:`sicomat.servo.blocks`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DriveModel"]


@dataclass(frozen=True)
class DriveModel:
    """A drive lowered to numbers: ``τ di/dt = i_ref − i``, effort ``= Kt i`` on the actuator.

    ``i_peak``, ``u_max``, ``resistance``, ``ke`` and ``wl`` are the parameters of the
    speed-dependent current limit (``wl`` = electrical speed per mechanical speed × inductance);
    ``kind`` the drive's ``type`` (:data:`~sicomat.servo.blocks.DRIVES`).
    """

    tau: float
    kt: float
    i_peak: float
    u_max: float
    resistance: float
    ke: float
    wl: float
    kind: str = "first-order"

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
