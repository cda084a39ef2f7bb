"""Coupled axes (several servo loops on one mechanics, servo/coupled.py, simulation/coupled.py): against the
single-axis runs when nothing couples them, against an independently written discrete closed loop when a full
mass matrix does, and the errors of a bad coupling."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from sicomat import machine_from_dict
from sicomat.errors import ModelError
from sicomat.mechanics.lumped import Link, Load, Measurement, Mechanics
from sicomat.motion.setpoints import step_profile, trapezoid_profile
from sicomat.servo.coupled import CoupledLoop, coupled_plant, coupled_program
from sicomat.servo.loop import SetpointTable, build_servo_loop
from sicomat.simulation import simulate
from sicomat.simulation.coupled import simulate_coupled

H = 2.0e-4
KT, TAU = 50.0, 2.0e-4


def _axis(name: str, masses: dict[str, float], *, spring: tuple[str, str, float, float] | None = None,
          actuator: str, sensor: str, friction: float = 0.0, resolution: float | None = None,
          **controller) -> dict:
    """One axis of a model file: lumped bodies, an optional spring, actuator, scale, drive, P-PI."""
    mech: dict = {"type": "lumped", "bodies": {b: {"mass": m} for b, m in masses.items()},
                  "actuators": {f"{name}_motor": {"body": actuator}},
                  "sensors": {f"{name}_scale": {"body": sensor, **({"resolution": resolution} if resolution else {})}}}
    if spring:
        mech["couplings"] = {f"{name}_spring": {"between": [spring[0], spring[1]], "stiffness": spring[2],
                                                "damping": spring[3]}}
    if friction:
        mech["frictions"] = {f"{name}_guides": {"between": [sensor, "ground"], "coulomb": friction, "viscous": 20.0}}
    drive = controller.pop("drive", {})
    ctrl = {"position_sensor": f"{name}_scale", "Kv": 40.0, "Kp_normalized": 300.0, "Ti": 0.01,
            "position_period": H, "velocity_period": H, "velocity_delay": 0, "position_delay": 0, **controller}
    return {"mechanics": mech, "drive": {"force_constant": KT, "time_constant": TAU, **drive},
            "controller": ctrl}


def _pad(vector: np.ndarray, before: int, after: int) -> np.ndarray:
    return np.concatenate([np.zeros(before), vector, np.zeros(after)])


def _stacked(*mechs: Mechanics) -> Mechanics:
    """The block-diagonal mechanics of independent ones: nothing couples them."""
    sizes = [m.n for m in mechs]
    total = sum(sizes)
    acts, sensors, couplings, frictions = [], [], [], []
    for k, m in enumerate(mechs):
        before = sum(sizes[:k])
        after = total - before - m.n
        acts += [Load(a.name, _pad(a.vector, before, after), a.kind) for a in m.actuators]
        sensors += [Measurement(s.name, _pad(s.vector, before, after), s.kind, s.unit, s.step) for s in m.sensors]
        couplings += [Link(c.name, _pad(c.g, before, after), c.kind, c.stiffness, c.damping) for c in m.couplings]
        frictions += [Link(f.name, _pad(f.g, before, after), f.kind, f.stiffness, f.damping, f.coulomb, f.static)
                      for f in m.frictions]
    return Mechanics.from_matrices([d for m in mechs for d in m.dofs],
                                   scipy.linalg.block_diag(*(m.mass for m in mechs)),
                                   scipy.linalg.block_diag(*(m.damping for m in mechs)),
                                   scipy.linalg.block_diag(*(m.stiffness for m in mechs)),
                                   actuators=acts, sensors=sensors, couplings=couplings, frictions=frictions)


def _two_axes(friction: float = 0.0, peak_current: float | None = None, **controller):
    """Axis X: motor and table on a spring, scale on the table; axis Y: one rigid mass."""
    drive = {"drive": {"peak_current": peak_current}} if peak_current else {}
    return machine_from_dict({"axes": {
        "X": _axis("X", {"xm": 10.0, "xt": 30.0}, spring=("xm", "xt", 2e6, 500.0), actuator="xm", sensor="xt",
                   friction=friction, **drive, **controller),
        "Y": _axis("Y", {"yt": 20.0}, actuator="yt", sensor="yt", friction=2 * friction / 3, **drive, **controller)}})


# a following error is a small difference of large positions: its scale is the setpoint's (and so on)
_REFERENCE_SCALE = {"following_error": "setpoint.fine", "tool_error": "setpoint.fine",
                    "position.error": "setpoint.position", "velocity.error": "velocity.command",
                    "velocity.error_gated": "velocity.command"}


@pytest.mark.parametrize("nonlinear,friction", [(False, 0.0), (True, 0.0), (True, 30.0)])
def test_uncoupled_axes_run_as_the_single_axis_runs(nonlinear, friction):
    machine = _two_axes(friction, peak_current=20.0)
    loops = [build_servo_loop(machine, axis) for axis in ("X", "Y")]
    coupled = CoupledLoop(_stacked(*(loop.mechanics for loop in loops)), tuple(loops))
    np.testing.assert_array_equal(coupled.tools["X"], [0.0, 1.0, 0.0])     # carried over by dof name
    profiles = {"X": trapezoid_profile(5e-3, 0.1, 2.0), "Y": trapezoid_profile(-3e-3, 0.05, 1.0, start=0.01)}
    run = simulate_coupled(coupled, profiles, 0.1, nonlinear=nonlinear)
    for loop in loops:
        single = simulate(loop, profiles[loop.axis], 0.1, nonlinear=nonlinear)
        series = run[loop.axis]
        assert set(single.names) <= set(series.names)
        # every signal of the single-axis run, within 1e-12 of its scale. Without friction the two runs are even
        # bit-identical here: the block-diagonal continuous part is discretised by the same products (the other
        # block adds exact zeros). With friction the in-step event bounds come from the Schur form of the whole
        # continuous part: other roundings of the sub-step decisions, ~1e-13..1e-12 of the signals' scale
        for name in single.names:
            scale = np.max(np.abs(single[_REFERENCE_SCALE.get(name, name)]))
            np.testing.assert_allclose(series[name], single[name], rtol=0, atol=1e-12 * scale, err_msg=name)
        assert series.metrics.max_following_error == pytest.approx(single.metrics.max_following_error, rel=1e-9)
        assert series.info["axis"] == loop.axis and series.info["samples"] == single.info["samples"]
    # the coupled mechanics' own signals: every dof and sensor, the friction forces
    assert {"xm.x", "xt.v", "yt.x", "sensor.X_scale", "sensor.Y_scale"} <= set(run.mechanics.names)
    assert ("friction.X_guides" in run.mechanics.names) == (nonlinear and friction > 0)
