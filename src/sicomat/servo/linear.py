"""The linear model of a servo loop: the closed velocity loop (sampled at Tv, or continuous for an
analog loop) and the closed velocity loop lifted to the position period, built from the blocks' one
lowering (:mod:`sicomat.servo.blocks`).

The same matrices give the stability verdict (their poles, :mod:`sicomat.servo.stability`), the
frequency responses (:class:`~sicomat.frequency.loops.LoopAnalysis` extends :class:`LoopModel`), the
step responses of the time tuning, and equal the simulator's linearised program.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from .blocks import linear_law
from .controller import DiscreteSS, filter_block
from ..errors import ModelError
from ..lti.response import zoh_matrices

if TYPE_CHECKING:  # pragma: no cover
    from .loop import ServoLoop

__all__ = ["LoopModel", "lifted"]


@dataclass(frozen=True, eq=False)
class LoopModel:
    """Pieces of a loop that do not depend on the gains, computed once (for tuning loops)."""

    loop: "ServoLoop"
    Phi: np.ndarray        # the plant ZOH-sampled at Tv; its continuous A for an analog velocity loop
    Gamma: np.ndarray      # ... and its B
    c_pos: np.ndarray      # row: raw position-sensor reading
    c_vel: np.ndarray      # row: raw velocity-sensor reading (a position if differenced)
    differenced: bool      # velocity from a position sensor (differenced, or differentiated if analog)
    analog: bool = False   # the velocity loop is continuous

    @classmethod
    def of(cls, loop: "ServoLoop"):
        """Discretise the plant of ``loop`` at the velocity period (keep it continuous for an analog
        velocity loop)."""
        from .loop import servo_plant

        ctrl = loop.controller
        plant = servo_plant(loop)
        analog = ctrl.velocity_loop == "continuous"
        Phi, Gamma = (plant.A, plant.B) if analog else zoh_matrices(plant.A, plant.B, ctrl.velocity_period)
        vel = loop.mechanics.sensor(ctrl.velocity_sensor or ctrl.position_sensor)
        return cls(loop, Phi, Gamma, plant.C[plant.outputs.index(f"sensor.{ctrl.position_sensor}")],
                   plant.C[plant.outputs.index(f"sensor.{vel.name}")], vel.kind == "position", analog)

    def _blocks(self) -> tuple[list[DiscreteSS], DiscreteSS | None]:
        ctrl, T = self.loop.controller, self.loop.controller.velocity_period
        where = f"axes.{self.loop.axis}.controller"
        current = [_filter(f, T, f"{where}.current_filters.{i}") for i, f in enumerate(ctrl.current_filters)]
        velocity = _filter(ctrl.velocity_filter, T, f"{where}.velocity_filter") if ctrl.velocity_filter else None
        return current, velocity

    def analog_closed_loop(self, Kp: float, Ti: float, *, error_form: bool = False
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous state space of the closed analog velocity loop: inputs (velocity command,
        feedforward effort), outputs (measured position in axis units, measured velocity).
        ``error_form``: the law seen from the error only (the loop gain's closed loop)."""
        from .analog import analog_loop
        from .loop import servo_plant

        loop = self.loop.with_gains(Kp=Kp, Ti=Ti)
        if loop.controller.position_loop == "continuous":     # the velocity loop alone, commanded
            loop = replace(loop, controller=loop.controller.model_copy(update={"position_loop": "discrete"}))
        closed = analog_loop(loop, servo_plant(loop), error_form=error_form)
        n = closed.A.shape[0]
        pos = np.zeros(n)
        pos[: self.c_pos.size] = self.c_pos / loop.position_gain
        return closed.A, closed.B, np.vstack([pos, closed.outputs["velocity.measured"][:n]])

    def velocity_closed_loop(self, Kp: float, Ti: float, *, error_form: bool = False
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """State space at Tv of the closed velocity loop: inputs (velocity command, feedforward
        effort), outputs (measured position in axis units, measured velocity). The velocity law is
        the controller kind's lowering (:func:`~sicomat.servo.blocks.linear_law`); ``error_form``:
        seen from the error only (the loop gain's closed loop). Further inputs of the sampled plant
        (``Gamma``'s columns after the first: the commands of a coupled axis's partners) are further
        inputs of the closed loop."""
        loop = self.loop
        blocks = self._blocks()
        law = linear_law(loop, Kp, Ti, error_form=error_form)
        extra = self.Gamma.shape[1] - 1
        b = _Builder(self.Phi.shape[0] + self.controller_states(law, blocks), n_inputs=2 + extra)
        x = b.block(self.Phi.shape[0])
        signal, position, v_meas = self.close_velocity(b, x, law, blocks, b.input(0), b.input(1))
        for i in range(self.Phi.shape[0]):
            value = b.row(x, self.Phi[i]) + signal * self.Gamma[i, 0]
            for j in range(extra):
                value = value + b.input(2 + j) * self.Gamma[i, 1 + j]
            b.next(x, i, value)
        A, B = b.matrices()
        n = A.shape[0]
        C = np.vstack([position.sx[:n], v_meas.sx[:n]])
        D = np.vstack([position.su, v_meas.su])
        if np.any(D):
            raise RuntimeError("the sampled measurements have no direct feedthrough")  # pragma: no cover
        return A, B, C

    def controller_states(self, law: DiscreteSS, blocks: tuple[list[DiscreteSS], DiscreteSS | None]) -> int:
        """At most how many states :meth:`close_velocity` adds to the plant's (checked against the
        memory budget)."""
        ctrl = self.loop.controller
        capacity = 1 + law.A.shape[0] + 2 * (len(blocks[0]) + 1) + ctrl.velocity_delay
        from ..budget import require_dense

        require_dense(self.Phi.shape[0] + capacity, "this analysis of the sampled velocity loop",
                      f"one per sample of the velocity_delay of {ctrl.velocity_delay}")
        return capacity

    def close_velocity(self, b: "_Builder", x: slice, law: DiscreteSS,
                       blocks: tuple[list[DiscreteSS], DiscreteSS | None], command: "_Affine",
                       feedforward: "_Affine") -> tuple["_Affine", "_Affine", "_Affine"]:
        """The sampled velocity loop's controller appended to the builder ``b`` whose block ``x`` holds
        the plant's states (the sensors read as ``c_pos``, ``c_vel`` from it): the differencing, the
        filters, the law (:func:`~sicomat.servo.blocks.linear_law`, ``law``), the current filters and
        the computation delay, from the velocity ``command`` and the ``feedforward`` effort. Returns
        the drive's current reference (the plant's input), the measured position (axis units) and the
        measured velocity — the one lowering of a velocity loop's linear part, for one axis
        (:meth:`velocity_closed_loop`) or each of coupled axes
        (:func:`~sicomat.servo.coupled_linear.coupled_axis_model`)."""
        loop, ctrl = self.loop, self.loop.controller
        T = ctrl.velocity_period
        current, velocity = blocks
        pos_raw = b.row(x, self.c_pos)
        vs_raw = b.row(x, self.c_vel)
        if self.differenced:
            prev = b.block(1)
            v_raw = (vs_raw - b.state(prev, 0)) * (1.0 / (T * loop.velocity_gain))
            b.next(prev, 0, vs_raw)
        else:
            v_raw = vs_raw * (1.0 / loop.velocity_gain)
        v_meas = b.apply(velocity, v_raw) if velocity is not None else v_raw
        error = command - v_meas
        effort = b.apply2(law, error, v_meas)
        signal = (effort + feedforward) * (1.0 / loop.drive.kt)
        for block in current:
            signal = b.apply(block, signal)
        if ctrl.velocity_delay:
            line = b.block(ctrl.velocity_delay)
            b.next(line, 0, signal)
            for j in range(1, ctrl.velocity_delay):
                b.next(line, j, b.state(line, j - 1))
            signal = b.state(line, ctrl.velocity_delay - 1)
        return signal, pos_raw * (1.0 / loop.position_gain), v_meas

    def position_model(self, Kp: float, Ti: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The closed velocity loop as an exact LTI system at Tp: inputs (velocity command,
        feedforward effort) held over Tp, outputs (measured position, velocity) sampled at Tp —
        the lifted sampled loop (``A^Np``, ``Σ A^i B``), or the ZOH of an analog one."""
        if self.analog:
            A, B, C = self.analog_closed_loop(Kp, Ti)
            Ap, Bp = zoh_matrices(A, B, self.loop.controller.position_period)
            return Ap, Bp, C
        A, B, C = self.velocity_closed_loop(Kp, Ti)
        Ap, Bp = lifted(A, B, self.loop.position_ratio)
        return Ap, Bp, C


def lifted(A: np.ndarray, B: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """A discrete system with its input held over ``steps`` periods, sampled every ``steps`` periods:
    ``(A^steps, Σ_{i<steps} A^i B)``, exact."""
    Bp = np.zeros_like(B)
    power = np.eye(A.shape[0])
    for _ in range(steps):
        Bp += power @ B
        power = power @ A
    return np.linalg.matrix_power(A, steps), Bp


def _filter(spec, period: float, path: str) -> DiscreteSS:
    try:
        return filter_block(spec, period)
    except ValueError as exc:
        raise ModelError(str(exc), path=path, value=spec.frequency) from None


class _Affine:
    """A signal as an affine function of the state and the inputs: ``sx · x + su · u``."""

    __slots__ = ("sx", "su")

    def __init__(self, sx: np.ndarray, su: np.ndarray) -> None:
        self.sx, self.su = sx, su

    def __add__(self, other: "_Affine") -> "_Affine":
        return _Affine(self.sx + other.sx, self.su + other.su)

    def __sub__(self, other: "_Affine") -> "_Affine":
        return _Affine(self.sx - other.sx, self.su - other.su)

    def __mul__(self, k: float) -> "_Affine":
        return _Affine(self.sx * k, self.su * k)


class _Builder:
    """Assembles a discrete state space from blocks whose next states are affine signals."""

    def __init__(self, capacity: int, n_inputs: int) -> None:
        self._max = capacity
        self.n_inputs = n_inputs
        self.sizes: list[int] = []
        self.rows: dict[int, _Affine] = {}

    @property
    def n_states(self) -> int:
        return sum(self.sizes)

    def block(self, size: int) -> slice:
        start = self.n_states
        if start + size > self._max:  # pragma: no cover - capacity is computed by the caller
            raise RuntimeError("state capacity exceeded")
        self.sizes.append(size)
        return slice(start, start + size)

    def state(self, block: slice, i: int) -> _Affine:
        sx = np.zeros(self._max)
        sx[block.start + i] = 1.0
        return _Affine(sx, np.zeros(self.n_inputs))

    def row(self, block: slice, c: np.ndarray) -> _Affine:
        sx = np.zeros(self._max)
        sx[block.start: block.start + c.size] = c
        return _Affine(sx, np.zeros(self.n_inputs))

    def input(self, j: int) -> _Affine:
        su = np.zeros(self.n_inputs)
        su[j] = 1.0
        return _Affine(np.zeros(self._max), su)

    def next(self, block: slice, i: int, value: _Affine) -> None:
        self.rows[block.start + i] = value

    def apply(self, ss: DiscreteSS, signal: _Affine) -> _Affine:
        A, B, C, D = (np.atleast_2d(m) for m in (ss.A, ss.B, ss.C, ss.D))
        blk = self.block(A.shape[0])
        states = [self.state(blk, i) for i in range(A.shape[0])]
        for i in range(A.shape[0]):
            value = signal * B[i, 0]
            for j in range(A.shape[0]):
                value = value + states[j] * A[i, j]
            self.next(blk, i, value)
        out = signal * D[0, 0]
        for j in range(A.shape[0]):
            out = out + states[j] * C[0, j]
        return out

    def apply2(self, ss: DiscreteSS, first: _Affine, second: _Affine) -> _Affine:
        """A block with two inputs (the velocity law: error, measured velocity); its output."""
        A, B, C, D = ss.A, ss.B, ss.C, ss.D
        k = A.shape[0]
        blk = self.block(k)
        states = [self.state(blk, i) for i in range(k)]
        for i in range(k):
            value = states[0] * A[i, 0]
            for j in range(1, k):
                value = value + states[j] * A[i, j]
            self.next(blk, i, value + first * B[i, 0] + second * B[i, 1])
        out = first * D[0, 0] + second * D[0, 1]
        for j in range(k):
            out = out + states[j] * C[0, j]
        return out

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.n_states
        A = np.zeros((n, n))
        B = np.zeros((n, self.n_inputs))
        for i, value in self.rows.items():
            A[i] = value.sx[:n]
            B[i] = value.su
        return A, B
