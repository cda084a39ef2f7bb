"""Shorthands for common axis shapes and their lowering to the lumped form: the nMmS chain and
the paper's Fig. 3 belt-rack axis (eqs. 5–9)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field, model_validator

from .base import (Inertia, Length, LinearDamping, LinearStiffness, Mass, Name, NonNegativeInertia, NonNegativeMass, Spec, TorsionalDamping, fail, quantity)
from .mechanics import LumpedSpec
from .registry import register

__all__ = ["ChainSpec", "BeltRackSpec", "chain_to_lumped", "belt_rack_to_lumped", "belt_rack_equivalents"]


@register("mechanics")
class ChainSpec(Spec):
    """An n-mass / (n−1)-spring chain (nMmS) of translational bodies, driven on its first body.

    Bodies are named ``names`` (default ``m1 … mn``), spring i joins bodies i and i+1. The
    actuator ``motor`` pushes the first body (against the ground); sensors ``first`` and
    ``last`` read the positions of the end bodies. ``ground_stiffness`` optionally ties the
    first body to the ground; ``viscous`` adds viscous friction of each body to the ground.
    """

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "chain", "masses": ["2 kg", 3, 1.5], "stiffnesses": ["1e6 N/m", 2e6], "dampings": [10, 20],
         "viscous": [1, 0, 2]},
        {"type": "chain", "masses": [5], "ground_stiffness": "1e4 N/m", "names": ["table"]}]})

    type: Literal["chain"]
    masses: list[Mass] = Field(min_length=1)
    stiffnesses: list[LinearStiffness] = Field(default_factory=list)
    dampings: list[LinearDamping] | None = None
    viscous: list[LinearDamping] | None = None
    ground_stiffness: LinearStiffness = 0.0
    names: list[Name] | None = None

    @model_validator(mode="after")
    def _lengths(self) -> "ChainSpec":
        n = len(self.masses)
        for key, expected in (("stiffnesses", n - 1), ("dampings", n - 1), ("viscous", n), ("names", n)):
            value = getattr(self, key)
            if value is not None and len(value) != expected and not (key == "stiffnesses" and n == 1 and not value):
                raise fail("expected {expected} entries for {n} masses", key, value, expected=expected, n=n)
        if self.names is not None and len(set(self.names)) != n:
            raise fail("body names must be unique", "names", self.names)
        return self

    def to_lumped(self) -> LumpedSpec:
        """The chain as a :class:`LumpedSpec`."""
        return chain_to_lumped(self)


@register("mechanics")
class BeltRackSpec(Spec):
    """The paper's Fig. 3 axis (2M1S): motor, belt with two wheels, gearwheel and rack, load.

    Parameters are the component values of Section II.C; :func:`sicomat.description.shorthands.belt_rack_to_lumped`
    computes the equivalents of eqs. (5)–(9). See ``docs/mechanics.md`` for the derivation.
    """

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"type": "belt-rack", "J_m": "1.2e-3 kg*m^2", "J_pm": "0.5e-3 kg*m^2", "R_pm": "30 mm", "m_c": "0.4 kg",
         "J_pc": "4.0e-3 kg*m^2", "R_pc": "60 mm", "J_pig": "0.3e-3 kg*m^2", "R_pig": "25 mm", "m_cre": "6 kg",
         "M_load": "180 kg", "k11eq": "2.5e7 N/m", "f11eq": "800 N*s/m", "mu11eq": "2e-4 N*m*s/rad",
         "mu12eq": "150 N*s/m", "coulomb_motor": "0.05 N*m", "coulomb_load": "60 N"}]})

    type: Literal["belt-rack"]
    J_m: Inertia
    J_am: NonNegativeInertia = 0.0
    J_pm: NonNegativeInertia = 0.0
    R_pm: Length
    m_c: NonNegativeMass = 0.0
    J_pc: NonNegativeInertia = 0.0
    R_pc: Length
    J_pig: NonNegativeInertia = 0.0
    J_apig: NonNegativeInertia = 0.0
    R_pig: Length
    m_cre: NonNegativeMass = 0.0
    M_load: Mass
    k11eq: LinearStiffness
    f11eq: LinearDamping = 0.0
    mu11eq: TorsionalDamping = 0.0
    mu12eq: LinearDamping = 0.0
    coulomb_motor: Annotated[float, quantity("torque"), Field(ge=0)] = 0.0
    coulomb_load: Annotated[float, quantity("force"), Field(ge=0)] = 0.0

    def to_lumped(self) -> LumpedSpec:
        """The axis as a :class:`LumpedSpec` with bodies ``motor`` and ``load``."""
        return belt_rack_to_lumped(self)


def chain_to_lumped(spec: "ChainSpec") -> "LumpedSpec":
    """Lower an nMmS chain to the general lumped form.

    Body i and i+1 are joined by spring i (stiffness ``stiffnesses[i]``, damping ``dampings[i]``);
    actuator ``motor`` pushes the first body against the ground; sensors ``first`` and ``last``
    read the end positions.
    """

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
    # validated from plain tables, as a model file's [mechanics] would be
    return LumpedSpec.model_validate({"bodies": bodies, "couplings": couplings, "frictions": frictions,
                                      "actuators": {"motor": {"body": names[0]}}, "sensors": sensors})


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

    eq = belt_rack_equivalents(spec)
    frictions = {}
    if spec.mu11eq > 0 or spec.coulomb_motor > 0:
        frictions["motor_bearings"] = {"between": ["motor", "ground"], "viscous": spec.mu11eq,
                                       "coulomb": spec.coulomb_motor}
    if spec.mu12eq > 0 or spec.coulomb_load > 0:
        frictions["load_guides"] = {"between": ["load", "ground"], "viscous": spec.mu12eq,
                                    "coulomb": spec.coulomb_load}
    return LumpedSpec.model_validate({
        "bodies": {"motor": {"inertia": eq["J11eq"]}, "load": {"mass": eq["M12eq"]}},
        "couplings": {"transmission": {"between": ["motor", "load"], "ratios": [eq["ratio"], 1.0],
                                       "stiffness": spec.k11eq, "damping": spec.f11eq}},
        "frictions": frictions,
        "actuators": {"motor": {"body": "motor"}},
        "sensors": {"encoder": {"body": "motor"}, "scale": {"body": "load"}},
    })
