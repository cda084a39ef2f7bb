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


M_MOTOR, M1, M2, COUPLING = 10.0, 30.0, 20.0, 0.6       # axis 2 rides on axis 1: M = [[m1+m2, m2 c], [m2 c, m2]]
K_SPRING, C_SPRING = 2.0e7, 5000.0


def _coupled_axes(**controller):
    """Axis X: a motor driving, through a spring, the body ``a`` that carries axis Y's body ``b``; the inertia
    couples ``a`` and ``b`` (M full). Each loop is built on its decoupled mechanics (the other axis locked)."""
    machine = machine_from_dict({"axes": {
        "X": _axis("X", {"xm": M_MOTOR, "a": M1 + M2}, spring=("xm", "a", K_SPRING, C_SPRING), actuator="xm",
                   sensor="a", **controller),
        "Y": _axis("Y", {"b": M2}, actuator="b", sensor="b", **controller)}})
    loops = (build_servo_loop(machine, "X"), build_servo_loop(machine, "Y"))
    g = np.array([1.0, -1.0, 0.0])
    mass = np.array([[M_MOTOR, 0.0, 0.0], [0.0, M1 + M2, M2 * COUPLING], [0.0, M2 * COUPLING, M2]])
    mech = Mechanics.from_matrices(
        ["xm", "a", "b"], mass, C_SPRING * np.outer(g, g), K_SPRING * np.outer(g, g),
        actuators=[Load("X_motor", np.array([1.0, 0.0, 0.0]), "translational"),
                   Load("Y_motor", np.array([0.0, 0.0, 1.0]), "translational")],
        sensors=[Measurement("X_scale", np.array([0.0, 1.0, 0.0]), "position", "translational"),
                 Measurement("Y_scale", np.array([0.0, 0.0, 1.0]), "position", "translational")],
        couplings=[Link("X_spring", g, "translational", stiffness=K_SPRING, damping=C_SPRING)])
    return CoupledLoop(mech, loops), loops


def _reference_run(coupled: CoupledLoop, profiles, n_steps: int):
    """The coupled closed loop written out independently: the continuous part (M⁻¹ by inversion, both current
    lags) discretised by scipy's cont2discrete (ZOH), then per axis the P position law, the differenced velocity
    and the PI (u = Kp e + z, z += Kp h / Ti e) as difference equations."""
    mech = coupled.mechanics
    Minv = np.linalg.inv(mech.mass)
    A = np.zeros((8, 8))
    A[:3, 3:6] = np.eye(3)
    A[3:6, :3] = -Minv @ mech.stiffness
    A[3:6, 3:6] = -Minv @ mech.damping
    A[3:6, 6] = Minv @ [1.0, 0.0, 0.0] * KT
    A[3:6, 7] = Minv @ [0.0, 0.0, 1.0] * KT
    A[6, 6] = A[7, 7] = -1.0 / TAU
    B = np.zeros((8, 2))
    B[6, 0] = B[7, 1] = 1.0 / TAU
    Phi, Gamma, *_ = scipy.signal.cont2discrete((A, B, np.eye(8), np.zeros((8, 2))), H, method="zoh")
    kp = np.array([loop.Kp for loop in coupled.loops])
    ti = np.array([loop.Ti for loop in coupled.loops])
    kv = np.array([loop.Kv for loop in coupled.loops])
    t = np.arange(n_steps) * H
    r = np.array([profiles[axis].evaluate(t)[0] for axis in ("X", "Y")]).T
    x, z, y_prev = np.zeros(8), np.zeros(2), np.zeros(2)
    ys, currents = [], []
    for k in range(n_steps):
        y = x[[1, 2]]                                    # the scales on a and b
        e = kv * (r[k] - y) - (y - y_prev) / H
        i_ref = (kp * e + z) / KT
        ys.append(y)
        currents.append(i_ref)
        z = z + kp * H / ti * e
        y_prev = y
        x = Phi @ x + Gamma @ i_ref
    return np.array(ys), np.array(currents)


def test_coupled_linear_loops_equal_an_independent_discrete_closed_loop():
    coupled, loops = _coupled_axes()
    assert loops[0].m_rigid == pytest.approx(M_MOTOR + M1 + M2) and loops[1].m_rigid == pytest.approx(M2)
    profiles = {"X": trapezoid_profile(5e-3, 0.1, 2.0), "Y": trapezoid_profile(-3e-3, 0.05, 1.0, start=0.01)}
    run = simulate_coupled(coupled, profiles, 0.2, nonlinear=False)
    ys, currents = _reference_run(coupled, profiles, len(run.mechanics.time))
    for j, axis in enumerate(("X", "Y")):
        series = run[axis]
        for got, want in ((series[f"sensor.{axis}_scale"], ys[:, j]), (series["current.applied"], currents[:, j])):
            # both discretise exactly (expm, a few eps per step) in the same coordinates but by other routes (a
            # Cholesky factor against an inverse of M); 0.2 s of a stable loop: 1e-9 of the signal's scale,
            # as tests/test_loop.py
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))
        np.testing.assert_allclose(series["setpoint.fine"] - series["following_error"], ys[:, j],
                                   rtol=0, atol=1e-9 * np.max(np.abs(ys[:, j])))
    # the coupling acts: Y's current is not what Y alone would command (M2·c·a_X of inertial force)
    alone = simulate(loops[1], profiles["Y"], 0.2, nonlinear=False)
    assert np.max(np.abs(alone["current.applied"] - run["Y"]["current.applied"])) > 0.05


def test_a_move_of_one_axis_disturbs_the_other_only_when_coupled():
    coupled, loops = _coupled_axes()
    profiles = {"X": trapezoid_profile(5e-3, 0.1, 2.0), "Y": step_profile(0.0)}
    run = simulate_coupled(coupled, profiles, 0.1)
    decoupled = simulate_coupled(CoupledLoop(_stacked(*(loop.mechanics for loop in loops)), loops), profiles, 0.1)
    # X accelerating at 2 m/s² pushes b with M2·c·2 = 24 N: Y's loop lets it follow by micrometres
    disturbed = np.max(np.abs(run["Y"]["following_error"]))
    assert disturbed > 1e-7
    assert np.max(np.abs(decoupled["Y"]["following_error"])) == 0.0
    assert np.max(np.abs(decoupled["Y"]["current.applied"])) == 0.0
    # and X's own following error is of the same order either way (its loop holds the extra inertia)
    ratio = run["X"].metrics.max_following_error / decoupled["X"].metrics.max_following_error
    assert 0.5 < ratio < 2.0


def test_bad_couplings_are_refused_with_located_errors():
    coupled, loops = _coupled_axes()
    mech = coupled.mechanics
    slow = machine_from_dict({"axes": {"Y": _axis("Y", {"b": M2}, actuator="b", sensor="b", velocity_period=2 * H,
                                                  position_period=2 * H)}})
    with pytest.raises(ModelError, match=r"share their velocity period .*: X 0\.0002 s, Y 0\.0004 s"):
        CoupledLoop(mech, (loops[0], build_servo_loop(slow)))
    only_x = Mechanics.from_matrices(mech.dofs, mech.mass, mech.damping, mech.stiffness,
                                     actuators=mech.actuators[:1], sensors=mech.sensors, couplings=mech.couplings)
    with pytest.raises(ModelError, match="'Y_motor' of axis Y is not an actuator of the coupled mechanics "
                                         r"\(its actuators: X_motor\)") as err:
        CoupledLoop(only_x, loops)
    assert err.value.path == "axes.Y.drive.actuator"
    no_scale = Mechanics.from_matrices(mech.dofs, mech.mass, mech.damping, mech.stiffness,
                                       actuators=mech.actuators, sensors=mech.sensors[:1], couplings=mech.couplings)
    with pytest.raises(ModelError, match="'Y_scale' of axis Y is not a sensor") as err:
        CoupledLoop(no_scale, loops)
    assert err.value.path == "axes.Y.controller.position_sensor"
    with pytest.raises(ModelError, match="distinct names"):
        CoupledLoop(mech, (loops[0], loops[0]))
    with pytest.raises(ModelError, match="over the 3 dofs"):
        CoupledLoop(mech, loops, tools={"X": np.ones(2)})
    with pytest.raises(ModelError, match="for no axis"):
        CoupledLoop(mech, loops, tools={"Z": np.ones(3)})
    with pytest.raises(ModelError, match="dof 'yt'"):      # the loop's tool body is no dof of the coupled mechanics
        CoupledLoop(mech, (loops[0], build_servo_loop(_two_axes(), "Y")))
    table = SetpointTable(np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ModelError, match="no setpoints for axis Y"):
        coupled_program(coupled, {"X": table})
    with pytest.raises(ModelError, match="no setpoint profile for axis Y"):
        simulate_coupled(coupled, {"X": step_profile(1e-3)}, 0.01)
    with pytest.raises(ModelError, match="shorter than two"):
        simulate_coupled(coupled, {"X": step_profile(1e-3), "Y": step_profile(0.0)}, H)


def test_an_analog_velocity_loop_is_refused():
    machine = machine_from_dict({"axes": {"Y": _axis("Y", {"b": M2}, actuator="b", sensor="b",
                                                     velocity_loop="continuous")}})
    coupled, loops = _coupled_axes()
    with pytest.raises(ModelError, match="continuous .analog. velocity loop is not supported") as err:
        CoupledLoop(coupled.mechanics, (loops[0], build_servo_loop(machine)))
    assert err.value.path == "axes.Y.controller.velocity_loop"


def test_the_coupled_plant_and_program_name_each_axis():
    coupled, _ = _coupled_axes()
    plant = coupled_plant(coupled)
    assert plant.inputs == ("X.current.reference", "Y.current.reference")
    assert plant.states[-2:] == ("X.drive.current", "Y.drive.current")
    assert plant.outputs[:3] == ("sensor.X_scale", "sensor.Y_scale", "X.tool.position")
    assert {"Y.drive.effort", "a.x", "b.v"} <= set(plant.outputs)
    table = SetpointTable(np.arange(3.0), np.zeros(2), np.zeros(1))
    program = coupled_program(coupled, {"X": table, "Y": SetpointTable(-np.ones(5), np.zeros(5), np.zeros(5))})
    assert program.table.shape == (6, 5)                            # 3 columns per axis, held at their ends
    np.testing.assert_array_equal(program.table[0], [0.0, 1.0, 2.0, 2.0, 2.0])
    assert {"X.velocity.error", "Y.current.command", "X.setpoint.position"} <= {*program.slot_names, *program.aliases}
    assert program.aliases["Y.sensor.Y_scale"] == program.slot_names.index("sensor.Y_scale")


def test_uncoupled_axes_with_their_own_position_periods_and_quantizers():
    """Position periods that differ (setpoint tables of different lengths in one table), quantized scales,
    feedforwards, a delay: still the single-axis runs."""
    machine = machine_from_dict({"axes": {
        "X": _axis("X", {"xm": 10.0, "xt": 30.0}, spring=("xm", "xt", 2e6, 500.0), actuator="xm", sensor="xt",
                   resolution=1e-7, position_period=4 * H, velocity_delay=1, velocity_feedforward=1.0),
        "Y": _axis("Y", {"yt": 20.0}, actuator="yt", sensor="yt", resolution=5e-8, acceleration_feedforward=0.8)}})
    loops = (build_servo_loop(machine, "X"), build_servo_loop(machine, "Y"))
    coupled = CoupledLoop(_stacked(*(loop.mechanics for loop in loops)), loops)
    profiles = {"X": trapezoid_profile(2e-3, 0.05, 1.0), "Y": trapezoid_profile(1e-3, 0.05, 1.0, start=0.005)}
    run = simulate_coupled(coupled, profiles, 0.08)
    for loop in loops:
        single = simulate(loop, profiles[loop.axis], 0.08)
        for name in single.names:
            scale = np.max(np.abs(single[_REFERENCE_SCALE.get(name, name)]))
            np.testing.assert_allclose(run[loop.axis][name], single[name], rtol=0, atol=1e-12 * scale, err_msg=name)
