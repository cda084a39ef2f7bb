"""The state space of a lumped mechanics (the paper's eqs. 11–12): z = (q, q̇)."""

from __future__ import annotations

from typing import Iterable

import numpy as np

from ..errors import ModelError
from ..lti.plant import Plant
from .lumped import Mechanics

__all__ = ["mechanics_plant"]


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
    >>> from sicomat.description import ChainSpec
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
