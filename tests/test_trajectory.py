"""sicomat.motion.trajectory: the time-optimal S-curve against closed forms, an LP peer, and its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure
from numpy.testing import assert_allclose

from sicomat.errors import ModelError
from sicomat.motion.trajectory import JerkProfile, scurve_profile, scurve_sequence


def closed_form_time(d, v, a, j):
    """Duration of the time-optimal rest-to-rest move (Biagiotti & Melchiorri, ch. 3.4), four regimes.

    If v is reached, T = d/v + T_acc, where accelerating to v takes v/a + a/j when a is reached
    (v j >= a²) and 2 sqrt(v/j) otherwise. If not, with a reached the peak velocity w solves
    d = w (w/a + a/j) and T = 2 (w/a + a/j); with neither, d = 2 j t³ and T = 4 t.
    """
    d = abs(d)
    t_acc = v / a + a / j if v * j >= a * a else 2 * math.sqrt(v / j)
    if d >= v * t_acc:
        return d / v + t_acc, "v"
    if d >= 2 * a ** 3 / j ** 2:
        w = (-a * a / j + math.sqrt((a * a / j) ** 2 + 4 * a * d)) / 2
        return 2 * (w / a + a / j), "a"
    return 4 * (d / (2 * j)) ** (1 / 3), "none"


def dense(profile, n=4001):
    t = np.union1d(np.linspace(profile.breaks[0], profile.end_time, n), profile.breaks)
    return t, *profile.evaluate(t), profile.jerk(t)


REGIMES = [
    # (distance, v, a, j, which limits are reached)
    (0.5, 1.0, 10.0, 200.0, {"v", "a"}),      # v j = 200 >= a² = 100, d >= v (v/a + a/j) = 0.15
    (0.5, 0.2, 10.0, 200.0, {"v"}),           # v j = 40 < a²: a is never reached
    (0.1, 1.0, 10.0, 200.0, {"a"}),           # 2 a³/j² = 0.05 <= d < 0.15
    (0.01, 1.0, 10.0, 200.0, set()),          # d < 0.05: pure jerk phases
]


@pytest.mark.parametrize("d, v, a, j, reached", REGIMES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_duration_and_peaks_against_closed_form(d, v, a, j, reached, sign):
    prof = scurve_profile(sign * d, v, a, j, start=0.3)
    expected, _ = closed_form_time(d, v, a, j)
    assert isinstance(prof, JerkProfile) and prof.kind == "s-curve"
    # closed forms in this file: the profile's segment durations solve the same equations as closed_form_time in
    # another order, a few roundings each, plus square/cube roots (<= 1 ulp): 1e-12; the distance is the
    # requested one by construction (1e-15); the jerk is ±j exactly
    assert_allclose(prof.end_time - 0.3, expected, rtol=1e-12)
    assert_allclose(sum(prof.segment_durations), expected, rtol=1e-12)
    assert_allclose(prof.distance, sign * d, rtol=1e-15)
    _, pos, vel, acc, jerk = dense(prof)
    # a reached limit: the dense samples on the plateau equal it up to the rounding of the polynomials (1e-9
    # slack); a limit not reached is missed by a finite margin in these regimes (REGIMES: v j vs a², d vs the
    # thresholds differ by factors >= 2), far more than 1e-6
    assert_allclose(np.max(np.abs(vel)), v, rtol=1e-9) if "v" in reached else \
        (np.max(np.abs(vel)) < v * (1 - 1e-6) or pytest.fail("v reached"))
    assert_allclose(np.max(np.abs(acc)), a, rtol=1e-9) if "a" in reached else \
        (np.max(np.abs(acc)) < a * (1 - 1e-6) or pytest.fail("a reached"))
    assert_allclose(np.max(np.abs(jerk)), j, rtol=1e-15)
    assert np.all(np.sign(vel[vel != 0]) == sign)          # never moves backwards


def test_before_start_and_after_end():
    prof = scurve_profile(0.2, 0.5, 4.0, 100.0, start=1.0)
    pos, vel, acc = prof.evaluate(np.array([0.0, 0.999, prof.end_time, prof.end_time + 5]))
    # before the start and after the end the profile is constant: exact up to the rounding of d
    assert_allclose(pos, [0, 0, 0.2, 0.2], atol=1e-15)
    assert_allclose(vel, 0.0, atol=1e-15)
    assert_allclose(acc, 0.0, atol=1e-15)
    assert_allclose(prof.jerk(np.array([0.5, prof.end_time + 1])), 0.0)


def test_zero_distance_stays_at_rest():
    prof = scurve_profile(0.0, 1.0, 10.0, 100.0, start=0.5)
    assert prof.end_time == 0.5 and prof.distance == 0.0
    pos, vel, acc = prof.evaluate(np.linspace(0, 2, 11))
    assert not pos.any() and not vel.any() and not acc.any()


def test_evaluate_keeps_the_shape_of_t():
    prof = scurve_profile(0.1, 1.0, 10.0, 100.0)
    pos, vel, acc = prof.evaluate(np.zeros((3, 2)))
    assert pos.shape == vel.shape == acc.shape == (3, 2)
    assert np.ndim(prof.evaluate(0.01)[0]) == 0


@pytest.mark.parametrize("kwargs, name", [
    (dict(max_velocity=0.0), "max_velocity"), (dict(max_velocity=-1.0), "max_velocity"),
    (dict(max_acceleration=0.0), "max_acceleration"), (dict(max_jerk=-5.0), "max_jerk"),
    (dict(max_jerk=math.inf), "max_jerk"),
])
def test_limits_must_be_positive(kwargs, name):
    args = dict(max_velocity=1.0, max_acceleration=10.0, max_jerk=100.0) | kwargs
    with pytest.raises(ValueError, match=f"{name} must be a finite number > 0") as info:
        scurve_profile(0.1, **args)
    assert isinstance(info.value, ModelError)
    with pytest.raises(ValueError, match=name):              # even for a move of zero length
        scurve_profile(0.0, **args)


def test_sequence_sums_moves_and_stops_between_them():
    d = [0.1, -0.04, 0.02]
    vmax = [0.5, 0.2, 1.0]
    seq = scurve_sequence(d, vmax, 5.0, 100.0, start=0.2)
    assert seq.kind == "s-curve sequence" and len(seq.segment_durations) == 21
    durations = [closed_form_time(x, v, 5.0, 100.0)[0] for x, v in zip(d, vmax)]
    # sums of closed-form durations: a few roundings
    assert_allclose(seq.end_time, 0.2 + sum(durations), rtol=1e-12)
    stops = 0.2 + np.cumsum(durations)
    pos, vel, acc = seq.evaluate(stops)
    # at each stop: position is the cumulative distance (rounding of a sum of <= 0.5 m values); velocity and
    # acceleration are polynomials evaluated at a sum of segment durations t, whose rounding eps·t ≈ 1e-16 s
    # times the jerk (100 m/s³) and acceleration gives <= 1e-12 and <= 1e-9 (a includes j·δt with δt the
    # rounding of the durations' cumulative sum, amplified by j = 100)
    assert_allclose(pos, np.cumsum(d), atol=1e-15)
    assert_allclose(vel, 0.0, atol=1e-12)
    assert_allclose(acc, 0.0, atol=1e-9)
    with pytest.raises(ValueError, match="expected 3 velocity limits"):
        scurve_sequence(d, [1.0, 2.0], 5.0, 100.0)


# ------------------------------------------------------------------ peer: a linear program
def _lp_feasible(duration, d, v, a, j, n=160):
    """Is there a jerk sequence, piecewise constant on n steps, moving d from rest to rest in ``duration``?

    Exact integration of the state (p, v, a) as linear functions of the jerks; velocity and
    acceleration bounded at every node and mid-step (acceleration is linear between nodes).
    """
    h = duration / n
    sub = 2
    rows_v, rows_a = [], []
    p, vel, acc = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(n):
        for m in range(1, sub + 1):
            dt = h * m / sub
            unit = np.zeros(n)
            unit[k] = 1.0
            rows_v.append(vel + dt * acc + dt * dt / 2 * unit)
            rows_a.append(acc + dt * unit)
        unit = np.zeros(n)
        unit[k] = 1.0
        p, vel, acc = (p + h * vel + h * h / 2 * acc + h ** 3 / 6 * unit, vel + h * acc + h * h / 2 * unit,
                       acc + h * unit)
    a_ub = np.vstack(rows_v + [-r for r in rows_v] + rows_a + [-r for r in rows_a])
    b_ub = np.concatenate([np.full(2 * len(rows_v), v), np.full(2 * len(rows_a), a)])
    res = scipy.optimize.linprog(np.zeros(n), A_ub=a_ub, b_ub=b_ub, A_eq=np.vstack([p, vel, acc]),
                                 b_eq=[d, 0.0, 0.0], bounds=[(-j, j)] * n, method="highs")
    return res.status == 0


@pytest.mark.parametrize("d, v, a, j, reached", REGIMES)
def test_time_optimal_against_a_linear_program(d, v, a, j, reached):
    t_opt = scurve_profile(d, v, a, j).end_time
    assert not _lp_feasible(0.97 * t_opt, d, v, a, j)       # nothing 3 % faster exists
    assert _lp_feasible(1.03 * t_opt, d, v, a, j)


# ------------------------------------------------------------------ invariants
@settings(max_examples=40, deadline=None)
@given(d=st.floats(1e-5, 2.0), sign=st.sampled_from([1.0, -1.0]), v=st.floats(0.01, 2.0),
       a=st.floats(0.1, 50.0), j=st.floats(1.0, 5000.0))
def test_limits_never_exceeded_and_continuity(d, sign, v, a, j):
    prof = scurve_profile(sign * d, v, a, j)
    t, pos, vel, acc, jerk = dense(prof, 1501)
    # limits hold exactly in closed form; samples only add rounding: 1e-9 relative slack; the time-optimal
    # duration against the closed form: square and cube roots of hypothesis's extreme ratios (j/a up to 5e4)
    # lose a few digits: 1e-9; the end position to the rounding of d (1e-12)
    tol = 1e-9
    assert np.max(np.abs(vel)) <= v * (1 + tol)
    assert np.max(np.abs(acc)) <= a * (1 + tol)
    assert np.max(np.abs(jerk)) <= j * (1 + tol)
    assert_allclose(prof.end_time, closed_form_time(d, v, a, j)[0], rtol=1e-9)   # roots of extreme ratios, above
    assert_allclose(pos[-1], sign * d, rtol=1e-12)
    assert np.all(np.diff(sign * pos) >= -1e-15 * d)        # monotonic
    # continuity of position, velocity and acceleration across every break
    br = np.asarray(prof.breaks[1:])
    eps = 1e-9 * max(prof.end_time, 1e-3)
    # continuity: across a break the left value differs by at most the derivative's bound times eps (1.01 allows
    # the bound's rounding) plus rounding of the value (1e-12 of the next order's scale)
    for left, right, atol in zip(prof.evaluate(br - eps), prof.evaluate(br),
                                 (1.01 * v * eps + 1e-12 * d, 1.01 * a * eps + 1e-12 * v, 1.01 * j * eps + 1e-12 * a)):
        assert_allclose(left, right, rtol=0, atol=atol)
    # velocity is the derivative of position (central differences on the dense grid)
    mid = 0.5 * (t[1:] + t[:-1])
    keep = np.diff(t) > 1e-12
    slope = np.diff(pos)[keep] / np.diff(t)[keep]
    # the central difference of the position is v(t_mid) up to its truncation error Δt²/24·|x'''| with
    # |x'''| = |jerk| <= j; /12 doubles it for an interval that straddles a jerk step; plus rounding of
    # the position differences (1e-9 v)
    assert_allclose(slope, prof.evaluate(mid[keep])[1], atol=1e-9 * v + j * np.max(np.diff(t)) ** 2 / 12)


def test_to_dict_and_plot():
    prof = scurve_profile(0.1, 1.0, 10.0, 200.0)
    info = prof.to_dict()
    assert info["kind"] == "s-curve" and len(info["segment_durations"]) == 7
    assert isinstance(prof.plot(), Figure)
