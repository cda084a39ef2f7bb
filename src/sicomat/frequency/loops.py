"""Frequency responses of the servo loops with the digital effects exact (paper III.B, Figs. 6, 9, 10).

The velocity loop is a sampled LTI loop at its period Tv: the plant (mechanics + current loop) is
ZOH-discretised exactly and evaluated at ``z = e^{jωTv}``; the controller, the filters, the
differencing and the computation delays are rational in z. The position loop runs at Tp = Np·Tv:
the closed velocity loop, with its command held over Np velocity periods and the position sampled
every Tp, is an exact LTI system at Tp (lifting: ``A^Np``, ``Σ A^i B``), evaluated at ``z = e^{jωTp}``.
Each loop is evaluated up to its own Nyquist frequency. The dynamic compliance (a continuous
disturbance against a sampled controller) uses the fundamental-band approximation: each digital
controller at ``e^{jωT}`` with the hold's ``(1 − e^{−jωT})/(jωT)``; aliasing is neglected.

A continuous (analog) velocity loop is evaluated at ``s = jω`` (its filters unwarped, a position
sensor read for velocity differentiated); a sampled position loop around it is the exact ZOH of the
continuous closed velocity loop at Tp; a continuous position loop is evaluated at ``s = jω`` too.
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, Iterable

import numpy as np

from ..servo.blocks import linear_law
from ..servo.controller import DiscreteSS, continuous_filter
from ..servo.linear import LoopModel
from ..errors import ModelError
from ..lti.response import FrequencyResponse, static_gain, transfer_at

if TYPE_CHECKING:  # pragma: no cover
    from ..servo.loop import ServoLoop

__all__ = ["LOOPS", "LoopAnalysis", "loop_response", "default_omega"]

LOOPS = ("plant", "velocity-open", "velocity-closed", "position-open", "position-closed",
         "following-error", "compliance", "disturbance")


def default_omega(loop: "ServoLoop", which: str, n: int = 2000, *,
                  resonances: "Iterable[tuple[float, float]] | None" = None) -> np.ndarray:
    """A log grid from 0.5 Hz to just below the Nyquist frequency of the loop ``which`` belongs to,
    refined around every lightly damped mode of the mechanics (±50 half-power bandwidths), so that
    resonance peaks and their loops on a Nichols chart are resolved whatever their damping.

    ``resonances``: the ``(ω rad/s, damping ratio)`` of the resonances to refine around, instead of the
    flexible modes of ``loop.mechanics`` (coupled loops: those of the coupled mechanics and of the
    loop with the other axes closed)."""
    ctrl = loop.controller
    period: float | None
    if which.startswith(("position", "following")) and ctrl.position_loop == "discrete":
        period = ctrl.position_period
    else:
        period = ctrl.velocity_period if ctrl.velocity_loop == "discrete" else None
    # a continuous loop: up to 20 times the current loop's bandwidth (at most 100 kHz)
    top = 0.999 * np.pi / period if period else min(20.0 / loop.drive.tau, 2 * np.pi * 1e5)
    low = 2 * np.pi * 0.5
    grid = [np.logspace(np.log10(low), np.log10(top), n)]
    offsets = np.concatenate([-np.geomspace(50, 0.02, 24), [0.0], np.geomspace(0.02, 50, 24)])
    if resonances is None:
        resonances = [(2 * np.pi * mode.frequency_hz, mode.damping_ratio)
                      for mode in loop.mechanics.modes().modes if not mode.rigid]
    for w, damping in resonances:
        if damping >= 0.2:
            continue
        half = w * max(damping, 1e-7)
        ws = 2 * np.pi / ctrl.velocity_period
        folded = abs(w - ws * np.round(w / ws))  # a sampled loop sees a mode above Nyquist aliased
        for centre in ({w, folded} if ctrl.velocity_loop == "discrete" else {w}):
            grid.append(centre + offsets * half)
    omega = np.unique(np.concatenate(grid))
    return omega[(omega >= low) & (omega <= top)]


def _ss_response(ss: DiscreteSS, z: np.ndarray) -> np.ndarray:
    """SISO response of a small discrete block at points z."""
    return transfer_at(ss.A, ss.B, ss.C, ss.D, z, discrete=True)[0, 0]


class LoopAnalysis(LoopModel):
    """Pieces of a loop that do not depend on the gains, computed once (for tuning loops); the
    loop's linear model (:class:`~sicomat.servo.linear.LoopModel`) and its frequency responses.

    Use :meth:`response` for any transfer, with the loop's gains or others.
    """

    # ------------------------------------------------------------------ velocity loop (rate Tv)
    def velocity_law_response(self, omega: np.ndarray, Kp: float, Ti: float, *, error_form: bool = False
                              ) -> tuple[np.ndarray, np.ndarray]:
        """The velocity law's lowering (:func:`~sicomat.servo.blocks.linear_law`) at
        ``z = e^{jωTv}`` (``s = jω`` analog): its feedthrough and its dynamic part from the error
        (``error_form``: the error with the measurement folded in, as the loop gain sees it)."""
        law = linear_law(self.loop, Kp, Ti, error_form=error_form)
        point = 1j * omega if self.analog else np.exp(1j * omega * self.loop.controller.velocity_period)
        if law.A.shape[0] == 1:     # one state (a PI's integrator): C B / (z − a), one division per point
            dynamic = law.C[0, 0] * law.B[0, 0] / (point - law.A[0, 0])
        else:
            dynamic = _ss_response(DiscreteSS(law.A, law.B[:, :1], law.C, np.zeros((1, 1))), point)
        return np.full(omega.shape, law.D[0, 0], dtype=complex), dynamic

    def velocity_factors(self, omega: np.ndarray, Kp: float, Ti: float):
        """``(C_p, C_i, A, M)`` at ``z = e^{jωTv}``: the feedthrough (proportional) and dynamic
        (integral) parts of the velocity law as the loop gain sees it, actuation (current filters,
        delay, 1/Kt, plant to the velocity sensor) and the measurement (differencing, conversion,
        filter), so that ``L_v = (C_p + C_i)·A·M``; at ``s = jω`` for an analog velocity loop."""
        loop, ctrl = self.loop, self.loop.controller
        integral: np.ndarray
        if self.analog:
            s = 1j * omega
            plant = _continuous_response(self.Phi, self.Gamma, self.c_vel, s)
            actuation: np.ndarray = np.full(s.shape, 1.0 / loop.drive.kt, dtype=complex)
            for spec in ctrl.current_filters:
                actuation = actuation * _tf_at(spec, s)
        else:
            T = ctrl.velocity_period
            z = np.exp(1j * omega * T)
            plant = _discrete_response(self.Phi, self.Gamma, self.c_vel, z)
            actuation = z ** (-ctrl.velocity_delay) / loop.drive.kt
            for block in self._blocks()[0]:
                actuation = actuation * _ss_response(block, z)
        proportional, integral = self.velocity_law_response(omega, Kp, Ti, error_form=True)
        return proportional, integral, actuation, plant * self._measurement(omega)

    def velocity_forward(self, omega: np.ndarray, Kp: float, Ti: float) -> np.ndarray:
        """The velocity law from the velocity command to the effort (``C_e``; ``C_p + C_i`` for a
        law driven by the error alone, ``C_i`` for P-IP)."""
        feedthrough, dynamic = self.velocity_law_response(omega, Kp, Ti)
        return feedthrough + dynamic if np.any(feedthrough) else dynamic

    def _measurement(self, omega: np.ndarray) -> np.ndarray:
        """Velocity-sensor reading → measured velocity: the conversion to axis units, the
        differencing of a position sensor (its exact derivative in an analog loop) and the velocity
        filter."""
        ctrl = self.loop.controller
        measure = np.full(omega.shape, 1.0 / self.loop.velocity_gain, dtype=complex)
        if self.analog:
            s = 1j * omega
            if self.differenced:
                measure = measure * s
            if ctrl.velocity_filter is not None:
                measure = measure * _tf_at(ctrl.velocity_filter, s)
            return measure
        T = ctrl.velocity_period
        z = np.exp(1j * omega * T)
        if self.differenced:
            measure = measure * (1.0 - 1.0 / z) / T
        velocity = self._blocks()[1]
        if velocity is not None:
            measure = measure * _ss_response(velocity, z)
        return measure

    # ------------------------------------------------------------------ position loop (rate Tp)
    def position_lifted(self, omega: np.ndarray, Kp: float, Ti: float) -> tuple[np.ndarray, np.ndarray]:
        """Lifted transfers at ``z = e^{jωTp}`` from the velocity command and from the feedforward
        effort (both held over Tp) to the measured position (sampled at Tp)."""
        Ap, Bp, C = self.position_model(Kp, Ti)
        z = np.exp(1j * omega * self.loop.controller.position_period)
        H = transfer_at(Ap, Bp, C[:1], points=z, discrete=True)
        return H[0, 0], H[0, 1]

    def position_continuous(self, omega: np.ndarray, Kp: float, Ti: float) -> tuple[np.ndarray, np.ndarray]:
        """For a continuous position loop: the transfers at ``s = jω`` from the velocity command
        and from the feedforward effort to the measured position, through the analog velocity loop."""
        A, B, C = self.analog_closed_loop(Kp, Ti)
        H = transfer_at(A, B, C[:1], points=1j * np.asarray(omega, dtype=float))
        return H[0, 0], H[0, 1]

    def closed_loop_static_gain(self, which: str, Kp: float | None = None, Ti: float | None = None,
                                Kv: float | None = None) -> float:
        """The exact static gain ``T(0)`` of ``T = L/(1 + L)`` for the loop gain ``which``
        (``"velocity-open"`` or ``"position-open"``), with the loop's gains or the ones given.

        The closed loop's state space is evaluated at ``z = 1`` (``s = 0`` for a continuous loop) by
        :func:`~sicomat.lti.response.static_gain`, which takes the exact limit through the removable
        pole of the rigid-body drift. The velocity loop: ``L_v`` sees the law from the error only
        (the same for P-PI and P-IP), so ``T_v`` is the loop with the law in that form. The position loop: ``Kv·z^{−d}·g_v``
        around the lifted (or analog) velocity loop, delay line included; a continuous position
        loop's delay ``e^{−s d Tp}`` is 1 at ``s = 0``. With an integrator in the loop the value is
        1 to round-off (it is computed, not assumed).
        """
        loop, ctrl = self.loop, self.loop.controller
        Kp = loop.Kp if Kp is None else Kp
        Ti = loop.Ti if Ti is None else Ti
        Kv = loop.Kv if Kv is None else Kv
        if which == "velocity-open":
            closed = self.analog_closed_loop if self.analog else self.velocity_closed_loop
            A, B, C = closed(Kp, Ti, error_form=True)
            return float(static_gain(A, B[:, :1], C[1:2], discrete=not self.analog)[0, 0])
        if which != "position-open":
            raise ModelError(f"expected 'velocity-open' or 'position-open', got {which!r}", path="which")
        if ctrl.position_loop == "continuous":
            A, B, C = self.analog_closed_loop(Kp, Ti)
            b, c = B[:, :1], C[:1]
            return float(static_gain(A - Kv * b @ c, Kv * b, c, discrete=False)[0, 0])
        Ap, Bp, C = self.position_model(Kp, Ti)
        n, d = Ap.shape[0], ctrl.position_delay
        b, c = Bp[:, :1], C[:1]
        # states (x, q_1..q_d): q_1 ← Kv (r − c x), q_j ← q_{j−1}, the velocity command is q_d
        A = np.zeros((n + d, n + d))
        B = np.zeros((n + d, 1))
        A[:n, :n] = Ap
        if d == 0:
            A[:n, :n] -= Kv * b @ c
            B[:n] = Kv * b
        else:
            A[:n, n + d - 1:] = b
            A[n:n + 1, :n] = -Kv * c
            B[n, 0] = Kv
            A[n + 1:, n:n + d - 1] = np.eye(d - 1)
        return float(static_gain(A, B, np.hstack([c, np.zeros((1, d))]), discrete=True)[0, 0])

    # ------------------------------------------------------------------ public
    def response(self, which: str, omega: np.ndarray | None = None, *, Kp: float | None = None,
                 Ti: float | None = None, Kv: float | None = None) -> FrequencyResponse:
        """The transfer ``which`` (one of :data:`LOOPS`) with the loop's gains or the ones given."""
        loop, ctrl = self.loop, self.loop.controller
        Kp = loop.Kp if Kp is None else Kp
        Ti = loop.Ti if Ti is None else Ti
        Kv = loop.Kv if Kv is None else Kv
        if which not in LOOPS:
            raise ModelError(f"unknown loop {which!r}; expected one of {', '.join(LOOPS)}", path="which")
        omega = default_omega(loop, which) if omega is None else np.asarray(omega, dtype=float)
        Tv = None if self.analog else ctrl.velocity_period
        Tp = ctrl.position_period if ctrl.position_loop == "discrete" else None
        if which == "plant":
            return self._plant(omega)
        if which in ("compliance", "disturbance"):
            return self._compliance(omega, Kp, Ti, Kv, which)
        if which.startswith("velocity"):
            cp, ci, act, meas = self.velocity_factors(omega, Kp, Ti)
            L = (cp + ci) * act * meas
            if which == "velocity-open":
                return FrequencyResponse(omega, L, which, Tv, open_loop=True,
                                         info={"input": "velocity error", "output": "measured velocity",
                                               "closed_loop_static_gain":
                                                   self.closed_loop_static_gain(which, Kp, Ti, Kv)})
            forward = self.velocity_forward(omega, Kp, Ti)
            return FrequencyResponse(omega, forward * act * meas / (1.0 + L), which, Tv,
                                     info={"input": "velocity command", "output": "measured velocity"})
        diff: np.ndarray
        if Tp is None:         # a continuous position loop around the analog velocity loop
            g_v, g_f = self.position_continuous(omega, Kp, Ti)
            z, diff = np.exp(1j * omega * ctrl.position_period), 1j * omega
        else:
            g_v, g_f = self.position_lifted(omega, Kp, Ti)
            z = np.exp(1j * omega * Tp)
            diff = (1.0 - 1.0 / z) / Tp
        L = Kv * z ** (-ctrl.position_delay) * g_v
        if which == "position-open":
            return FrequencyResponse(omega, L, which, Tp, open_loop=True,
                                     info={"input": "position error", "output": "measured position",
                                           "closed_loop_static_gain": self.closed_loop_static_gain(which, Kp, Ti, Kv)})
        ff = ctrl.velocity_feedforward * diff * np.exp(-1j * omega * ctrl.feedforward_delay) * g_v \
            + ctrl.acceleration_feedforward * loop.m_rigid * diff ** 2 * np.exp(-1j * omega * ctrl.feedforward_delay) * g_f
        T = (Kv * z ** (-ctrl.position_delay) * g_v + ff) / (1.0 + L)
        if which == "position-closed":
            return FrequencyResponse(omega, T, which, Tp, info={"input": "position setpoint",
                                                                "output": "measured position"})
        return FrequencyResponse(omega, 1.0 - T, which, Tp, info={"input": "position setpoint",
                                                                  "output": "following error"})

    def _plant(self, omega: np.ndarray) -> FrequencyResponse:
        mech, loop = self.loop.mechanics, self.loop
        plant = mech.state_space().select(inputs=[loop.actuator], outputs=[loop.controller.position_sensor])
        H = transfer_at(plant.A, plant.B, plant.C, plant.D, 1j * omega)[0, 0]
        return FrequencyResponse(omega, H, "plant", None,
                                 info={"input": f"{loop.actuator} effort", "output": loop.controller.position_sensor})

    def _compliance(self, omega, Kp, Ti, Kv, which) -> FrequencyResponse:
        """Force on the tool body → tool position (compliance) or measured position (disturbance)."""
        from ..servo.loop import servo_plant

        loop, ctrl = self.loop, self.loop.controller
        plant = servo_plant(loop, disturbance=loop.tool)
        vel = loop.mechanics.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
        outs = [f"sensor.{ctrl.position_sensor}", f"sensor.{vel.name}", "tool.position"]
        sub = plant.select(outputs=outs)
        G = transfer_at(sub.A, sub.B, sub.C, sub.D, 1j * omega)  # (3, 2, n)
        Tv, Tp = ctrl.velocity_period, ctrl.position_period
        cp, ci, act, _ = self.velocity_factors(omega, Kp, Ti)
        meas_v = self._measurement(omega)
        if self.analog:        # continuous velocity law, no hold
            hold_v = np.ones_like(meas_v)
        else:
            hold_v = (1 - np.exp(-1j * omega * Tv)) / (1j * omega * Tv)
        if ctrl.position_loop == "continuous":
            hold_p = np.ones_like(omega, dtype=complex)
        else:
            hold_p = (1 - np.exp(-1j * omega * Tp)) / (1j * omega * Tp)
        # current reference = -act·[ (C_p + C_i) v_meas + C_e Kv e^{-jω dp Tp} hold_p · p_meas ]: the
        # position loop's output is the velocity command, which the law sees through C_e (P-IP: C_i)
        law = (cp + ci) * act * hold_v
        k_vel = law * meas_v
        forward = self.velocity_forward(omega, Kp, Ti) * act * hold_v
        k_pos = forward * Kv * np.exp(-1j * omega * ctrl.position_delay * Tp) * hold_p / loop.position_gain
        # y = G_d d + G_u u, u = -(k_pos y_pos + k_vel y_vel)
        loop_gain = 1.0 + k_pos * G[0, 0] + k_vel * G[1, 0]
        u = -(k_pos * G[0, 1] + k_vel * G[1, 1]) / loop_gain
        out = 2 if which == "compliance" else 0
        H = G[out, 1] + G[out, 0] * u
        if which == "disturbance":
            H = H / loop.position_gain
        return FrequencyResponse(omega, H, which, None,
                                 info={"input": "force at the tool (along its coordinate)",
                                       "output": "tool position" if which == "compliance" else "measured position"})


def loop_response(loop: "ServoLoop", which: str, omega: np.ndarray | None = None) -> FrequencyResponse:
    """Frequency response of one transfer of a servo loop (see :data:`LOOPS`).

    Examples
    --------
    >>> import sicomat
    >>> from sicomat.servo.loop import build_servo_loop
    >>> loop = build_servo_loop(sicomat.load_model("examples/paper_5m4s.toml"))
    >>> frf = loop_response(loop, "velocity-open")
    >>> bool(frf.omega[-1] < 3.1416 / loop.controller.velocity_period)
    True
    """
    return LoopAnalysis.of(loop).response(which, omega)


def _continuous_response(A, B, c, s) -> np.ndarray:
    """``c (sI − A)⁻¹ b`` of the plant's first input at points s."""
    return _plant_factor(A, B, c, s, discrete=False)


def _tf_at(spec, s: np.ndarray) -> np.ndarray:
    """A filter's continuous (unwarped) transfer function at points s."""
    num, den = continuous_filter(spec)
    return np.polyval(num, s) / np.polyval(den, s)


def _discrete_response(Phi, Gamma, c, z) -> np.ndarray:
    """``c (zI − Φ)⁻¹ γ`` of the plant's first input at points z."""
    return _plant_factor(Phi, Gamma, c, z, discrete=True)


def _plant_factor(A, B, c, points, *, discrete: bool) -> np.ndarray:
    """``c (pI − A)⁻¹ b`` (first input), memoised: the plant factor of the velocity loop does not depend
    on the gains, and ``margins``/``bode`` evaluate it for several transfers on one grid (read-only)."""
    A, B, c = (np.ascontiguousarray(x, dtype=float) for x in (A, np.asarray(B)[:, :1], c))
    points = np.ascontiguousarray(points, dtype=complex)
    return _plant_factor_cached(A.shape[0], A.tobytes(), B.tobytes(), c.tobytes(), points.tobytes(), discrete)


@lru_cache(maxsize=8)
def _plant_factor_cached(n: int, a: bytes, b: bytes, c: bytes, p: bytes, discrete: bool) -> np.ndarray:
    A = np.frombuffer(a).reshape(n, n)
    H = transfer_at(A, np.frombuffer(b).reshape(n, 1), np.frombuffer(c).reshape(1, n),
                    points=np.frombuffer(p, dtype=complex), discrete=discrete)[0, 0]
    H.setflags(write=False)
    return H


