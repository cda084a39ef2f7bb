"""Symbolic models of an :class:`~sicomat.robotics.MDHRobot` (SymPy), SYMORO's way: the frame
transforms ``0T_j``, the inverse dynamic model (Newton–Euler) and the inertia matrix (composite links),
each a sequence of named intermediate assignments followed by its outputs.

Symbol policy (the robot's numbers decide what is a symbol):

- joint variables ``q1..qn``, ``qd1..``, ``qdd1..``, numbered by joint (1-based, frame order, fixed
  frames skipped);
- a geometric constant (``gamma b alpha d theta r`` of frame j) that is exactly 0 vanishes, an angle that
  is a multiple of pi/2 (to 1e-12 rad) becomes exact (so its cos and sin are 0 or ±1), any other one is
  a symbol named after its field and frame (``d3``, ``r4``, ``alpha2``);
- a dynamic parameter (``XX1 .. FS1``, frame number) is a symbol unless it is exactly 0, then it is 0;
- gravity components ``G1 G2 G3``, a zero one dropped.

Intermediates are named while the recursions run, as SYMORO's symbol manager does: every entry of a
frame's ``w, wd, vd, U, F, N``, totals, composite inertias and transforms that is not a number or a
single symbol becomes a named symbol (``C2 = cos(q2)``, ``WP3z``, ``U2xy``, ``FT4x``...), the same
expression getting the same name. So no expression is ever large, and :func:`sympy.cse` over the whole
sequence only has to find the products shared between entries (named ``x1, x2...``). Unused
intermediates are dropped. Nothing iterates over a set or a hash-ordered dict, so the output does not
depend on ``PYTHONHASHSEED``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
import sympy

from ._symbolic_programs import Equations, Policy, composite_program, newton_euler_program, transforms_program

if TYPE_CHECKING:
    from .table import MDHRobot

__all__ = ["SymbolicModel", "SymbolicModels", "symbolic_models"]


@dataclass(frozen=True, eq=False)
class SymbolicModel:
    """One model as a straight-line program: ``assignments`` in order, then ``outputs``.

    Attributes
    ----------
    name : str
        ``"transforms"``, ``"inverse_dynamics"``, ``"inertia_matrix"`` or ``"gravity_torques"``.
    arguments : tuple of str
        The argument names of the generated functions, in order (``("q", "qd", "qdd", "p")``...).
    inputs : tuple of tuple of Symbol
        The symbols each argument holds, in order (``p``: the parameters, all of them).
    assignments : tuple of (Symbol, Expr)
        Intermediates, each defined from the inputs and the intermediates before it.
    outputs : tuple of (str, Expr)
        Named outputs (``tau1``, ``A1_2``, ``T3_14``) in terms of inputs and intermediates.
    shape : tuple of int
        Shape of the output array (``(n,)``, ``(n, n)``, ``(NF + 1, 4, 4)``), outputs row-major.
    """

    name: str
    arguments: tuple[str, ...]
    inputs: tuple[tuple[sympy.Symbol, ...], ...]
    assignments: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    outputs: tuple[tuple[str, sympy.Expr], ...]
    shape: tuple[int, ...]

    def expressions(self) -> list[sympy.Expr]:
        """The outputs with every intermediate substituted (in terms of inputs only; may be long)."""
        full: dict[sympy.Symbol, sympy.Expr] = {}
        for symbol, expr in self.assignments:
            full[symbol] = expr.xreplace(full)
        return [expr.xreplace(full) for _, expr in self.outputs]

    def lambdify(self) -> Callable[..., np.ndarray]:
        """A numeric function of the arguments (sequences, in the order of :attr:`arguments`) returning the
        output array of :attr:`shape`, made by :func:`sympy.lambdify` (``math`` functions) with the
        intermediates as its common subexpressions."""
        function = sympy.lambdify(self.inputs, [e for _, e in self.outputs], modules="math",
                                  cse=lambda exprs: (list(self.assignments), exprs))
        shape = self.shape

        def model(*args: Sequence[float]) -> np.ndarray:
            return np.array(function(*args), dtype=float).reshape(shape)
        return model


@dataclass(frozen=True, eq=False)
class SymbolicModels:
    """The symbolic models of a robot and its symbols (:func:`symbolic_models`).

    Attributes
    ----------
    q, qd, qdd : tuple of Symbol
        Joint positions, velocities, accelerations, by joint.
    parameters : dict of Symbol to float
        Every parameter symbol and its value in the robot, in the order of the ``p`` argument:
        geometry frame by frame (``gamma b alpha d theta r``), then the dynamic parameters frame by
        frame (``XX .. FS``), then ``G1 G2 G3``.
    transforms, inverse_dynamics, inertia_matrix, gravity_torques : SymbolicModel
        ``0T_j`` for j = 0..NF, ``tau`` (n), ``A`` (n x n, both triangles written), the gravity torques
        ``Q(q)`` (n, the inverse dynamics at ``qd = qdd = 0``).
    """

    q: tuple[sympy.Symbol, ...]
    qd: tuple[sympy.Symbol, ...]
    qdd: tuple[sympy.Symbol, ...]
    parameters: dict[sympy.Symbol, float]
    transforms: SymbolicModel
    inverse_dynamics: SymbolicModel
    inertia_matrix: SymbolicModel
    gravity_torques: SymbolicModel

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the ``p`` argument's entries, in order."""
        return tuple(s.name for s in self.parameters)

    @property
    def models(self) -> tuple[SymbolicModel, ...]:
        """The four models, in the order the exported files hold them."""
        return self.transforms, self.inverse_dynamics, self.inertia_matrix, self.gravity_torques


def _finish(name: str, arguments: tuple[str, ...], inputs: tuple[tuple[sympy.Symbol, ...], ...], eq: Equations,
            outputs: list[tuple[str, sympy.Expr]], shape: tuple[int, ...]) -> SymbolicModel:
    """Drop the unused intermediates, then name the products shared between entries (:func:`sympy.cse`)."""
    needed: set[sympy.Symbol] = set()
    for _, expr in outputs:
        needed |= expr.free_symbols
    kept = []
    for symbol, expr in reversed(eq.assignments):
        if symbol in needed:
            kept.append((symbol, expr))
            needed |= expr.free_symbols
    kept.reverse()
    exprs = [e for _, e in kept] + [e for _, e in outputs]
    replacements, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols("x", cls=sympy.Symbol, start=1,
                                                                             real=True))
    # a shared -C1 or a bare symbol is no product worth a name: put it back in place
    inline = {s: e for s, e in replacements if e.is_Atom or (-e).is_Atom}
    shared = {s: e.xreplace(inline) for s, e in replacements if s not in inline}
    reduced = [e.xreplace(inline) for e in reduced]
    placed: set[sympy.Symbol] = set()
    program: list[tuple[sympy.Symbol, sympy.Expr]] = []

    def place(expr: sympy.Expr) -> None:
        """Put each shared product just before its first use (its own operands are defined by then)."""
        for atom in sorted(expr.atoms(sympy.Symbol), key=lambda s: s.name):
            if atom in shared and atom not in placed:
                place(shared[atom])
                placed.add(atom)
                program.append((atom, shared[atom]))

    for (symbol, _), expr in zip(kept, reduced):
        place(expr)
        program.append((symbol, expr))
    final = []
    for (label, _), expr in zip(outputs, reduced[len(kept):]):
        place(expr)
        final.append((label, expr))
    return SymbolicModel(name, arguments, inputs, tuple(program), tuple(final), shape)


def symbolic_models(robot: "MDHRobot") -> SymbolicModels:
    """The transforms, inverse dynamic model, inertia matrix and gravity torques of a robot, symbolic (SymPy).

    Parameters
    ----------
    robot : MDHRobot
        Its numbers decide the symbol policy (module docstring): zeros vanish, right angles are exact,
        other constants and the nonzero dynamic parameters are symbols whose values are kept in
        :attr:`SymbolicModels.parameters`.

    Returns
    -------
    SymbolicModels
        Each model a straight-line program of named intermediates; evaluated at the robot's parameters
        they equal :meth:`MDHRobot.transforms`, :meth:`MDHRobot.inverse_dynamics` (gravity, ``IA``,
        ``FV``, ``FS sign(qd)`` with ``sign(0) = 0``) and :meth:`MDHRobot.inertia_matrix`.

    Examples
    --------
    A 2 kg slide on a vertical axis: ``tau1 = M1 (qdd1 - G3)``, through two named intermediates.

    >>> from sicomat.robotics import MDHRobot
    >>> models = symbolic_models(MDHRobot.from_table([{"ant": 0, "sigma": 1, "M": 2.0}]))
    >>> models.inverse_dynamics.assignments, models.inverse_dynamics.outputs
    (((VP1z, -G3 + qdd1), (F1z, M1*VP1z)), (('tau1', F1z),))
    >>> models.parameters
    {M1: 2.0, G3: -9.81}
    """
    policy = Policy(robot)
    nf, n = robot.n_frames, robot.n_joints
    p = tuple(policy.parameters)
    t_eq, t_out = transforms_program(policy)
    d_eq, d_out = newton_euler_program(policy)
    a_eq, a_out = composite_program(policy)
    g_eq, g_out = newton_euler_program(policy, at_rest=True)
    return SymbolicModels(
        q=policy.q, qd=policy.qd, qdd=policy.qdd, parameters=dict(policy.parameters),
        transforms=_finish("transforms", ("q", "p"), (policy.q, p), t_eq, t_out, (nf + 1, 4, 4)),
        inverse_dynamics=_finish("inverse_dynamics", ("q", "qd", "qdd", "p"),
                                 (policy.q, policy.qd, policy.qdd, p), d_eq, d_out, (n,)),
        inertia_matrix=_finish("inertia_matrix", ("q", "p"), (policy.q, p), a_eq, a_out, (n, n)),
        gravity_torques=_finish("gravity_torques", ("q", "p"), (policy.q, p), g_eq,
                                [(f"Q{k + 1}", e) for k, (_, e) in enumerate(g_out)], (n,)))
