"""The linear model of one axis of coupled loops (:class:`~sicomat.servo.coupled.CoupledLoop`) with the
other axes' loops closed: the single-axis linear model (:class:`~sicomat.servo.linear.LoopModel`) on a
larger sampled "plant", so that every analysis written for one axis (its frequency responses, margins,
static gains, poles) runs unchanged.

The plant of axis A is the coupled continuous part (:func:`~sicomat.servo.coupled.coupled_plant`: the
coupled mechanics and every axis's current loop) ZOH-sampled at the shared velocity period Tv, with every
other axis's velocity loop closed on it by the one lowering of a velocity loop
(:meth:`~sicomat.servo.linear.LoopModel.close_velocity`), from A's current reference. The other axes
hold their position: their setpoints are zero (no feedforward). Their position loops:

* one that runs at Tv (``position_period = velocity_period``) is an LTI element at Tv: it is closed in
  that plant (its P law on the measured position and its computation delay), so A's velocity loop sees
  the other axis's whole cascade;
* a slower one (``Tp = Np·Tv``, the usual CNC) samples and holds at Tp: closed around A's velocity loop
  it would make that loop periodic, not LTI at Tv, with no exact frequency response. A's **velocity
  loop** is analysed with it open (the other axis's velocity command held at zero, as A's own position
  loop is open in the velocity analysis of one axis); A's **position loop** (lifted to Tp) closes it
  after lifting, exactly, when it runs at A's position period — another period is refused
  (:class:`~sicomat.errors.ModelError` naming the axes and periods).

Decisions: ``docs/servo.md``, "Coupled axes".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .blocks import linear_law
from .linear import LoopModel, _Affine, _Builder, lifted
from ..errors import ModelError
from ..lti.response import zoh_matrices

if TYPE_CHECKING:  # pragma: no cover
    from .coupled import CoupledLoop
    from .loop import ServoLoop
    from .stability import Verdict

__all__ = ["CoupledAxisModel", "coupled_axis_model", "closed_partners", "coupled_verdict"]


@dataclass(frozen=True, eq=False)
class CoupledAxisModel(LoopModel):
    """The linear model of axis ``loop.axis`` of coupled loops, the other axes' loops closed (module
    docstring). ``Phi``/``Gamma`` are the sampled plant with the others closed (inputs: the axis's current
    reference, then each slow partner's velocity command); ``c_pos``/``c_vel`` the axis's sensors on it.

    Attributes
    ----------
    coupled : CoupledLoop
    slow : tuple of (ServoLoop, ndarray)
        The partners whose position loop runs slower than Tv, each with its measured position (axis
        units) as a row over the plant's states; their commands are ``Gamma``'s columns ``1, 2, …``.
    """

    coupled: "CoupledLoop | None" = None
    slow: tuple = ()

    def position_model(self, Kp: float, Ti: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The closed velocity loops lifted to the axis's position period, each slow partner's position
        loop (its P law and computation delay) closed at that period: inputs (the axis's velocity command,
        feedforward effort), outputs (its measured position, velocity), as for one axis.

        Raises
        ------
        ModelError
            A slow partner's position period is not the axis's: the lifted loop would not be LTI.
        """
        loop = self.loop
        Tp = loop.controller.position_period
        other = [(p.axis, p.controller.position_period) for p, _ in self.slow
                 if abs(p.controller.position_period - Tp) > 1e-12 * Tp]
        if other:
            listed = ", ".join(f"{axis} {period:g} s" for axis, period in [(loop.axis, Tp), *other])
            raise ModelError(f"the position loop of axis {loop.axis} with the other loops closed needs every "
                             f"position loop slower than the velocity period ({loop.controller.velocity_period:g} "
                             f"s) at its own period: {listed} (sampled at another period, the loop is periodic, "
                             f"not LTI, and has no exact frequency response)",
                             path=f"axes.{other[0][0]}.controller.position_period", value=other[0][1])
        A, B, C = self.velocity_closed_loop(Kp, Ti)
        Ap, Bp = lifted(A, B, loop.position_ratio)
        n = Ap.shape[0]
        delays = [partner.controller.position_delay for partner, _ in self.slow]
        size = n + sum(delays)
        from ..budget import require_dense

        require_dense(size, "the lifted position loop of coupled axes", "one state per sample of a position_delay")
        Acl = np.zeros((size, size))
        Acl[:n, :n] = Ap
        offset = n
        for j, ((partner, row), d) in enumerate(zip(self.slow, delays)):
            b = Bp[:, 2 + j]
            c = np.zeros(n)
            c[: row.size] = row
            if d == 0:                   # v = Kv (0 − y) now
                Acl[:n, :n] -= partner.Kv * np.outer(b, c)
            else:                        # q_1 ← −Kv y, q_i ← q_{i−1}, v = q_d
                Acl[:n, offset + d - 1] += b
                Acl[offset, :n] = -partner.Kv * c
                for i in range(1, d):
                    Acl[offset + i, offset + i - 1] = 1.0
            offset += d
        Bcl = np.zeros((size, 2))
        Bcl[:n] = Bp[:, :2]
        Ccl = np.zeros((C.shape[0], size))
        Ccl[:, :n] = C
        return Acl, Bcl, Ccl


def _sensor_rows(loop: "ServoLoop", plant, mech) -> tuple[np.ndarray, np.ndarray, bool]:
    """An axis's position- and velocity-sensor rows in ``plant`` (of the coupled mechanics ``mech``) and
    whether its velocity is differenced."""
    ctrl = loop.controller
    name = ctrl.velocity_sensor or ctrl.position_sensor
    kind = mech.sensor(name).kind
    return (plant.C[plant.outputs.index(f"sensor.{ctrl.position_sensor}")],
            plant.C[plant.outputs.index(f"sensor.{name}")], kind == "position")


def closed_partners(coupled: "CoupledLoop", axis: str) -> dict[str, dict[str, list[str]]]:
    """What the analysis of ``axis`` closes of the other axes, per analysed loop: ``{"velocity":
    {"closed": ["Y.velocity", "Y.position"], "open": []}, "position": {...}}`` (module docstring)."""
    out: dict[str, dict[str, list[str]]] = {"velocity": {"closed": [], "open": []},
                                            "position": {"closed": [], "open": []}}
    for partner in coupled.loops:
        if partner.axis == axis:
            continue
        for which in ("velocity", "position"):
            out[which]["closed"].append(f"{partner.axis}.velocity")
        fast = partner.position_ratio == 1
        out["velocity"]["closed" if fast else "open"].append(f"{partner.axis}.position")
        out["position"]["closed"].append(f"{partner.axis}.position")
    return out


def coupled_axis_model(coupled: "CoupledLoop", axis: str) -> CoupledAxisModel:
    """The linear model of ``axis`` of ``coupled`` with the other axes' loops closed (module docstring):
    the coupled plant ZOH-sampled at Tv, every other velocity loop (and each position loop at Tv) closed
    on it by :meth:`~sicomat.servo.linear.LoopModel.close_velocity`, with their gains.

    Raises
    ------
    ModelError
        No such axis; a position loop that is not sampled (``position_loop = "continuous"``).
    """
    from .coupled import coupled_plant

    own = coupled.loop(axis)
    for loop in coupled.loops:
        if loop.controller.position_loop != "discrete":
            raise ModelError("a continuous position loop is not analysed in coupled loops (expected a sampled "
                             "one)", path=f"axes.{loop.axis}.controller.position_loop",
                             value=loop.controller.position_loop)
    plant = coupled_plant(coupled)
    Tv = coupled.base_period
    Phi, Gamma = zoh_matrices(plant.A, plant.B, Tv)
    nx = Phi.shape[0]
    others = [loop for loop in coupled.loops if loop.axis != axis]
    slow = [loop for loop in others if loop.position_ratio > 1]
    parts = []
    capacity = nx
    for loop in others:
        c_pos, c_vel, differenced = _sensor_rows(loop, plant, coupled.mechanics)
        model = LoopModel(loop, Phi, Gamma, c_pos, c_vel, differenced)
        blocks = model._blocks()
        law = linear_law(loop, loop.Kp, loop.Ti)
        parts.append((model, blocks, law))
        capacity += model.controller_states(law, blocks)
        if loop.position_ratio == 1:
            capacity += loop.controller.position_delay
    b = _Builder(capacity, n_inputs=1 + len(slow))
    x = b.block(nx)
    zero = _Affine(np.zeros(capacity), np.zeros(1 + len(slow)))
    signals = {axis: b.input(0)}
    for model, blocks, law in parts:
        loop = model.loop
        if loop.position_ratio > 1:
            command = b.input(1 + slow.index(loop))
        else:                                   # its P law at Tv on its measured position, setpoint 0
            command = b.row(x, model.c_pos) * (-loop.Kv / loop.position_gain)
            d = loop.controller.position_delay
            if d:
                line = b.block(d)
                b.next(line, 0, command)
                for j in range(1, d):
                    b.next(line, j, b.state(line, j - 1))
                command = b.state(line, d - 1)
        signals[loop.axis] = model.close_velocity(b, x, law, blocks, command, zero)[0]
    columns = [plant.inputs.index(f"{name}.current.reference") for name in signals]
    for i in range(nx):
        value = b.row(x, Phi[i])
        for name, k in zip(signals, columns):
            value = value + signals[name] * Gamma[i, k]
        b.next(x, i, value)
    A, B = b.matrices()
    n = A.shape[0]
    c_pos, c_vel, differenced = _sensor_rows(own, plant, coupled.mechanics)
    pad = np.zeros(n - nx)
    rows = []
    for loop in slow:
        row = np.zeros(n)
        row[:nx] = _sensor_rows(loop, plant, coupled.mechanics)[0] / loop.position_gain
        rows.append((loop, row))
    return CoupledAxisModel(own, A, B, np.concatenate([c_pos, pad]), np.concatenate([c_vel, pad]), differenced,
                            False, coupled, tuple(rows))


def coupled_verdict(coupled: "CoupledLoop") -> "Verdict":
    """The stability verdict of coupled loops, all closed: the poles of their linear model
    (:func:`~sicomat.servo.stability.loop_verdict` on the model of the axis with the slowest position loop,
    whose lifted position loop holds every other). ``velocity``: the velocity loops with the position loops
    that run at Tv; ``position``: the whole. Unknown (``None``, with a warning) when position loops slower
    than Tv run at different periods (the lifted loop would not be LTI); unstable when the velocity loops
    already are."""
    from .stability import Verdict, loop_verdict

    slowest = max(coupled.loops, key=lambda loop: loop.position_ratio)
    model = coupled_axis_model(coupled, slowest.axis)
    try:
        return loop_verdict(model.loop, an=model)
    except ModelError as exc:
        velocity = loop_verdict(model.loop, an=model, loops=("velocity",))
        note = (f"the poles of the coupled position loops are not computed ({exc.message}); the verdict is that "
                f"of the velocity loops and of the run")
        return Verdict(False if velocity.stable is False else None, velocity.warnings + (note,), velocity.loops)
