"""Frequency responses and margins of one loop of coupled axes with the other loops closed.

The loop of axis A is broken where the analysis of one axis breaks it (:mod:`sicomat.frequency.loops`):
the velocity loop at its error (the loop gain ``L_v``, A's position loop open), the position loop at its
error (``L_p``, around A's closed velocity loop lifted to Tp). The other axes' loops are closed on the
coupled mechanics, their setpoints held (:mod:`sicomat.servo.coupled_linear`: each velocity loop, and each
position loop that runs at the velocity period, in the sampled plant; a slower position loop closed after
lifting in A's position-loop analysis and open in its velocity-loop one). The digital effects are those of
one axis, exactly: :class:`CoupledLoopAnalysis` *is* a :class:`~sicomat.frequency.loops.LoopAnalysis` on
that larger plant, so every formula (the factors of ``L_v``, the lifting, the static gains, the poles of
the stability verdict) is the single-axis one.

Examples
--------
>>> import sicomat
>>> from sicomat.servo.coupled import robot_coupled_loop
>>> coupled = robot_coupled_loop(sicomat.load_model("examples/xy_elastic.toml"))
>>> an = coupled_analysis(coupled, "X")
>>> frf = an.response("velocity-open")
>>> bool(frf.omega[-1] < 3.1416 / coupled.base_period)
True
"""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from ..servo.coupled_linear import CoupledAxisModel, closed_partners, coupled_axis_model
from .loops import LOOPS, LoopAnalysis, default_omega

if TYPE_CHECKING:  # pragma: no cover
    from ..lti.response import FrequencyResponse
    from ..servo.coupled import CoupledLoop

__all__ = ["COUPLED_LOOPS", "CoupledLoopAnalysis", "coupled_analysis", "coupled_omega", "closed_partners"]

COUPLED_LOOPS = ("velocity-open", "velocity-closed", "position-open", "position-closed", "following-error")
"""The transfers of :data:`~sicomat.frequency.loops.LOOPS` built with the other loops closed (the plant, the
compliance and the disturbance response are those of one axis's mechanics)."""


class CoupledLoopAnalysis(LoopAnalysis, CoupledAxisModel):
    """The single-axis analysis of axis ``loop.axis`` on the sampled plant with the other axes' loops
    closed (:class:`~sicomat.servo.coupled_linear.CoupledAxisModel`); build it with :func:`coupled_analysis`.
    """

    def response(self, which: str, omega: np.ndarray | None = None, *, Kp: float | None = None,
                 Ti: float | None = None, Kv: float | None = None) -> "FrequencyResponse":
        """The transfer ``which`` (one of :data:`COUPLED_LOOPS`) with the other loops closed, on
        :func:`coupled_omega`'s grid unless ``omega`` is given."""
        if which in LOOPS and which not in COUPLED_LOOPS:
            raise ModelError(f"the {which!r} response is not built for coupled loops (it is one axis's mechanics "
                             f"alone); expected one of {', '.join(COUPLED_LOOPS)}", path="which", value=which)
        if omega is None and which in COUPLED_LOOPS:
            omega = coupled_omega(self, which)
        frf = super().response(which, omega, Kp=Kp, Ti=Ti, Kv=Kv)
        frf.info["coupled"] = True
        return frf

    def resonances(self) -> list[tuple[float, float]]:
        """``(ω rad/s, damping ratio)`` of the flexible modes of the coupled mechanics and of the lightly
        damped poles of the sampled plant with the other loops closed (ω in the first Nyquist band)."""
        assert self.coupled is not None
        out = [(2 * np.pi * mode.frequency_hz, mode.damping_ratio)
               for mode in self.coupled.mechanics.modes().modes if not mode.rigid]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.log(np.linalg.eigvals(self.Phi).astype(complex)) / self.loop.controller.velocity_period
        for pole in s[(s.imag > 0) & np.isfinite(s)]:
            out.append((float(pole.imag), float(-pole.real / abs(pole))))
        return out


def coupled_analysis(coupled: "CoupledLoop", axis: str) -> CoupledLoopAnalysis:
    """The analysis of ``axis``'s loops with the other axes of ``coupled`` closed.

    Raises
    ------
    ModelError
        No such axis, a continuous position loop; the position loop's analysis (not this call) refuses
        slow position loops at other periods than the axis's.
    """
    model = coupled_axis_model(coupled, axis)
    return CoupledLoopAnalysis(**{f.name: getattr(model, f.name) for f in fields(model)})


def coupled_omega(an: CoupledLoopAnalysis, which: str, n: int = 2000) -> np.ndarray:
    """The grid of :func:`~sicomat.frequency.loops.default_omega` for axis ``an.loop``, refined around the
    resonances of the coupled loop (:meth:`CoupledLoopAnalysis.resonances`)."""
    return default_omega(an.loop, which, n, resonances=an.resonances())
