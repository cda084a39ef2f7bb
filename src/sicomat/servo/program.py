"""The hybrid program the simulation kernel runs: a continuous LTI part with Coulomb friction links,
and a list of discrete operations on a vector of named signal slots, each at its own rate.

Every block of the servo loop (drive, CNC controller, filters, setpoints) lowers to these few
element kinds, so a new block needs no change in the kernel. This module only *describes*; the
kernel (:mod:`sicomat.simulation.kernel`) executes.

Timing, at base step k (time t_k = k*h):
  1. continuous outputs ``y = C x + D u`` are written into ``output_slots``;
  2. every op with ``(k - phase) % period == 0`` runs, in list order;
  3. the held input ``u = slots[input_slots]`` is latched (zero-order hold until t_{k+1});
  4. the recorded slots and the acting friction forces are stored;
  5. the continuous state is advanced exactly to t_{k+1} (stick/slip events located inside the step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ContinuousPart", "LinearBlock", "LinearOutput", "LinearUpdate", "Sum", "Saturate",
           "Quantize", "Delay", "CurrentLimit", "ClampGate", "Setpoint", "Op", "HybridProgram"]


@dataclass(frozen=True, eq=False)
class ContinuousPart:
    """``ẋ = A x + B u + F f``, ``y = C x + D u``; ``f_j`` is the Coulomb force of friction link j.

    ``v_j = G[j] @ x`` is the sliding velocity of link j. While link j slides,
    ``f_j = -coulomb[j] * sign(v_j)``; while it sticks, ``f_j`` is the constraint force that keeps
    ``v_j = 0``, and the link breaks away when that force would exceed ``static[j]``.
    """

    A: np.ndarray          # (nx, nx)
    B: np.ndarray          # (nx, nu)   held inputs
    C: np.ndarray          # (ny, nx)
    D: np.ndarray          # (ny, nu)
    F: np.ndarray          # (nx, nf)   friction force inputs
    G: np.ndarray          # (nf, nx)   sliding velocities
    coulomb: np.ndarray    # (nf,)  kinetic friction force, > 0
    static: np.ndarray     # (nf,)  breakaway force, >= coulomb
    x0: np.ndarray         # (nx,)
    input_slots: tuple[int, ...]    # u[i] = slots[input_slots[i]] (latched after the ops)
    output_slots: tuple[int, ...]   # slots[output_slots[i]] = y[i] (before the ops)
    friction_slots: tuple[int, ...] = ()  # optional: where the acting f_j is written (-1: nowhere)


@dataclass(frozen=True, eq=False)
class LinearBlock:
    """A discrete linear block ``x+ = A x + B u``, ``y = C x + D u`` (its state lives in the kernel).

    ``inputs`` are slot indices read into ``u``; ``outputs`` are slot indices written from ``y``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple[int, ...]
    outputs: tuple[int, ...]
    x0: np.ndarray | None = None


@dataclass(frozen=True)
class Op:
    """Base of the discrete operations: they run when ``(k - phase) % period == 0``."""

    period: int = 1
    phase: int = 0


@dataclass(frozen=True)
class LinearOutput(Op):
    """``slots[block.outputs] = C x + D slots[block.inputs]`` for ``blocks[block]``."""

    block: int = 0


@dataclass(frozen=True)
class LinearUpdate(Op):
    """``x = A x + B slots[block.inputs]`` for ``blocks[block]``."""

    block: int = 0


@dataclass(frozen=True)
class Sum(Op):
    """``slots[output] = offset + Σ weights[i] * slots[inputs[i]]``."""

    inputs: tuple[int, ...] = ()
    weights: tuple[float, ...] = ()
    output: int = 0
    offset: float = 0.0


@dataclass(frozen=True)
class Saturate(Op):
    """``slots[output] = clip(slots[input], lo, hi)``; lo/hi from ``lower_slot``/``upper_slot`` when >= 0."""

    input: int = 0
    output: int = 0
    lower: float = -np.inf
    upper: float = np.inf
    lower_slot: int = -1
    upper_slot: int = -1


@dataclass(frozen=True)
class Quantize(Op):
    """``slots[output] = step * round(slots[input] / step)`` (``mode="floor"``: ``floor`` instead)."""

    input: int = 0
    output: int = 0
    step: float = 1.0
    mode: str = "round"


@dataclass(frozen=True)
class Delay(Op):
    """``slots[output]`` = ``slots[input]`` as it was ``samples`` executions of this op ago (0 before)."""

    input: int = 0
    output: int = 0
    samples: int = 1


@dataclass(frozen=True)
class CurrentLimit(Op):
    """Current-reference bounds of a drive from its peak current and the voltage limit.

    With speed ``w = slots[speed]`` (rad/s or m/s), the q-axis voltage ``R i + Ke w`` and the
    cross-coupling ``wL * w * i`` must satisfy ``(R i + Ke w)^2 + (wL w i)^2 <= u_max^2``; the
    admissible currents form an interval ``[i_lo, i_hi]``, intersected with ``[-i_peak, i_peak]``
    and written to ``slots[lower]``, ``slots[upper]``. ``u_max = inf`` disables the voltage part.
    If the interval is empty (the back-EMF alone exceeds the supply), both bounds are the value
    of the interval's nearest end (the drive brakes as hard as it can).
    """

    speed: int = 0
    lower: int = 0
    upper: int = 0
    i_peak: float = np.inf
    u_max: float = np.inf
    resistance: float = 0.0
    ke: float = 0.0
    wl: float = 0.0


@dataclass(frozen=True)
class ClampGate(Op):
    """Conditional integration (clamping anti-windup).

    ``slots[output] = 0`` when the controller output is saturated (``slots[unsaturated] !=
    slots[saturated]``) and the error ``slots[input]`` has the sign of ``slots[unsaturated]``;
    ``slots[output] = slots[input]`` otherwise.
    """

    input: int = 0
    unsaturated: int = 0
    saturated: int = 0
    output: int = 0


@dataclass(frozen=True)
class Setpoint(Op):
    """``slots[output] = table[column, j]`` at the op's j-th execution (held at the last sample after the end)."""

    column: int = 0
    output: int = 0


@dataclass(frozen=True, eq=False)
class HybridProgram:
    """A complete hybrid system ready for the kernel.

    Attributes
    ----------
    step : float
        Base step h (s); every op period is a whole number of base steps.
    n_slots : int
        Size of the signal vector; ``slot_names[i]`` names slot i.
    continuous : ContinuousPart
    blocks : tuple of LinearBlock
    ops : tuple of Op
        Executed in order at each base step where due.
    table : ndarray, shape (n_columns, n_samples)
        Setpoint samples read by :class:`Setpoint` ops.
    record : tuple of int
        Slots stored at every base step.
    aliases : dict
        Other names of slots (signals that are identity copies of others); the kernel ignores them.
    """

    step: float
    slot_names: tuple[str, ...]
    continuous: ContinuousPart
    blocks: tuple[LinearBlock, ...] = ()
    ops: tuple[Op, ...] = ()
    table: np.ndarray = field(default_factory=lambda: np.zeros((0, 1)))
    record: tuple[int, ...] = ()
    aliases: dict[str, int] = field(default_factory=dict)

    @property
    def n_slots(self) -> int:
        """Number of signal slots."""
        return len(self.slot_names)
