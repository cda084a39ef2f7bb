"""Closed-loop bandwidth: one definition (margins.closed_loop_bandwidth) relative to the exact static
gain (frequency.static_gain, LoopAnalysis.closed_loop_static_gain), against closed forms, against a
pointwise root finder and python-control on the 5M4S, and the same figure from `tune` and `margins`."""

from __future__ import annotations

import json
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.optimize
from typer.testing import CliRunner

import sicomat
from sicomat.cli.main import app
from sicomat.lti.response import FrequencyResponse, static_gain, zoh_matrices
from sicomat.servo.loop import build_servo_loop
from sicomat.frequency.loops import LoopAnalysis
from sicomat.frequency.margins import closed_loop, closed_loop_bandwidth, stability_margins

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# Interpolation error of the crossing (closed forms): the level crossing of f = 20 log10|T| is found
# with the cubic through 4 grid points equally spaced by h in ln ω, whose error is at most
# (9/16) h⁴ max|f⁽⁴⁾| / 24. On GRID, h = ln(1e6)/20000 = 6.9e-4, h⁴ = 2.3e-13; for these roll-offs
# (first and second order, ζ ≥ 0.1) |f⁽⁴⁾| ≤ 1e4 dB and the slope at the crossing |f'| ≥ 3 dB per
# unit of ln ω, so the root moves by at most 1e-9 in ln ω: rtol = 1e-8 keeps a factor 10.
GRID = np.logspace(-3, 3, 20001)
RTOL_GRID = 1e-8


def T_of(omega, values):
    return FrequencyResponse(np.asarray(omega, float), np.asarray(values, complex))


# --------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("a", [0.05, 1.0, 30.0])
def test_first_order_closed_loop_bandwidth_is_its_pole(a):
    # T = a/(s + a): |T(0)| = 1, |T|² = a²/(ω² + a²) = 1/2 at ω = a.
    s = 1j * GRID
    assert closed_loop_bandwidth(T_of(GRID, a / (s + a)), 1.0) == pytest.approx(a, rel=RTOL_GRID)


@pytest.mark.parametrize("zeta", [0.1, 0.3, 1 / np.sqrt(2), 1.0, 2.0])
def test_second_order_closed_loop_bandwidth_closed_form(zeta):
    # T = ωn²/(s² + 2ζωn s + ωn²): |T|² = 1/2 ⇔ u² − 2(1 − 2ζ²)u − 1 = 0 (u = ω²/ωn²), so
    # ω_bw = ωn sqrt(1 − 2ζ² + sqrt(4ζ⁴ − 4ζ² + 2)); with ζ < 1/√2 the resonance peak above |T(0)|
    # comes first and does not count.
    wn = 7.0
    s = 1j * GRID
    T = wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)
    expected = wn * np.sqrt(1 - 2 * zeta**2 + np.sqrt(4 * zeta**4 - 4 * zeta**2 + 2))
    assert closed_loop_bandwidth(T_of(GRID, T), 1.0) == pytest.approx(expected, rel=RTOL_GRID)  # cubic bound, top


def test_type_zero_loop_is_relative_to_its_static_gain():
    # L = K/(s + 1): T = K/(s + 1 + K), T(0) = K/(1 + K), −3 dB below it at ω = 1 + K.
    K = 3.0
    s = 1j * GRID
    L = FrequencyResponse(GRID, K / (s + 1), open_loop=True)
    assert closed_loop_bandwidth(closed_loop(L), K / (1 + K)) == pytest.approx(1 + K, rel=RTOL_GRID)


def test_margins_use_the_exact_static_gain_not_the_lowest_grid_point():
    # L = ωc/s on a grid starting at ω0 = ωc/3: |T(ω0)| = 1/sqrt(1 + 1/9) < 1 = |T(0)|. Relative to
    # |T(ω0)| the −3 dB point would be sqrt(ωc² + 2ω0²) = 1.106 ωc; relative to T(0) it is ωc.
    wc = 10.0
    omega = np.logspace(np.log10(wc / 3), 3, 4000)   # h = 1.5e-3: error ≤ 1e-9 as above
    frf = FrequencyResponse(omega, wc / (1j * omega), open_loop=True)
    m = stability_margins(frf, closed_loop_static_gain=1.0)
    assert m.bandwidth_rad_s == pytest.approx(wc, rel=RTOL_GRID)
    assert m.static_gain_exact and m.to_dict()["closed_loop_static_gain"] == 1.0
    # the same through the info a LoopAnalysis response carries
    tagged = FrequencyResponse(omega, frf.response, open_loop=True, info={"closed_loop_static_gain": 1.0})
    assert stability_margins(tagged).bandwidth_rad_s == pytest.approx(wc, rel=RTOL_GRID)
    # a bare response says that its reference is the lowest grid point
    bare = stability_margins(frf)
    assert not bare.static_gain_exact
    assert bare.bandwidth_rad_s == pytest.approx(np.sqrt(wc**2 + 2 * omega[0] ** 2), rel=RTOL_GRID)


def test_bandwidth_not_reached_or_below_the_grid():
    omega = np.logspace(-2, 0, 100)
    s = 1j * omega
    assert closed_loop_bandwidth(T_of(omega, 1e3 / (s + 1e3)), 1.0) == np.inf
    assert np.isnan(closed_loop_bandwidth(T_of(omega, 1e-3 / (s + 1e-3)), 1.0))   # crossing below 0.01
    assert np.isnan(closed_loop_bandwidth(T_of(omega, 1 / (s + 1)), 0.0))
    assert np.isnan(closed_loop_bandwidth(T_of(omega, 1 / (s + 1)), np.inf))


# --------------------------------------------------------------------------- exact static gains
def test_static_gain_of_a_pi_velocity_loop_with_a_drifting_position():
    # 1/(m s) under Kp (1 + 1/(Ti s)); states (x, v, ξ). T_v(0) = 1 although A is singular: the
    # position drift is a pole at 0 the velocity does not see. Position output: a pole at 0 → inf.
    m, kp, ti = 2.0, 50.0, 0.1
    A = np.array([[0, 1, 0], [0, -kp / m, 1 / m], [0, -kp / ti, 0]])
    B = np.array([[0], [kp / m], [kp / ti]])
    C = np.array([[0, 1, 0], [1, 0, 0]])
    assert np.linalg.matrix_rank(A) == 2
    G = static_gain(A, B, C, discrete=False)
    # the solve of the regular part (v, ξ): κ = 1e3, n = 3, n·κ·eps = 7e-13 (1e-11); sampled, the same κ
    # plus expm's error (n·eps·κ(V)·‖A h‖, ‖A h‖ = 0.5): 1e-10
    assert G[0, 0] == pytest.approx(1.0, abs=1e-11) and G[1, 0] == np.inf
    # the same loop sampled (ZOH at 1 ms): z = 1, same values
    Ad, Bd = zoh_matrices(A, B, 1e-3)
    Gd = static_gain(Ad, Bd, C, discrete=True)
    assert Gd[0, 0] == pytest.approx(1.0, abs=1e-10) and Gd[1, 0] == np.inf


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_static_gain_matches_python_control_when_regular(seed):
    # A regular case: python-control's dcgain, D − C A⁻¹ B (continuous) and D + C (I − A)⁻¹ B
    # (discrete). Both are backward stable solves, so they agree to a few n·κ·eps (κ the condition
    # number of the matrix solved): rtol 100 n κ eps, relative to the largest gain.
    rng = np.random.default_rng(seed)
    n = 6
    A = rng.standard_normal((n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 1.0) * np.eye(n)       # poles at least 1 left of 0
    B, C, D = rng.standard_normal((n, 2)), rng.standard_normal((3, n)), rng.standard_normal((3, 2))
    for M, disc, ref in ((A, False, control.ss(A, B, C, D).dcgain()),
                         (0.5 * A / np.max(np.abs(np.linalg.eigvals(A))), True, None)):
        if disc:      # poles inside the unit disc, none at 1
            ref = control.ss(M, B, C, D, 1.0).dcgain()
        kappa = np.linalg.cond(M - (1.0 if disc else 0.0) * np.eye(n))
        np.testing.assert_allclose(static_gain(M, B, C, D, discrete=disc), ref, rtol=0,
                                   atol=100 * n * kappa * np.finfo(float).eps * np.max(np.abs(ref)))


@pytest.fixture(scope="module")
def paper_loop():
    return build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml"))


@pytest.mark.parametrize("sets", [[], ["axes.X.controller.type=P-IP"]])
def test_loop_static_gains_are_one_with_integrators(sets):
    # Both loops have an integrator (the PI; the position): T(0) = 1 exactly. The computed value
    # carries the round-off of the solve of the regular part: ≤ 15 states, condition number after
    # balancing ≈ 3e4 (velocity loop, drift split off) and ≈ 1e3 (position loop): n·κ·eps ≤ 1e-10.
    loop = build_servo_loop(sicomat.load_model(EXAMPLES / "paper_5m4s.toml", sets))
    an = LoopAnalysis.of(loop)
    assert an.closed_loop_static_gain("velocity-open") == pytest.approx(1.0, abs=1e-10)
    assert an.closed_loop_static_gain("position-open") == pytest.approx(1.0, abs=1e-10)
    assert an.response("position-open").info["closed_loop_static_gain"] == pytest.approx(1.0, abs=1e-10)  # n·κ·eps


def test_analog_and_continuous_position_loop_static_gains():
    # ≤ 9 states, κ ≤ 1.2e3 after balancing: n·κ·eps ≤ 3e-12, 1e-10 as above
    for sets in ([], ["axes.X.controller.position_loop=continuous"]):
        loop = build_servo_loop(sicomat.load_model(EXAMPLES / "ballscrew_analog.toml", sets))
        an = LoopAnalysis.of(loop)
        assert an.closed_loop_static_gain("velocity-open") == pytest.approx(1.0, abs=1e-10)
        assert an.closed_loop_static_gain("position-open") == pytest.approx(1.0, abs=1e-10)   # n·κ·eps above


# --------------------------------------------------------------------------- 5M4S against oracles
def _pointwise_bandwidth(an: LoopAnalysis, which: str, static: float, bracket) -> float:
    """|T(jω)| = static/√2 by Brent's method on the loop gain evaluated at each trial ω (no grid,
    no interpolation): the root is as accurate as |T| itself (1e-12) over its slope."""
    def f(w):
        L = an.response(which, np.array([w])).response[0]
        return abs(L / (1 + L)) - static / np.sqrt(2)
    return scipy.optimize.brentq(f, *bracket, xtol=1e-13, rtol=1e-13)


def test_paper_5m4s_position_bandwidth_against_python_control_and_a_root_finder(paper_loop):
    an = LoopAnalysis.of(paper_loop)
    ctrl = paper_loop.controller
    # the position loop closed by hand with python-control: lifted velocity loop g_v (Tp), the
    # delay z^-d and Kv in negative feedback; its dcgain is T(0)
    Ap, Bp, C = an.position_model(paper_loop.Kp, paper_loop.Ti)
    Tp = ctrl.position_period
    g_v = control.ss(Ap, Bp[:, :1], C[:1], 0, Tp)
    forward = paper_loop.Kv * g_v * control.tf([1], [1] + [0] * ctrl.position_delay, Tp)
    closed = control.feedback(control.ss(forward), 1)
    static_pc = float(np.real(closed.dcgain()))
    assert static_pc == pytest.approx(1.0, abs=1e-9)   # the lifted model's cond ~1e3: round-off 1e-12
    # python-control's own frequency response of that closed loop, on a dense grid, bracketing
    # the −3 dB point; then Brent's method pointwise on the package's loop gain
    w = np.linspace(20.0, 40.0, 2001)
    mag = np.abs(np.asarray(closed.frequency_response(w).complex).ravel())
    i = int(np.flatnonzero(mag < static_pc / np.sqrt(2))[0])
    oracle = _pointwise_bandwidth(an, "position-open", static_pc, (w[i - 1], w[i]))
    assert oracle == pytest.approx(28.33, abs=0.005)   # the figure, quoted to 2 decimals: ±0.005
    m = stability_margins(an.response("position-open"))
    # the grid of default_omega (2000 log points from π to 3138 rad/s: h = 3.5e-3 in ln ω, h⁴ =
    # 1.5e-10) and the same cubic bound as above: ≤ 1e-7 relative; the old definition (the lowest
    # grid point as static gain) gave 28.85, 1.8 % off.
    assert m.static_gain_exact
    assert m.bandwidth_rad_s == pytest.approx(oracle, rel=1e-6)


def test_paper_5m4s_velocity_bandwidth_against_a_root_finder(paper_loop):
    an = LoopAnalysis.of(paper_loop)
    m = stability_margins(an.response("velocity-open"))
    # bracket: the grid interval holding the crossing (the package's own grid, only to bracket)
    T = np.abs(closed_loop(m.frf).response)
    i = int(np.flatnonzero(T < 1 / np.sqrt(2))[0])
    oracle = _pointwise_bandwidth(an, "velocity-open", 1.0, (m.frf.omega[i - 1], m.frf.omega[i]))
    assert m.bandwidth_rad_s == pytest.approx(oracle, rel=1e-6)   # grid bound as for the position loop


def test_tune_and_margins_report_the_same_bandwidths(tmp_path):
    # tune --write then margins on the written model: the same loop, evaluated on two different
    # grids (tune: 1200 points, margins: 2000): both within the interpolation bound 1e-7 of the
    # true bandwidth, so within 1e-6 of each other. Before, tune took the first grid point below
    # |T(ω_min)|/√2 (no interpolation, the lowest grid point as static gain).
    runner = CliRunner()
    model = tmp_path / "m.toml"
    model.write_text((EXAMPLES / "paper_5m4s.toml").read_text())
    tuned = tmp_path / "tuned.toml"
    out = runner.invoke(app, ["tune", str(model), "--json", "--write", str(tuned)])
    assert out.exit_code == 0, out.output
    achieved = json.loads(out.output)["achieved"]
    out = runner.invoke(app, ["margins", str(tuned), "--json"])
    assert out.exit_code == 0, out.output
    margins = json.loads(out.output)
    for loop in ("velocity", "position"):
        assert margins[loop]["static_gain_exact"] is True
        # two interpolation bounds (comment above): (2000/1200)⁴·1e-7 = 7.7e-7 on tune's grid + 1e-7 < 1e-6
        assert achieved[f"{loop}_bandwidth_rad_s"] == pytest.approx(margins[loop]["bandwidth_rad_s"], rel=1e-6)
