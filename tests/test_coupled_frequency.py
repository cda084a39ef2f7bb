"""One loop of coupled axes with the others closed (frequency/coupled.py, servo/coupled_linear.py) and the
``--coupled`` commands (margins, bode, simulate, tune): against the single-axis analysis where the mechanics
decouples, against python-control's own interconnection of the coupled discrete loops, against the hybrid
simulator for the lifted multirate loop, the coupling's physics on the elastic XY (none without the head's
offset MX5, quadratic in it), the CLI's wiring and its refusals."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

import sicomat
from sicomat import machine_from_dict
from sicomat.cli.main import app
from sicomat.errors import ModelError
from sicomat.frequency.coupled import coupled_analysis, coupled_omega
from sicomat.frequency.loops import LoopAnalysis
from sicomat.frequency.margins import stability_margins
from sicomat.motion.setpoints import step_profile, trapezoid_profile
from sicomat.servo.coupled import coupled_plant, robot_coupled_loop
from sicomat.servo.coupled_linear import coupled_axis_model
from sicomat.servo.loop import build_servo_loop
from sicomat.servo.stability import loop_verdict, position_closed_loop
from sicomat.simulation.coupled import simulate_coupled

XY = "examples/xy_elastic.toml"
PI = math.pi
SCALARS = ("gain_margin_db", "phase_margin_deg", "gain_crossover_rad_s", "phase_crossover_rad_s", "delay_margin_s",
           "modulus_margin", "modulus_margin_rad_s", "bandwidth_rad_s")


def run(*args: str):
    return CliRunner().invoke(app, list(args))


def _independent_table(**y_controller) -> sicomat.Machine:
    """Two prismatic motorised joints on perpendicular axes (X along x0, Y along y0 riding on X), each driving
    its own mass through an elastic screw: the coupled mass matrix is block-diagonal (a prismatic pair's inertia
    term is the mass beyond both times z_X · z_Y = 0), so nothing couples the loops. Y has a velocity filter and a
    current notch, and its position period may be changed (``y_controller``)."""
    def controller(pos, vel, **extra):
        return {"type": "P-PI", "position_sensor": pos, "velocity_sensor": vel, "Kv": 50.0, "Kp_normalized": 150.0,
                "Ti": 0.006, "velocity_period": 125e-6, "position_period": 1e-3, **extra}

    return machine_from_dict({
        "robot": {"gravity": [0.0, 0.0, -9.81], "configuration": [0.0, 0.0, 0.1, 0.0],
                  "frames": [dict(name="X", ant=0, sigma=1, mu=1, gamma=PI / 2, alpha=PI / 2, IA=90.0, FV=300.0),
                             dict(name="X_screw", ant=1, sigma=1, eta=1, k=1.8e8, FV=6000.0, M=350.0),
                             dict(name="Y", ant=2, sigma=1, mu=1, alpha=-PI / 2, IA=60.0, FV=200.0),
                             dict(name="Y_screw", ant=3, sigma=1, eta=1, k=1.2e8, FV=4000.0, M=180.0)]},
        "axes": {"X": {"drive": {"force_constant": 294.5, "bandwidth": 1500.0},
                       "controller": controller("X_load", "X", position_delay=2)},
                 "Y": {"drive": {"force_constant": 196.3, "bandwidth": 1500.0},
                       "controller": controller("Y_load", "Y", velocity_filter={"type": "low-pass", "frequency": 900.0},
                                                current_filters=[{"type": "notch", "frequency": 600.0, "width": 0.4,
                                                                  "depth": 0.1}], **y_controller)}}})


def _xy(*overrides: str) -> sicomat.Machine:
    return sicomat.load_model(XY, list(overrides))


# ---------------------------------------------------------------------------------- (a) decoupled mechanics
@pytest.mark.parametrize("axis", ["X", "Y"])
def test_independent_axes_have_their_single_axis_margins(axis):
    machine = _independent_table()
    coupled = robot_coupled_loop(machine)
    mass = coupled.mechanics.mass
    # the premise: the mass matrix is block-diagonal, to rounding (the frames' ±90° rotations carry
    # cos(π/2) = 6e-17, summed over the links' masses: a few eps of the largest entry)
    assert np.abs(mass[:2, 2:]).max() <= 1e-14 * np.abs(mass).max()
    an = coupled_analysis(coupled, axis)
    alone = LoopAnalysis.of(build_servo_loop(machine, axis))
    for which in ("velocity-open", "position-open"):
        omega = coupled_omega(an, which)            # one grid for both: the margins are read off the same points
        got, want = stability_margins(an.response(which, omega)), stability_margins(alone.response(which, omega))
        # the two sampled plants are the ZOH of the same block (the other axis's block adds exact zeros to M, D,
        # K), but by expm of matrices of other sizes (other scalings): entries differ by a few eps, amplified by
        # the loop's conditioning near the rigid pole at z = 1 (|z − 1| ≈ 4e-4 at 0.5 Hz) to ~1e-11 in L
        # (measured); the margins read off the same grid points inherit it: 1e-9 relative
        for key in SCALARS:
            assert getattr(got, key) == pytest.approx(getattr(want, key), rel=1e-9), (which, key)
        np.testing.assert_allclose(got.gain_crossovers, want.gain_crossovers, rtol=1e-9)
        assert got.closed_loop_static_gain == pytest.approx(want.closed_loop_static_gain, rel=1e-9)
    assert loop_verdict(an.loop, an=an).stable is True


def test_a_partner_position_loop_at_the_velocity_period_is_closed_inside_and_changes_nothing_here():
    """Y's position loop at Tv (an LTI element at Tv, closed in X's sampled plant) with X's at 1 ms: X's loops
    are still its single-axis ones (the axes are independent); Y's position loop cannot be lifted with X's at
    another period: refused, naming both."""
    machine = _independent_table(position_period=125e-6)
    coupled = robot_coupled_loop(machine)
    an = coupled_analysis(coupled, "X")
    alone = LoopAnalysis.of(build_servo_loop(machine, "X"))
    for which in ("velocity-open", "position-open"):
        omega = coupled_omega(an, which)
        # as in the test above
        np.testing.assert_allclose(an.response(which, omega).response, alone.response(which, omega).response,
                                   rtol=1e-9)
    an_y = coupled_analysis(coupled, "Y")
    an_y.response("velocity-open")                  # X's position loop is open there: LTI at Tv
    with pytest.raises(ModelError, match=r"Y 0\.000125 s, X 0\.001 s"):
        an_y.response("position-open")


# ---------------------------------------------------------------------------------- (b) python-control peer
def _control_loop_gain(coupled, axis: str, which: str):
    """The loop gain of ``axis``'s velocity or position loop with the other axes' cascades closed, written
    independently with python-control: the coupled continuous plant ZOH-sampled by ``control.c2d``, and per axis
    the textbook P-PI cascade as discrete transfer functions at T (single rate: Tp = Tv = T): the measured
    position y_p/g_p, the differenced velocity (1 − z⁻¹)/(T g_v)·y_v, the P law Kv·z^(−d_p) on the position
    error, the PI Kp + (Kp T/Ti)/(z − 1) on the velocity error (forward Euler), the computation delay
    z^(−d_v)/kt to the current reference; the loop broken at ``axis``'s velocity error (its position loop
    open) or position error."""
    import control as ct

    T = coupled.base_period
    plant = coupled_plant(coupled)
    rows, names = [], []
    for loop in coupled.loops:
        ctrl = loop.controller
        for key, sensor in (("yp", ctrl.position_sensor), ("yv", ctrl.velocity_sensor or ctrl.position_sensor)):
            rows.append(plant.outputs.index(f"sensor.{sensor}"))
            names.append(f"{loop.axis}_{key}")
    sampled = ct.c2d(ct.ss(plant.A, plant.B, plant.C[rows], np.zeros((len(rows), len(coupled.loops)))), T, "zoh")
    systems = [ct.ss(sampled.A, sampled.B, sampled.C, sampled.D, T, inputs=[f"{a}_i" for a in coupled.axes],
                     outputs=names, name="plant")]

    def delayed(gain, d, inp, out):
        return ct.tf([gain], [1.0] + [0.0] * d, T, inputs=inp, outputs=out, name=f"{out}_block")

    for loop in coupled.loops:
        a, ctrl = loop.axis, loop.controller
        broken = which if a == axis else None
        systems += [ct.tf([1.0, -1.0], [T * loop.velocity_gain, 0.0], T, inputs=f"{a}_yv", outputs=f"{a}_v", name=f"{a}_d"),
                    ct.tf([1.0 / loop.position_gain], [1.0], T, inputs=f"{a}_yp", outputs=f"{a}_p", name=f"{a}_m"),
                    ct.tf([loop.Kp, loop.Kp * T / loop.Ti - loop.Kp], [1.0, -1.0], T, inputs=f"{a}_e",
                          outputs=f"{a}_u", name=f"{a}_pi"),
                    delayed(1.0 / loop.drive.kt, ctrl.velocity_delay, f"{a}_u", f"{a}_i")]
        if broken != "velocity":
            systems += [delayed(loop.Kv, ctrl.position_delay, f"{a}_ep", f"{a}_vc"),
                        ct.summing_junction(inputs=[f"{a}_vc", f"-{a}_v"], output=f"{a}_e", name=f"{a}_sv", dt=T)]
        if broken is None:
            systems.append(ct.summing_junction(inputs=[f"-{a}_p"], output=f"{a}_ep", name=f"{a}_sp", dt=T))
    ends = {"velocity": ("e", "v"), "position": ("ep", "p")}[which]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # the unused outputs of the broken axis's measurement blocks
        return ct.interconnect(systems, inputs=[f"{axis}_{ends[0]}"], outputs=[f"{axis}_{ends[1]}"], dt=T)


@pytest.mark.parametrize("axis", ["X", "Y"])
@pytest.mark.parametrize("which", ["velocity", "position"])
def test_single_rate_coupled_loops_are_python_controls_interconnection(axis, which):
    import control as ct

    machine = _xy('axes.X.controller.position_period="125 us"', 'axes.Y.controller.position_period="125 us"')
    coupled = robot_coupled_loop(machine)
    an = coupled_analysis(coupled, axis)
    reference = _control_loop_gain(coupled, axis, which)
    T = coupled.base_period
    omega = 2 * np.pi * np.array([0.7, 5.0, 30.0, 90.0, 140.0, 400.0, 1500.0, 3900.0])
    got = an.response(f"{which}-open", omega).response
    want = np.array([complex(reference(np.exp(1j * w * T))) for w in omega])
    # one discrete transfer evaluated at the same z by two routes (our builder's state space solved by LU; their
    # interconnection of transfer functions), both sampled exactly from the same continuous matrices (expm):
    # rounding amplified by the loop's conditioning (the rigid pole at z = 1, the lightly damped yaw mode at
    # 140 Hz); measured 2e-11
    np.testing.assert_allclose(got, want, rtol=1e-9)
    # the margins: python-control's on its own response sampled on our grid (an FRD: its crossover search),
    # ours on ours. The crossovers are located between the same grid points by two interpolants (our local
    # cubic in ln ω, their own), each within O(h⁴) of the truth for the grid's step h ≈ 3e-3 in ln ω: measured
    # 1e-8 dB, 1e-9 °, 1e-10 relative, 4e-9 on the modulus margin; 1e-6 leaves room and still catches any
    # change of the loop
    frf = an.response(f"{which}-open")
    ours = stability_margins(frf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, sm, wpc, wgc, _ = ct.stability_margins(ct.frd(reference(np.exp(1j * frf.omega * T)), frf.omega))
    assert ours.gain_margin_db == pytest.approx(20 * np.log10(gm), abs=1e-6)
    assert ours.phase_margin_deg == pytest.approx(pm, abs=1e-6)
    assert ours.gain_crossover_rad_s == pytest.approx(wgc, rel=1e-6)
    assert ours.phase_crossover_rad_s == pytest.approx(wpc, rel=1e-6)
    assert ours.modulus_margin == pytest.approx(sm, rel=1e-6)


@pytest.mark.parametrize("axis", ["X", "Y"])
def test_the_lifted_multirate_position_loop_is_the_simulators_linear_run(axis):
    """Position loops at 1 ms around velocity loops at 125 µs: the lifted model of one axis with the other's
    position loop closed after lifting (its computation delay of 2 periods as states) against the hybrid
    simulator's linear coupled run (another lowering: the program's ops, the kernel's exact ZOH steps), a
    position step of ``axis`` with the other holding, sampled at Tp."""
    machine = _xy("axes.X.controller.velocity_feedforward=0", "axes.Y.controller.velocity_feedforward=0",
                  "axes.Y.controller.position_delay=2")
    coupled = robot_coupled_loop(machine)
    model = coupled_axis_model(coupled, axis)
    loop = model.loop
    A, B, C, Tp = position_closed_loop(model, loop.Kp, loop.Ti, loop.Kv)
    n, step = 150, 1e-3
    x, lifted = np.zeros(A.shape[0]), []
    for _ in range(n):
        lifted.append(C @ x)
        x = A @ x + B * step
    profiles = {name: step_profile(step if name == axis else 0.0) for name in coupled.axes}
    simulated = simulate_coupled(coupled, profiles, n * Tp, nonlinear=False)[axis]["position.measured"]
    # both exact discretisations of one linear system (expm), 1200 steps: a few eps per step; measured 2e-14
    np.testing.assert_allclose(simulated[:: loop.position_ratio][:n], lifted, rtol=0, atol=1e-10 * step)


# ---------------------------------------------------------------------------------- (c) the XY's physics
def _loop_gains(machine, omega):
    coupled = robot_coupled_loop(machine)
    out = {}
    for axis in ("X", "Y"):
        an = coupled_analysis(coupled, axis)
        alone = LoopAnalysis.of(build_servo_loop(machine, axis))
        for which in ("velocity-open", "position-open"):
            grid = coupled_omega(an, which) if omega is None else omega
            out[axis, which] = (an.response(which, grid), alone.response(which, grid))
    return out


def test_without_the_heads_offset_the_coupled_loops_are_the_decoupled_ones():
    """At q3 = 0 the XY's mass matrix couples {X, X_screw, yaw} to {Y, Y_screw} only through the Y slide's first
    moment MX5 (the notes' closed form: A34 = A35 = MX5, A14 = A15 = −M5 sin q3 = 0). With MX5 = 0 the blocks
    decouple: X's loop sees nothing of Y's (closed, in the coupled model; its motor locked and its screw free,
    in the decoupled one), and the other way round, so coupled and decoupled loop gains and margins are equal.
    With the example's MX5 = 9 kg·m they are not."""
    centred = _xy("robot.frames.4.MX=0")
    mass = robot_coupled_loop(centred).mechanics.mass
    assert np.abs(mass[:3, 3:]).max() <= 1e-14 * np.abs(mass).max()     # to rounding, as in the test above
    for (axis, which), (coupled, alone) in _loop_gains(centred, None).items():
        # as in test_independent_axes_have_their_single_axis_margins; measured 1e-11 (the margins 1e-12)
        np.testing.assert_allclose(coupled.response, alone.response, rtol=1e-9, err_msg=f"{axis} {which}")
        got, want = stability_margins(coupled), stability_margins(alone)
        for key in SCALARS:
            assert getattr(got, key) == pytest.approx(getattr(want, key), rel=1e-9), (axis, which, key)
    for (axis, which), (coupled, alone) in _loop_gains(_xy(), None).items():
        relative = np.abs(coupled.response - alone.response) / np.abs(alone.response)
        assert relative.max() > 1e-3, (axis, which)          # measured 0.06 to 0.44: the coupling is real
        # at the crossovers, far below the yaw resonance (140 Hz) where the coupling acts, the margins move little:
        # the modulus margins by 1.2e-7 to 2.5e-6 relative (measured), against 1e-14 with MX5 = 0
        got, want = stability_margins(coupled), stability_margins(alone)
        assert abs(got.modulus_margin / want.modulus_margin - 1) > 1e-8, (axis, which)


def test_the_coupling_changes_each_loop_gain_quadratically_in_the_heads_offset():
    """The other axis acts on a loop through the off-diagonal block of M, proportional to MX5, twice (from this
    axis to the other's closed loop and back): L_coupled − L_decoupled = O(MX5²). Halving MX5 quarters it, up
    to relative corrections O(MX5²) that are below 0.1 % at 20 and 60 Hz, away from the yaw resonance near
    140 Hz (measured ratios 4.000 ± 0.004)."""
    omega = 2 * np.pi * np.array([20.0, 60.0])
    full, half = _loop_gains(_xy("robot.frames.4.MX=9"), omega), _loop_gains(_xy("robot.frames.4.MX=4.5"), omega)
    for key in full:
        ratio = np.abs(full[key][0].response - full[key][1].response) / np.abs(half[key][0].response
                                                                              - half[key][1].response)
        np.testing.assert_allclose(ratio, 4.0, rtol=0.02, err_msg=str(key))


# ---------------------------------------------------------------------------------- the commands
def test_margins_coupled_json_has_todays_keys_the_decoupled_beside_and_the_table_both():
    plain = json.loads(run("margins", XY, "--axis", "X", "--json").output)
    result = run("margins", XY, "--axis", "X", "--coupled", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    assert set(plain) <= set(payload) and payload["coupled"] is True
    assert set(payload["decoupled"]) == set(plain)
    assert payload["decoupled"] == plain              # the decoupled figures are today's margins, unchanged
    assert set(payload["velocity"]) == set(plain["velocity"])
    an = coupled_analysis(robot_coupled_loop(_xy()), "X")
    assert payload["velocity"]["phase_margin_deg"] == stability_margins(an.response("velocity-open")).phase_margin_deg
    assert payload["closed_loops"]["position"] == {"closed": ["Y.velocity", "Y.position"], "open": []}
    assert payload["closed_loops"]["velocity"]["open"] == ["Y.position"] and payload["notes"]
    table = run("margins", XY, "--axis", "Y", "--coupled")
    assert table.exit_code == 0, table.output
    for row in ("velocity", "position"):
        assert table.output.count(row) >= 2 and "coupled" in table.output and "decoupled" in table.output


def test_bode_coupled(tmp_path):
    figure = tmp_path / "bode.png"
    result = run("bode", XY, "--axis", "Y", "--coupled", "--loop", "position-open", "--points", "300", "--json",
                 "--plot", str(figure))
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    plain = json.loads(run("bode", XY, "--axis", "Y", "--loop", "position-open", "--points", "300", "--json").output)
    assert set(plain) <= set(payload) and payload["coupled"] is True and payload["info"]["coupled"] is True
    assert payload["decoupled"] == plain and figure.stat().st_size > 0
    assert payload["margins"]["phase_margin_deg"] != plain["margins"]["phase_margin_deg"]
    closed = json.loads(run("bode", XY, "--axis", "X", "--coupled", "--loop", "velocity-closed", "--json").output)
    assert "margins" not in closed and closed["stable"] is True


def test_simulate_coupled_moves_one_axis_and_the_other_holds_through_the_coupling(tmp_path):
    csv, figure = tmp_path / "run.csv", tmp_path / "errors.png"
    result = run("simulate", XY, "--axis", "X", "--move", "20", "--coupled", "--linear", "--json",
                 "--out", str(csv), "--plot", str(figure))
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    plain = json.loads(run("simulate", XY, "--axis", "X", "--move", "20", "--linear", "--json").output)
    assert set(plain) <= set(payload) and payload["coupled"] is True and payload["axis"] == "X"
    assert set(payload["axes"]) == {"X", "Y"}
    assert set(payload["axes"]["Y"]) == {"max_following_error", "rms_following_error", "final_error",
                                         "overshoot_percent", "rise_time", "settling_time"}
    # the same run through the library: the CLI holds Y at a constant setpoint and moves X as simulate --move does
    machine = _xy()
    from sicomat.tasks.simulate import choose_profile

    profile, duration = choose_profile(None, None, 20.0, None, None)
    run_ = simulate_coupled(robot_coupled_loop(machine), {"X": profile, "Y": step_profile(0.0)}, duration,
                            nonlinear=False)
    for axis in ("X", "Y"):
        assert payload["axes"][axis]["max_following_error"] == run_[axis].metrics.max_following_error
    x, y = payload["axes"]["X"]["max_following_error"], payload["axes"]["Y"]["max_following_error"]
    # the coupling reaches X's own loop only at second order in MX5 (the test above: its loop gain moves by
    # 1e-7 to 2e-5 relative below 60 Hz, where this move's error lives): its error within 1e-3 of the decoupled
    # run's (measured 9e-6); Y is pushed by X's acceleration through MX5, at first order: far above rounding,
    # far below X's (measured 7.8e-4 of it on this move)
    assert x == pytest.approx(plain["max_following_error"], rel=1e-3)
    assert 1e-5 * x < y < 0.1 * x
    assert payload["max_following_error"] == x
    header = csv.read_text().splitlines()[0].split(",")
    assert {"X.following_error", "Y.following_error", "Y.current.applied", "sensor.X_scale", "yaw.theta"} <= set(header)
    assert figure.stat().st_size > 0
    centred = json.loads(run("simulate", XY, "--axis", "X", "--move", "20", "--coupled", "--linear", "--json",
                             "--set", "robot.frames.4.MX=0").output)
    # with MX5 = 0 nothing reaches Y: at rest to rounding (as tests/test_robotics_model.py's library run)
    assert centred["axes"]["Y"]["max_following_error"] < 1e-12 * x


def test_tune_reports_the_tuned_loop_with_the_other_loops_closed():
    result = run("tune", XY, "--axis", "X", "--velocity-crossover", "180", "--json")
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    coupled = payload["coupled_margins"]
    assert {"velocity", "position", "achieved", "targets_met", "unmet", "stable", "warnings", "closed_loops"} <= set(coupled)
    assert isinstance(coupled["targets_met"], bool) and coupled["stable"] is True
    assert coupled["targets_met"] == (not coupled["unmet"])
    # the tuning's definitions on the coupled model: the example is tuned to these targets, and the coupling
    # moves the margins by 1e-4 degrees or so: they still hold
    assert coupled["targets_met"] and abs(coupled["achieved"]["velocity_phase_margin_deg"] - 45.0) < 1.0
    plain = json.loads(run("tune", "examples/paper_5m4s.toml", "--json").output)
    assert "coupled_margins" not in plain


@pytest.mark.parametrize("args,words", [
    (("margins", "examples/paper_5m4s.toml", "--coupled"), "no [robot] section"),
    (("bode", "examples/paper_5m4s.toml", "--coupled"), "no [robot] section"),
    (("simulate", "examples/paper_5m4s.toml", "--coupled", "--step", "1"), "no [robot] section"),
    (("simulate", "examples/xy_table.toml", "--coupled", "--gcode", "examples/contour.nc"),
     "needs a machine described by a [robot] section"),
    (("simulate", XY, "--coupled", "--axis", "X"), "no setpoint"),
    (("bode", XY, "--coupled", "--loop", "compliance"), "--loop: with the other loops closed, expected one of"),
    (("margins", XY, "--coupled", "--axis", "Z"), "Z"),
    (("margins", XY, "--coupled", "--set", 'axes.Y.controller.position_period="2 ms"'),
     "X 0.001 s, Y 0.002 s"),
])
def test_bad_coupled_requests_are_one_line_and_exit_2(args, words):
    result = run(*args)
    assert result.exit_code == 2, result.output
    assert words in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_an_unstable_partner_makes_the_coupled_run_and_margins_unstable():
    """Y's position loop with Kv = 3000 1/s is unstable on its own; X's is not. Decoupled, X's run is stable;
    coupled, the verdict is the poles of all loops closed: unstable, exit 3, no step figures."""
    bad = ("--set", "axes.Y.controller.Kv=3000")
    alone = json.loads(run("simulate", XY, "--axis", "X", "--move", "5", "--linear", "--json", *bad).output)
    assert alone["stable"] is True
    result = run("simulate", XY, "--axis", "X", "--move", "5", "--linear", "--coupled", "--json", *bad)
    assert result.exit_code == 3, result.output
    payload = json.loads(result.output)
    assert payload["stable"] is False and any("unstable" in w for w in payload["warnings"])
    assert payload["overshoot_percent"] is None and payload["axes"]["Y"]["settling_time"] is None
    margins = run("margins", XY, "--axis", "X", "--coupled", "--json", *bad)
    assert margins.exit_code == 3 and json.loads(margins.output)["position"]["stable"] is False
