"""Continuous LTI plants with named states, inputs and outputs (python-control interop)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    import control


__all__ = ["Plant"]


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
