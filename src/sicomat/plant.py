"""Continuous LTI plants with named states, inputs and outputs (python-control interop)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable

import numpy as np

from .errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    import control

    from .mechanics import Mechanics

__all__ = ["Plant", "mechanics_plant"]


@dataclass(frozen=True, eq=False)
class Plant:
    """``ż = A z + B u``, ``y = C z + D u`` with named signals (SI units).

    Attributes
    ----------
    A, B, C, D : ndarray
        Shapes ``(nx, nx)``, ``(nx, nu)``, ``(ny, nx)``, ``(ny, nu)``; read-only.
    states, inputs, outputs : tuple of str
        Signal names, e.g. ``"load.x"``, ``"motor"``, ``"scale"``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    def __post_init__(self) -> None:
        for name in ("A", "B", "C", "D"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        nx, nu, ny = len(self.states), len(self.inputs), len(self.outputs)
        for name, shape in (("A", (nx, nx)), ("B", (nx, nu)), ("C", (ny, nx)), ("D", (ny, nu))):
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, expected {shape}")

    @property
    def n_states(self) -> int:
        """Number of states."""
        return len(self.states)

    def poles(self) -> np.ndarray:
        """Eigenvalues of A (rad/s), unsorted."""
        return np.linalg.eigvals(self.A)

    def to_control(self) -> "control.StateSpace":
        """The plant as a python-control ``StateSpace`` with the same signal names.

        python-control reserves ``.`` in input and output names (``subsystem.signal``), so an input
        ``load.force`` becomes ``load_force`` there; state names are kept.
        """
        import control

        def names(items):
            return [name.replace(".", "_") for name in items]

        return control.ss(self.A, self.B, self.C, self.D, states=list(self.states),
                          inputs=names(self.inputs), outputs=names(self.outputs))

    def select(self, inputs: Iterable[str] | None = None, outputs: Iterable[str] | None = None) -> "Plant":
        """The sub-plant from some inputs to some outputs, by name."""
        ins = list(self.inputs if inputs is None else inputs)
        outs = list(self.outputs if outputs is None else outputs)
        for kind, names, known in (("input", ins, self.inputs), ("output", outs, self.outputs)):
            unknown = [n for n in names if n not in known]
            if unknown:
                raise ModelError(f"unknown {kind} {unknown[0]!r}; expected one of {', '.join(known)}")
        i = [self.inputs.index(n) for n in ins]
        o = [self.outputs.index(n) for n in outs]
        return Plant(self.A, self.B[:, i], self.C[o, :], self.D[np.ix_(o, i)], self.states,
                     tuple(ins), tuple(outs))


def mechanics_plant(mech: "Mechanics", *, forces_on: Iterable[str] = (), dof_outputs: bool = False) -> Plant:
    """The state space of eqs. (11)–(12): ``z = (q, q̇)``.

    The paper prints ``z = (Ẋ, X)`` but its A and B of eq. (12) are those of ``z = (X, Ẋ)``;
    we follow A and B (see ``docs/mechanics.md``).

    Parameters
    ----------
    mech : Mechanics
        The lumped model.
    forces_on : iterable of str, optional
        Bodies that also get an external load input, named ``"<body>.force"`` or ``"<body>.torque"``
        (for compliance and disturbance transfers).
    dof_outputs : bool, optional
        Also output every state (``"<body>.v"``, ``"<body>.x"``, ...).

    Returns
    -------
    Plant
        Inputs: the actuators, then the external loads. Outputs: the sensors (position sensors read
        ``q``, velocity sensors ``q̇``), then the states if ``dof_outputs``.

    Examples
    --------
    >>> from sicomat.model import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = mechanics_plant(build_mechanics(ChainSpec(type="chain", masses=[2.0])))
    >>> plant.states, plant.inputs, plant.outputs
    (('m1.x', 'm1.v'), ('motor',), ('first', 'last'))
    >>> plant.B.ravel().tolist()
    [0.0, 0.5]
    """
    n = mech.n
    m_inv = np.diag(1.0 / np.diag(mech.mass))  # lumped bodies: M is diagonal
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-m_inv @ mech.stiffness, -m_inv @ mech.damping]])
    columns = [a.vector for a in mech.actuators]
    inputs = [a.name for a in mech.actuators]
    for body in forces_on:
        if body not in mech.dof_names:
            raise ModelError(f"unknown body {body!r}; expected one of {', '.join(mech.dof_names)}")
        vector = np.zeros(n)
        vector[mech.index(body)] = 1.0
        columns.append(vector)
        inputs.append(mech.dofs[mech.index(body)].load)
    Fu = np.column_stack(columns) if columns else np.zeros((n, 0))
    B = np.vstack([np.zeros((n, Fu.shape[1])), m_inv @ Fu])
    rows, outputs = [], []
    for s in mech.sensors:
        rows.append(np.concatenate([np.zeros(n), s.vector]) if s.kind == "velocity"
                    else np.concatenate([s.vector, np.zeros(n)]))
        outputs.append(s.name)
    states = [d.position for d in mech.dofs] + [d.velocity for d in mech.dofs]
    if dof_outputs:
        rows.extend(np.eye(2 * n))
        outputs.extend(states)
    C = np.array(rows).reshape(len(rows), 2 * n)
    return Plant(A, B, C, np.zeros((len(outputs), len(inputs))), tuple(states), tuple(inputs), tuple(outputs))
