"""Builders that lower the common axis shapes (nMmS chain, the paper's Fig. 3 belt-rack axis) to lumped models."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from .model import BeltRackSpec, ChainSpec, LumpedSpec

__all__ = ["chain_to_lumped", "belt_rack_to_lumped", "belt_rack_equivalents"]


def chain_to_lumped(spec: "ChainSpec") -> "LumpedSpec":
    """Lower an nMmS chain to the general lumped form.

    Body i and i+1 are joined by spring i (stiffness ``stiffnesses[i]``, damping ``dampings[i]``);
    actuator ``motor`` pushes the first body against the ground; sensors ``first`` and ``last``
    read the end positions.
    """
    from .model import LumpedSpec

    n = len(spec.masses)
    names = spec.names or [f"m{i + 1}" for i in range(n)]
    dampings = spec.dampings or [0.0] * (n - 1)
    bodies = {name: {"mass": m} for name, m in zip(names, spec.masses)}
    couplings = {f"k{i + 1}": {"between": [names[i], names[i + 1]], "stiffness": k, "damping": d}
                 for i, (k, d) in enumerate(zip(spec.stiffnesses, dampings))}
    if spec.ground_stiffness > 0:
        couplings["k0"] = {"between": [names[0], "ground"], "stiffness": spec.ground_stiffness}
    frictions = {}
    if spec.viscous is not None:
        frictions = {f"{name}_guide": {"between": [name, "ground"], "viscous": c}
                     for name, c in zip(names, spec.viscous) if c > 0}
    sensors = {"first": {"body": names[0]}, "last": {"body": names[-1]}}
    return LumpedSpec(bodies=bodies, couplings=couplings, frictions=frictions,
                      actuators={"motor": {"body": names[0]}}, sensors=sensors)


def belt_rack_equivalents(spec: "BeltRackSpec") -> dict[str, float]:
    """The equivalent parameters of the paper's eqs. (5)–(9) for the Fig. 3 axis.

    Returns
    -------
    dict
        ``J11eq`` (kg·m², eq. 7), ``M12eq`` (kg, eq. 6), ``n_b`` (belt ratio R_pc/R_pm) and
        ``ratio`` = R_pig/n_b (m/rad): the load moves ``ratio * theta_m`` when the belt is rigid.
    """
    n_b = spec.R_pc / spec.R_pm
    return {
        "J11eq": spec.J_m + spec.J_am + spec.J_pm + spec.m_c * spec.R_pm ** 2,
        "M12eq": spec.m_cre + spec.M_load + (spec.J_pig + spec.J_apig + spec.J_pc) / spec.R_pig ** 2,
        "n_b": n_b,
        "ratio": spec.R_pig / n_b,
    }


def belt_rack_to_lumped(spec: "BeltRackSpec") -> "LumpedSpec":
    """Lower the Fig. 3 axis to bodies ``motor`` (θ_m) and ``load`` (x_M).

    The transmission spring acts on the stretch ``(R_pig/n_b)·θ_m − x_M`` with the linear stiffness
    ``k11eq`` (N/m) and the damping ``f11eq`` (N·s/m); ``mu11eq`` (N·m·s/rad) and ``mu12eq`` (N·s/m)
    act from the motor and the load to the frame. This reproduces the printed eqs. (8) and (9)
    exactly; ``docs/mechanics.md`` explains how it reads the paper's parameter names.
    """
    from .model import LumpedSpec

    eq = belt_rack_equivalents(spec)
    frictions = {}
    if spec.mu11eq > 0 or spec.coulomb_motor > 0:
        frictions["motor_bearings"] = {"between": ["motor", "ground"], "viscous": spec.mu11eq,
                                       "coulomb": spec.coulomb_motor}
    if spec.mu12eq > 0 or spec.coulomb_load > 0:
        frictions["load_guides"] = {"between": ["load", "ground"], "viscous": spec.mu12eq,
                                    "coulomb": spec.coulomb_load}
    return LumpedSpec(
        bodies={"motor": {"inertia": eq["J11eq"]}, "load": {"mass": eq["M12eq"]}},
        couplings={"transmission": {"between": ["motor", "load"], "ratios": [eq["ratio"], 1.0],
                                    "stiffness": spec.k11eq, "damping": spec.f11eq}},
        frictions=frictions,
        actuators={"motor": {"body": "motor"}},
        sensors={"encoder": {"body": "motor"}, "scale": {"body": "load"}},
    )
