"""The stability verdict of a servo loop: the poles of its closed linear model, and warnings.

Every command that analyses or simulates a loop states one verdict, ``stable`` (True, False, or None
when unknown) with a list of plain-sentence ``warnings`` (:class:`Verdict`). The verdict comes from
the loop's linear model: the poles of the closed velocity loop (sampled at Tv, or continuous for an
analog loop: :meth:`~sicomat.servo.linear.LoopModel.velocity_closed_loop`,
:meth:`~sicomat.servo.linear.LoopModel.analog_closed_loop`, built from the blocks' one lowering) and of the closed position loop around it
(lifted to Tp with its computation delay, or continuous: :func:`position_closed_loop`).

A pole is unstable when its growth rate over one velocity period, ``ln|z|`` (``Re(s)·Tv`` for a
continuous pole, ``ln|z|/Np`` for a pole of the position loop at ``Tp = Np·Tv``), exceeds
:data:`GROWTH_TOLERANCE`. Poles on the unit circle at ``z = 1`` (``s = 0``) are the free rigid-body
position a velocity loop alone does not hold: marginal, not unstable.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from .linear import LoopModel

if TYPE_CHECKING:  # pragma: no cover
    from .loop import ServoLoop

__all__ = ["GROWTH_TOLERANCE", "LoopPoles", "Verdict", "position_closed_loop", "loop_poles",
           "loop_verdict", "combine"]

GROWTH_TOLERANCE = 1e-7
"""Largest growth ``ln|z|`` per velocity period counted as not unstable (8e-4 1/s, an e-folding
time of 21 min, at Tv = 125 µs). The eigenvalues of a closed loop carry a rounding error of about
``eps·‖A‖·κ``: the rigid-body pole of the 5M4S comes out at 2e-16 per period; a double pole at
z = 1 (an undamped free body no sensor sees) is perturbed by ``√eps ≈ 1.5e-8``; both stay below."""


@dataclass(frozen=True, eq=False)
class LoopPoles:
    """The poles of one closed loop and whether they are stable.

    Attributes
    ----------
    loop : str
        ``"velocity"`` or ``"position"``.
    poles : ndarray of complex
        In z at ``sample_period``, or in s (rad/s) for a continuous loop (``sample_period`` None).
    sample_period : float or None
    velocity_period : float
        The velocity loop's period Tv (s), the unit of the growth.
    """

    loop: str
    poles: np.ndarray
    sample_period: float | None
    velocity_period: float

    @property
    def growth(self) -> np.ndarray:
        """Growth ``ln|z|`` of each pole per velocity period (``Re(s)·Tv`` for a continuous one)."""
        return _growth(self.poles, self.sample_period, self.velocity_period)

    @property
    def growth_per_period(self) -> float:
        """The largest growth per velocity period (negative: every pole decays)."""
        g = self.growth
        return float(np.max(g)) if g.size else -np.inf

    @property
    def stable(self) -> bool:
        """No pole grows faster than :data:`GROWTH_TOLERANCE` per velocity period."""
        return bool(self.growth_per_period <= GROWTH_TOLERANCE)

    def unstable_poles_hz(self) -> list[float]:
        """Frequencies (Hz) of the unstable poles (one per conjugate pair)."""
        p = np.asarray(self.poles, dtype=complex)
        with np.errstate(all="ignore"):
            s = p if self.sample_period is None else np.log(p) / self.sample_period
        freqs = np.abs(s.imag[(self.growth > GROWTH_TOLERANCE) & np.isfinite(s.imag)]) / (2 * np.pi)
        return sorted({float(f"{f:.4g}") for f in freqs})

    def describe(self) -> str:
        """One sentence for the warnings."""
        rate = self.growth_per_period / self.velocity_period
        where = ", ".join(f"{f:.4g} Hz" for f in self.unstable_poles_hz())
        speed = "without bound" if not np.isfinite(rate) else f"at {rate:.4g} 1/s"
        return (f"the closed {self.loop} loop is unstable: its linear model has poles growing {speed}"
                + (f" (at {where})" if where else ""))


@dataclass(frozen=True)
class Verdict:
    """``stable`` (True, False or None when unknown) and plain-sentence ``warnings``."""

    stable: bool | None
    warnings: tuple[str, ...] = ()
    loops: dict[str, bool] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The ``"stable"`` and ``"warnings"`` keys of every ``--json`` payload."""
        return {"stable": self.stable, "warnings": list(self.warnings)}

    def with_warnings(self, warnings: Iterable[str], *, unstable: bool = False) -> "Verdict":
        """The same verdict with more warnings; ``unstable=True`` makes it unstable."""
        new = tuple(w for w in warnings if w not in self.warnings)
        return Verdict(False if unstable else self.stable, self.warnings + new, self.loops)


def combine(verdicts: Iterable[Verdict], prefixes: Iterable[str] | None = None) -> Verdict:
    """One verdict of several (e.g. the axes of a path): unstable if any is, unknown if any is
    unknown and none unstable; warnings joined, each prefixed (e.g. ``"axis X: "``)."""
    verdicts = list(verdicts)
    prefixes = list(prefixes) if prefixes is not None else [""] * len(verdicts)
    flags = [v.stable for v in verdicts]
    stable = False if False in flags else (None if None in flags or not flags else True)
    warnings = tuple(f"{p}{w}" for v, p in zip(verdicts, prefixes) for w in v.warnings)
    return Verdict(stable, warnings)


def position_closed_loop(an: "LoopModel", Kp: float, Ti: float, Kv: float):
    """The closed position loop from the position setpoint to the measured position:
    ``(A, B, C, period)``, at Tp (the lifted velocity loop with the position loop's computation
    delay line) or, for a continuous position loop, in continuous time (``period`` None)."""
    ctrl = an.loop.controller
    if ctrl.position_loop == "continuous":     # v_cmd = Kv (x_ref - x) around the analog velocity loop
        A, B, C = an.analog_closed_loop(Kp, Ti)
        return A - Kv * np.outer(B[:, 0], C[0]), Kv * B[:, 0], C[0], None
    Ap, Bp, C = an.position_model(Kp, Ti)
    Bp = Bp[:, 0]
    d = ctrl.position_delay
    n_x = Ap.shape[0]
    size = n_x + d
    from ..budget import require_dense

    require_dense(size, "the closed position loop", f"one state per sample of the position_delay of {d}")
    Acl = np.zeros((size, size))
    Bcl = np.zeros(size)
    Acl[:n_x, :n_x] = Ap
    if d:
        Acl[:n_x, n_x + d - 1] = Bp
        Acl[n_x, :n_x] = -Kv * C[0]
        Bcl[n_x] = Kv
        for j in range(1, d):
            Acl[n_x + j, n_x + j - 1] = 1.0
    else:
        Acl[:n_x, :n_x] -= Kv * np.outer(Bp, C[0])
        Bcl[:n_x] = Kv * Bp
    Ccl = np.zeros(size)
    Ccl[:n_x] = C[0]
    return Acl, Bcl, Ccl, ctrl.position_period


def _growth(poles: np.ndarray, period: float | None, velocity_period: float) -> np.ndarray:
    poles = np.asarray(poles, dtype=complex)
    if period is None:
        return poles.real * velocity_period
    with np.errstate(divide="ignore"):
        return np.log(np.abs(poles)) * (velocity_period / period)


def _poles(loop: str, A: np.ndarray, period: float | None, velocity_period: float) -> LoopPoles:
    if not np.all(np.isfinite(A)):
        return LoopPoles(loop, np.array([np.inf + 0j]), period, velocity_period)
    return LoopPoles(loop, np.linalg.eigvals(A), period, velocity_period)


def loop_poles(an: "LoopModel", *, Kp: float | None = None, Ti: float | None = None,
               Kv: float | None = None, loops: Iterable[str] = ("velocity", "position")) -> dict[str, LoopPoles]:
    """The poles of the closed velocity loop and of the closed position loop (the whole cascade),
    with the loop's gains or the ones given (Kp in physical units)."""
    loop = an.loop
    Kp = loop.Kp if Kp is None else Kp
    Ti = loop.Ti if Ti is None else Ti
    Kv = loop.Kv if Kv is None else Kv
    Tv = loop.controller.velocity_period
    out = {}
    with np.errstate(all="ignore"):
        if "velocity" in loops:
            if an.analog:
                A = an.analog_closed_loop(Kp, Ti)[0]
                out["velocity"] = _poles("velocity", A, None, Tv)
            else:
                out["velocity"] = _poles("velocity", an.velocity_closed_loop(Kp, Ti)[0], Tv, Tv)
        if "position" in loops:
            A, _, _, period = position_closed_loop(an, Kp, Ti, Kv)
            out["position"] = _poles("position", A, period, Tv)
    return out


def loop_verdict(loop: "ServoLoop", *, Kp: float | None = None, Ti: float | None = None, Kv: float | None = None,
                 loops: Iterable[str] = ("velocity", "position"), an: "LoopModel | None" = None) -> Verdict:
    """The verdict of a servo loop from the poles of its closed linear model.

    ``loops`` chooses the closed loops judged: ``("velocity",)`` for the velocity loop alone (the
    ``velocity`` step response, its open-loop Bode plot), both for the whole cascade (a simulation,
    the position loop). Stable when every one is; the warnings name each unstable loop and the
    frequencies and growth rates of its unstable poles.

    Examples
    --------
    >>> import sicomat
    >>> from sicomat.servo.loop import build_servo_loop
    >>> machine = sicomat.load_model("examples/paper_5m4s.toml")
    >>> loop_verdict(build_servo_loop(machine)).stable
    True
    >>> loop_verdict(build_servo_loop(machine).with_gains(Kv=5000.0)).stable
    False
    """
    an = an if an is not None else LoopModel.of(loop)
    poles = loop_poles(an, Kp=Kp, Ti=Ti, Kv=Kv, loops=loops)
    warnings = []
    flags = {name: p.stable for name, p in poles.items()}
    if not flags.get("velocity", True):
        warnings.append(poles["velocity"].describe())
        if "position" in poles:      # the position loop around an unstable velocity loop: one sentence
            flags["position"] = False
    elif not flags.get("position", True):
        warnings.append(poles["position"].describe())
    return Verdict(all(flags.values()), tuple(warnings), flags)
