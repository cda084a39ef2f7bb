"""Actuators and sensors geared rigidly to their body (``ratio``, ``stretch``), and the damping the drive-chain
builder gives its springs — each against a closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sicomat.description import LumpedSpec
from sicomat.errors import ModelError
from sicomat.io import machine_from_dict
from sicomat.lti.response import transfer_at
from sicomat.mechanics import build_mechanics
from sicomat.mechanics.modal import modal_analysis
from sicomat.mechanics.statespace import mechanics_plant

LEAD = 0.010 / (2 * math.pi)          # 10 mm per revolution, m/rad
J_MOTOR, J_SCREW, M_TABLE = 7e-4, 1.2e-3, 250.0


def _rigid_lumped(**sensor) -> LumpedSpec:
    m_eq = M_TABLE + (J_MOTOR + J_SCREW) / LEAD ** 2     # J_eq = m·lead² read the other way
    return LumpedSpec.model_validate({
        "bodies": {"table": {"mass": m_eq}},
        "actuators": {"motor": {"body": "table", "ratio": "6.283185307179586 rad/cm", "stretch": "rotational"}},
        "sensors": {"encoder": {"body": "table", "ratio": 1 / LEAD, "stretch": "rotational", **sensor}}})


def test_a_rotary_motor_geared_to_a_translating_body_gives_the_classic_rigid_transfer():
    # a torque T on the motor of a rigid screw axis: (J + m·r²)·θ'' = T with x = r·θ, so x/T = r/((J + m r²)s²)
    # and the motor angle θ/T = 1/((J + m r²)s²). The geared body form has the table as its coordinate.
    mech = build_mechanics(_rigid_lumped())
    assert mech.actuators[0].kind == "rotational" and mech.sensors[0].unit == "rotational"
    assert mech.actuators[0].vector[0] == pytest.approx(1 / LEAD, rel=1e-15)   # "6.28 rad/cm" = 2π/1 cm
    plant = mechanics_plant(mech, dof_outputs=True)
    w = np.array([3.0, 40.0])
    h = transfer_at(plant.A, plant.B, plant.C, plant.D, 1j * w)
    j_total = J_MOTOR + J_SCREW + M_TABLE * LEAD ** 2
    theta = h[plant.outputs.index("encoder"), 0, :]
    x = h[plant.outputs.index("table.x"), 0, :]
    # rounding only: a 2-state double integrator evaluated by LU, relative error a few 1e-16
    np.testing.assert_allclose(theta, -1 / (j_total * w ** 2), rtol=1e-12)
    np.testing.assert_allclose(x, -LEAD / (j_total * w ** 2), rtol=1e-12)


def test_a_geared_encoder_quantizes_in_radians():
    mech = build_mechanics(_rigid_lumped(counts_per_revolution=4096))
    assert mech.sensors[0].step == pytest.approx(2 * math.pi / 4096, rel=1e-15)


def test_a_zero_ratio_and_a_ratio_of_the_wrong_dimension_are_refused():
    with pytest.raises(ModelError, match=r"actuators\.motor\.ratio.*non-zero"):
        machine_from_dict({"axes": {"X": {"mechanics": {"type": "lumped", "bodies": {"t": {"mass": 1}},
                                                         "actuators": {"motor": {"body": "t", "ratio": 0}}}}}})
    with pytest.raises(ModelError, match=r"actuators\.motor\.ratio"):
        machine_from_dict({"axes": {"X": {"mechanics": {"type": "lumped", "bodies": {"t": {"mass": 1}},
                                                         "actuators": {"motor": {"body": "t", "ratio": "3 kg",
                                                                                 "stretch": "rotational"}}}}}})


# --------------------------------------------------------------------------- the builder's damping
def _screw_axis(detail: str, zeta: float = 0.03) -> dict:
    parts = [{"kind": "motor", "rotor_inertia": J_MOTOR},
             {"kind": "coupling", "inertia": 2e-4, "torsional_stiffness": 2.0e4},
             {"kind": "ball-screw", "lead": "10 mm", "diameter": "32 mm", "root_diameter": "25.3 mm",
              "length": "1 m", "mounting": "fixed-supported", "nut_stiffness": "500 N/um",
              "bearing_stiffness": "600 N/um"},
             {"kind": "table", "mass": M_TABLE}]
    return {"axes": {"X": {"mechanics": {"type": "components", "parts": parts, "detail": detail,
                                         "position": "0.6 m", "damping_ratio": zeta}}}}


def test_a_2_mass_chain_has_exactly_the_damping_ratio_asked():
    # one spring k, one damper c = 2ζk/ω between two bodies: the one flexible mode has ω² = k/m_red and
    # ζ = c/(2√(k·m_red)) = ζ exactly; the modal analysis's eigenvalues carry ~1e-15 relative error.
    machine = machine_from_dict(_screw_axis("2-mass"))
    result = modal_analysis(build_mechanics(machine.axes["X"].mechanics))
    flexible = [m for m in result.modes if m.frequency_hz > 0]
    assert len(flexible) == 1
    assert flexible[0].damping_ratio == pytest.approx(0.03, rel=1e-9)


def test_each_full_chain_mode_is_damped_near_the_ratio_asked():
    # stiffness-proportional losses per spring, tuned on the mode that strains it most: that mode gets ζ from
    # its own spring plus ζ·(ω_i/ω_j)·e_ij from the others (e_ij their strain shares), so never less than ζ
    # times its dominant share; the first (control-relevant) mode of a screw axis is dominated by the axial
    # spring (> 90 % of the strain), hence within [0.9 ζ, 1.5 ζ].
    machine = machine_from_dict(_screw_axis("full"))
    result = modal_analysis(build_mechanics(machine.axes["X"].mechanics))
    flexible = [m for m in result.modes if m.frequency_hz > 0]
    assert len(flexible) == 3
    assert 0.9 * 0.03 <= flexible[0].damping_ratio <= 1.5 * 0.03
    assert all(m.damping_ratio >= 0.5 * 0.03 for m in flexible)


def test_sensors_follow_their_body_when_the_detail_lumps_it():
    # motor encoder and a screw-end encoder behind a 5:1 gearbox and a 10 mm lead: in the rigid detail the only
    # body is the table, so the motor angle is x·5·2π/0.01 rad and the screw angle x·2π/0.01 rad; at 2-mass the
    # screw end (compliance share below one half: the stiff gearbox and coupling come first) joins the motor's
    # side, the screw turning at 1/5 of the motor.
    parts = [{"kind": "motor", "rotor_inertia": 7e-4},
             {"kind": "gearbox", "ratio": 5, "input_inertia": 1e-4, "torsional_stiffness": 3e4},
             {"kind": "coupling", "inertia": 1e-4, "torsional_stiffness": 2e4},
             {"kind": "ball-screw", "lead": "10 mm", "diameter": "32 mm", "root_diameter": "25.3 mm", "length": "1 m",
              "mounting": "fixed-fixed", "nut_stiffness": 5e8, "bearing_stiffness": 6e8},
             {"kind": "table", "mass": 250}, {"kind": "encoder", "resolution": 4096},
             {"kind": "encoder", "resolution": 1000, "mounting": "load", "name": "screw_end"}]

    def sensors(detail):
        m = machine_from_dict({"axes": {"X": {"mechanics": {"type": "components", "parts": parts, "detail": detail}}}})
        return {s.name: s for s in build_mechanics(m.axes["X"].mechanics).sensors}

    rigid = sensors("rigid")
    assert rigid["encoder"].vector.tolist() == pytest.approx([5 * 2 * math.pi / 0.010], rel=1e-14)
    assert rigid["screw_end"].vector.tolist() == pytest.approx([2 * math.pi / 0.010], rel=1e-14)
    assert rigid["encoder"].unit == "rotational"
    two = sensors("2-mass")
    assert two["screw_end"].vector.tolist() == pytest.approx([0.2, 0.0], rel=1e-14)
    full = sensors("full")
    assert full["screw_end"].vector.tolist() == [0.0, 0.0, 0.0, 1.0, 0.0]   # the screw at the nut


def test_a_copied_or_pickled_drive_chain_derives_its_own_chain():
    # model_copy(update=...) does not validate: the derived chain must follow the copy's fields, not the
    # original's; a pickled machine (Dask ships them to workers) must load with its part classes
    import pickle

    machine = machine_from_dict(_screw_axis("full"))
    spec = machine.axes["X"].mechanics
    moved = spec.model_copy(update={"position": 0.9})
    assert spec.chain.position == 0.6 and moved.chain.position == 0.9
    axial = {s.name: s.stiffness for s in moved.chain.springs}["screw_axial"]
    assert axial < {s.name: s.stiffness for s in spec.chain.springs}["screw_axial"]   # A·E/x: softer further out
    again = pickle.loads(pickle.dumps(machine))
    assert again == machine and again.axes["X"].mechanics.chain.position == 0.6
