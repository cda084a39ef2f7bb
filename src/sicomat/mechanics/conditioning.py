"""Whether a mechanics' numbers mean anything in double precision: coefficient range, pole accuracy.

Two checks, both on the model as given (so a message names couplings and bodies, not numbers): the
range in :func:`~sicomat.mechanics.build_mechanics`, the poles in :func:`~sicomat.mechanics.modal.modal_analysis`,
:func:`~sicomat.servo.loop.build_servo_loop` and the ``check`` and ``reduce`` commands
(:func:`check_axis_mechanics`).

* **Range.** Every mass, inertia, stiffness, damping and friction coefficient must lie in
  [1e-100, 1e100]. The analyses form products of up to three of them (``m·ω²``, the loop's
  ``Kp·Kv`` with the rigid mass, 2×2 determinants of the state matrix); three factors within
  that range stay between 1e-300 and 1e300, inside the normal doubles (2.2e-308 … 1.8e308).
* **Resolvable poles.** The poles come from one eigenproblem of the state matrix. LAPACK returns
  each pole λ with an error of at most about ``κ·ε·‖A‖`` (first-order perturbation bound: κ the
  pole's condition number, ε the machine epsilon, ``A`` the balanced state matrix). Springs of
  very different stiffness-to-mass ratios (1e30 N/m beside 1e7 N/m) make that bound exceed the
  soft poles themselves: the computed pole then carries no correct digit (its damping ratio can
  come out negative, its damped frequency 0 Hz). Such a model is refused. The bound is computed
  only when a cheap estimate says it may matter: ``ε·(ω²_max/ω²_min)`` over the springs' own
  ``k·gᵀM⁻¹g`` (``k·Σ g²/m`` for lumped bodies) above 1e-6 (the 5M4S: 1e-12).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from .lumped import Mechanics

__all__ = ["check_numeric_range", "check_resolvable", "COEFFICIENT_RANGE"]

EPS = float(np.finfo(float).eps)
COEFFICIENT_RANGE = (1e-100, 1e100)   # as sicomat.description.units.MAGNITUDES, for mechanics built in Python
_RISK = 1e-6


def check_numeric_range(values: dict[str, float]) -> None:
    """Refuse a non-zero coefficient outside :data:`COEFFICIENT_RANGE` (``values``: key → value).

    Examples
    --------
    >>> check_numeric_range({"bodies.table.mass": 150.0})
    >>> check_numeric_range({"bodies.table.mass": 1e300})
    Traceback (most recent call last):
    ...
    sicomat.errors.ModelError: mechanics.bodies.table.mass: this value is too large ...
    """
    low, high = COEFFICIENT_RANGE
    for key, value in values.items():
        if value != 0 and not low <= abs(value) <= high:
            side = "large" if abs(value) > high else "small"
            raise ModelError(f"this value is too {side} to compute with in double precision: products of "
                             f"three model values must stay finite, so every value lies in [{low:g}, {high:g}] "
                             "in SI units", path=f"mechanics.{key}", value=value)


def check_resolvable(mech: "Mechanics") -> None:
    """Refuse a mechanics whose flexible poles double precision cannot resolve (see the module)."""
    springs = [link for link in mech.couplings if link.stiffness > 0]
    if len(springs) < 2:
        return
    G = np.array([link.g for link in springs])
    inverse_mass_g = mech.mass_factor.solve(G.T).T         # rows M⁻¹ g (g / m for lumped bodies)
    local = np.array([link.stiffness for link in springs]) * np.sum(G * inverse_mass_g, axis=1)   # k gᵀM⁻¹g
    stiff, soft = int(np.argmax(local)), int(np.argmin(local))
    if not EPS * local[stiff] / local[soft] > _RISK:
        return
    import scipy.linalg

    A = mech.state_space().A
    balanced, _ = scipy.linalg.matrix_balance(A)
    poles, left, right = scipy.linalg.eig(balanced, left=True, right=True)
    kappa = np.linalg.norm(left, axis=0) * np.linalg.norm(right, axis=0) / \
        np.maximum(np.abs(np.sum(left.conj() * right, axis=0)), np.finfo(float).tiny)
    bound = kappa * EPS * np.linalg.norm(balanced, 2)
    order = np.argsort(np.abs(poles))
    r = mech.rigid_modes().shape[1]
    flexible = order[2 * r:]               # a rigid motion is a double pole at 0: not a mode to resolve
    if flexible.size and np.any(~np.isfinite(poles[flexible]) | (bound[flexible] >= np.abs(poles[flexible]))):
        a, b = springs[stiff].name, springs[soft].name
        raise ModelError(f"couplings {a!r} and {b!r} differ too much in stiffness (for the masses they join) "
                         "for double precision: the error bound of the soft poles exceeds the poles "
                         "themselves, so their frequencies and damping ratios would carry no correct digit; "
                         "make the stiff coupling rigid (merge its bodies) or bring the values closer",
                         path=f"mechanics.couplings.{a}.stiffness")

