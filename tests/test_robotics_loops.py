"""Closed loops (issue 13): SYMORO's cut frames in :meth:`MDHRobot.from_table` (``links``), the closure
and the closed-loop dynamics of :mod:`sicomat.robotics.loops`.

References independent of the code under test:
- a parallelogram linkage, its closed form derived by hand below (the coupler translates);
- a crank-rocker four-bar, its Lagrange equations built here from plane geometry alone (the coupler and
  rocker angles as closed-form functions of the crank angle: two circles' intersection; their derivatives
  by five-point differences), never from the MDH table or the package (sympy is not a dependency);
- finite differences of :func:`solve_closure` for the constraint Jacobian (the code derives it from the
  frames' Jacobians instead).

Tolerances (error analysis):
- Closed forms vs the code: both evaluate a few dozen operations on numbers of order 1 (lengths <= 1 m,
  masses <= 2 kg, speeds <= 3 rad/s); the code's passive accelerations and G come from an SVD solve of a
  well-conditioned 6x3 loop Jacobian (singular values 0.2..2 away from the four-bar's dead points).
  Rounding ~1e-15 of the torque scale; 1e-9 keeps a margin of ~1e5 while a wrong sign, a missing
  (dq_p/dq_a)^T term or the wrong assembly mode is off by O(1).
- The four-bar's Lagrange torques use five-point differences (h = 1e-3) of smooth closed forms, nested
  once: truncation h^4/30 |f^(5)| ~1e-12 * |f^(5)| (|f^(5)| <= ~1e2 for this crank-rocker, far from its
  limit positions), rounding eps/h^2 ~ 2e-10 for the nested derivative: ~1e-9 of the torque scale, so
  those comparisons use 1e-7 (a margin of ~100; a wrong term is off by O(1e-2..1)).
- Newton: it stops at a closure error below 1e-14 of the size here (quadratic convergence reaches
  rounding, ~1e-16 * 3 m); the joint error is that over a lever >= 0.3 m: ~1e-13 rad, compared at 1e-10.
- Finite differences of solve_closure, h = 1e-5: truncation h^2/6 |q'''| <= ~1e-9 (|q'''| <= ~50 on this
  linkage), rounding 1e-13 / h = 1e-8: the bound 1e-6 leaves a margin of ~100, a wrong G is off by O(0.1..1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sicomat.errors import ModelError
from sicomat.robotics import (MDHRobot, active_joints, closed_loop_inertia_matrix, closed_loop_inverse_dynamics,
                              closure_error, constraint_jacobian, inverse_dynamics, loop_frames, loop_states,
                              passive_joints, solve_closure)

G0 = 9.81
REL = 1e-9
STENCIL = 1e-7


def _four_bar_frames(l0: float, l1: float, l2: float, l3: float, links: dict) -> list[dict]:
    """Crank 1 at O (active), coupler 2 on its tip, rocker 3 at O' = (l0, 0); the joint between the rocker
    and the coupler is cut: cut frame 4 on the rocker's tip, closing frame 5 on the coupler at l2."""
    return [dict(ant=0, sigma=0, mu=1, **links[1]),
            dict(ant=1, sigma=0, d=l1, **links[2]),
            dict(ant=0, sigma=0, d=l0, **links[3]),
            dict(ant=3, sigma=0, d=l3, **links.get(4, {})),
            dict(ant=2, sigma=2, d=l2)]


def _planar_link(m: float, mx: float, my: float, extra: float, **joint: float) -> dict:
    """A plane body about its frame origin: point-mass moments plus `extra` (>= 0) on each axis."""
    return dict(M=m, MX=mx, MY=my, XX=my ** 2 / m + extra, YY=mx ** 2 / m + extra,
                ZZ=(mx ** 2 + my ** 2) / m + extra, XY=-mx * my / m, **joint)


# --------------------------------------------------------------------------- parallelogram, by hand
A_CRANK, L_GROUND = 0.3, 0.8
PARALLELOGRAM_LINKS = {1: _planar_link(1.0, 0.15, 0.05, 0.01, IA=0.02, FV=0.1),
                       2: _planar_link(2.0, 0.8, -0.1, 0.05, FV=0.2),
                       3: _planar_link(1.5, 0.2, -0.06, 0.02, IA=0.03, FV=0.3),
                       4: dict(FV=0.4)}


def _parallelogram() -> MDHRobot:
    frames = _four_bar_frames(L_GROUND, A_CRANK, L_GROUND, A_CRANK, PARALLELOGRAM_LINKS)
    return MDHRobot.from_table(frames, gravity=(0.0, -G0, 0.0), links=3)


def test_parallelogram_against_its_closed_form():
    """Cranks of length a, ground and coupler of length L: on the parallelogram branch the rocker turns
    with the crank (q3 = q1), the coupler translates (q1 + q2 = 0) and the cut joint turns by q4 = -q1.
    With gravity -g y0, about the joints' axes (ZZ about the frame origins):
        T = 1/2 (ZZ1 + ZZ3 + M2 a^2) qd1^2 (the coupler's points all move at a qd1; it does not turn)
        V = g (MX1 s1 + MY1 c1 + M2 a s1 + MY2 + MX3 s1 + MY3 c1)
    plus the rotors IA1 qd1^2/2, IA3 qd3^2/2 = IA3 qd1^2/2 and the viscous friction of every joint, each
    |dq_j/dq1| = 1, so FV_j qd_j dq_j/dq1 = FV_j qd1:
        Gamma1 = (ZZ1 + ZZ3 + M2 a^2 + IA1 + IA3) qdd1 + g ((MX1 + MX3 + M2 a) c1 - (MY1 + MY3) s1)
                 + (FV1 + FV2 + FV3 + FV4) qd1."""
    robot = _parallelogram()
    assert (robot.n_links, robot.n_loops, robot.links) == (3, 1, 3)
    assert loop_frames(robot) == [(4, 5)]
    assert active_joints(robot).tolist() == [0] and passive_joints(robot).tolist() == [1, 2, 3]
    p = {j: PARALLELOGRAM_LINKS[j] for j in (1, 2, 3)}
    inertia = p[1]["ZZ"] + p[3]["ZZ"] + p[2]["M"] * A_CRANK ** 2 + p[1]["IA"] + p[3]["IA"]
    friction = sum(PARALLELOGRAM_LINKS[j]["FV"] for j in (1, 2, 3, 4))
    rng = np.random.default_rng(0)
    for q1 in rng.uniform(0.2, math.pi - 0.2, 5) * rng.choice([-1, 1], 5):   # away from the dead points 0, pi
        # closed to 1e-14 of the size (2.2 m): the joints to ~1e-13 rad (levers >= 0.3 m), and G, qd, qdd,
        # which vary at O(1) per rad, to ~1e-13 of their O(1..10) values: bounds 1e-11
        q = solve_closure(robot, [q1], [q1 + 0.05, -q1 - 0.05, q1 - 0.05, -q1 + 0.05], tol=1e-14)
        np.testing.assert_allclose(q, [q1, -q1, q1, -q1], rtol=0, atol=1e-11)
        np.testing.assert_allclose(constraint_jacobian(robot, q), [[-1.0], [1.0], [-1.0]], rtol=0, atol=1e-11)
        qd1, qdd1 = rng.uniform(-3, 3, 2)
        qd, qdd = loop_states(robot, q, [qd1], [qdd1])
        np.testing.assert_allclose(qd, [qd1, -qd1, qd1, -qd1], rtol=0, atol=1e-11 * 3)
        np.testing.assert_allclose(qdd, [qdd1, -qdd1, qdd1, -qdd1], rtol=0, atol=1e-11 * 10)
        c, s = math.cos(q1), math.sin(q1)
        expected = inertia * qdd1 + G0 * ((p[1]["MX"] + p[3]["MX"] + p[2]["M"] * A_CRANK) * c
                                          - (p[1]["MY"] + p[3]["MY"]) * s) + friction * qd1
        np.testing.assert_allclose(closed_loop_inverse_dynamics(robot, q, qd, qdd), [expected], rtol=0,
                                   atol=REL * max(1.0, abs(expected)))
        np.testing.assert_allclose(closed_loop_inertia_matrix(robot, q), [[inertia]], rtol=0, atol=1e-11)


# --------------------------------------------------------------------------- four-bar, Lagrange from plane geometry
L0, L1, L2, L3 = 1.0, 0.35, 0.9, 0.6         # Grashof crank-rocker: 0.35 + 1.0 < 0.9 + 0.6, the crank turns fully
FOUR_BAR_LINKS = {1: _planar_link(0.8, 0.12, 0.03, 0.01, IA=0.05, FV=0.2),
                  2: _planar_link(2.0, 0.9, 0.1, 0.08, FV=0.1),
                  3: _planar_link(1.2, 0.35, -0.05, 0.03, IA=0.02, FV=0.15),
                  4: dict(FV=0.05)}


def _angles(q: float) -> tuple[float, float]:
    """phi2, phi3 of the four-bar from plane geometry: A = l1 (c1, s1); B on the circles (A, l2) and
    (O', l3): phi2 = atan2(D) + acos((l2^2 + |D|^2 - l3^2) / (2 l2 |D|)), D = O' - A (one assembly mode),
    phi3 the angle of B - O'."""
    ax, ay = L1 * math.cos(q), L1 * math.sin(q)
    dx, dy = L0 - ax, -ay
    dist = math.hypot(dx, dy)
    phi2 = math.atan2(dy, dx) + math.acos((L2 ** 2 + dist ** 2 - L3 ** 2) / (2 * L2 * dist))
    return phi2, math.atan2(ay + L2 * math.sin(phi2), ax + L2 * math.cos(phi2) - L0)


def _derivative(f, q: float, h: float = 1e-3):
    """Five-point central difference: truncation h^4/30 |f^(5)|, rounding ~eps |f| / h."""
    return (np.subtract(f(q - 2 * h), f(q + 2 * h)) + 8 * np.subtract(f(q + h), f(q - h))) / (12 * h)


def _four_bar_lagrange():
    """Gamma1(q1, qd1, qdd1) and A(q1) of the four-bar by Lagrange, from plane geometry alone.

    One degree of freedom: T = 1/2 m(q) qd^2 with, r2 = dphi2/dq, r3 = dphi3/dq (differences of the closed
    form) and A' = dA/dq = l1 (-s1, c1),
        m = ZZ1 + IA1 + (ZZ3 + IA3) r3^2 + M2 |A'|^2 + ZZ2 r2^2 + 2 r2 A' . (z x R(phi2) MS2)
    (the coupler's T about its joint A: 1/2 M2 v_A^2 + 1/2 ZZ2 w^2 + w v_A . (z x R MS2)); V = g y-moments;
    Rayleigh R = 1/2 sum FV_j (r_j qd)^2 with the relative joint rates r = 1, r2 - 1, r3, r2 - r3. So
        Gamma1 = m qdd + 1/2 m'(q) qd^2 + V'(q) + sum FV_j r_j^2 qd.
    m' and V' are five-point differences too: with h = 1e-3 their error is ~1e-10 of their scale."""
    p = FOUR_BAR_LINKS

    def rates(q):
        return _derivative(lambda x: np.array(_angles(x)), q)

    def mass(q):
        r2, r3 = rates(q)
        phi2 = _angles(q)[0]
        ms = np.array([p[2]["MX"] * math.cos(phi2) - p[2]["MY"] * math.sin(phi2),
                       p[2]["MX"] * math.sin(phi2) + p[2]["MY"] * math.cos(phi2)])
        da = L1 * np.array([-math.sin(q), math.cos(q)])
        return (p[1]["ZZ"] + p[1]["IA"] + (p[3]["ZZ"] + p[3]["IA"]) * r3 ** 2 + p[2]["M"] * da @ da
                + p[2]["ZZ"] * r2 ** 2 + 2 * r2 * (da @ np.array([-ms[1], ms[0]])))

    def potential(q):
        phi2, phi3 = _angles(q)
        return G0 * (p[1]["MX"] * math.sin(q) + p[1]["MY"] * math.cos(q) + p[2]["M"] * L1 * math.sin(q)
                     + p[2]["MX"] * math.sin(phi2) + p[2]["MY"] * math.cos(phi2)
                     + p[3]["MX"] * math.sin(phi3) + p[3]["MY"] * math.cos(phi3))

    def torque(q, qd, qdd):
        r2, r3 = rates(q)
        damping = sum(p[j]["FV"] * r ** 2 for j, r in zip((1, 2, 3, 4), (1.0, r2 - 1.0, r3, r2 - r3)))
        return mass(q) * qdd + 0.5 * _derivative(mass, q) * qd ** 2 + _derivative(potential, q) + damping * qd

    return torque, mass, _angles


@pytest.fixture(scope="module")
def four_bar():
    frames = _four_bar_frames(L0, L1, L2, L3, FOUR_BAR_LINKS)
    return MDHRobot.from_table(frames, gravity=(0.0, -G0, 0.0), links=3), _four_bar_lagrange()


def _closed(robot: MDHRobot, angles, q1: float) -> np.ndarray:
    phi2, phi3 = angles(q1)
    exact = np.array([q1, phi2 - q1, phi3, phi2 - phi3])
    q = solve_closure(robot, [q1], exact + [0.0, 0.08, -0.06, 0.05], tol=1e-14)
    # the guess picks the assembly mode: Newton lands on the one of the closed form
    np.testing.assert_allclose(np.angle(np.exp(1j * (q - exact))), 0.0, rtol=0, atol=1e-10)
    return q


def test_four_bar_against_lagrange(four_bar):
    robot, (torque, mass, angles) = four_bar
    rng = np.random.default_rng(1)
    for q1 in rng.uniform(-math.pi, math.pi, 8):
        q = _closed(robot, angles, q1)
        assert np.max(np.abs(closure_error(robot, q))) <= 1e-14 * 3
        qd1, qdd1 = rng.uniform(-3, 3, 2)
        qd, qdd = loop_states(robot, q, [qd1], [qdd1])
        expected = torque(q1, qd1, qdd1)
        np.testing.assert_allclose(closed_loop_inverse_dynamics(robot, q, qd, qdd), [expected], rtol=0,
                                   atol=STENCIL * max(1.0, abs(expected)))
        np.testing.assert_allclose(closed_loop_inertia_matrix(robot, q), [[mass(q1)]], rtol=0,
                                   atol=STENCIL * max(1.0, abs(mass(q1))))


def test_constraint_jacobian_against_finite_differences_of_the_closure(four_bar):
    robot, (_, _, angles) = four_bar
    h = 1e-5
    for q1 in (-2.5, -0.4, 1.1, 2.9):
        q = _closed(robot, angles, q1)
        plus, minus = _closed(robot, angles, q1 + h), _closed(robot, angles, q1 - h)
        numeric = np.angle(np.exp(1j * (plus - minus)))[1:] / (2 * h)
        np.testing.assert_allclose(constraint_jacobian(robot, q)[:, 0], numeric, rtol=0, atol=1e-6)


def test_virtual_work_at_random_consistent_states(four_bar):
    """Gamma_a . qd_a = Gamma_tr . qd for consistent qd: the loop's reactions do no work. Both sides sum the
    same products in another order: rounding ~1e-15 of |Gamma_tr| |qd|, bound 1e-12 of it."""
    robot, (_, _, angles) = four_bar
    rng = np.random.default_rng(2)
    for q1 in rng.uniform(-math.pi, math.pi, 6):
        q = _closed(robot, angles, q1)
        qd, qdd = loop_states(robot, q, rng.uniform(-3, 3, 1), rng.uniform(-5, 5, 1))
        gamma_tree = inverse_dynamics(robot, q, qd, qdd)
        gamma_a = closed_loop_inverse_dynamics(robot, q, qd, qdd)
        scale = np.max(np.abs(gamma_tree)) * np.max(np.abs(qd))
        assert abs(gamma_a @ qd[active_joints(robot)] - gamma_tree @ qd) <= 1e-12 * scale
        # and the loop's velocities are consistent: the cut and closing frames move together
        from sicomat.robotics import loop_jacobian

        assert np.max(np.abs(loop_jacobian(robot, q) @ qd)) <= 1e-12 * np.max(np.abs(qd))


def test_states_that_do_not_close_and_bad_guesses_are_reported(four_bar):
    from sicomat.errors import AnalysisError

    robot, _ = four_bar
    with pytest.raises(ModelError, match="does not close"):
        constraint_jacobian(robot, [0.3, 0.0, 0.0, 0.0])
    with pytest.raises(ModelError, match="1 finite values"):
        solve_closure(robot, [0.1, 0.2], np.zeros(4))
    with pytest.raises(AnalysisError, match="did not close"):
        solve_closure(robot, [0.3], np.zeros(4), max_iterations=1)


# --------------------------------------------------------------------------- validation of the table
def _loop_table(**changes: dict) -> list[dict]:
    frames = [dict(row) for row in _four_bar_frames(L0, L1, L2, L3, FOUR_BAR_LINKS)]
    for key, row_changes in changes.items():
        frames[int(key[1:]) - 1].update(row_changes)
    return frames


@pytest.mark.parametrize("frames,links,path,words", [
    (_loop_table(), 2, "frames[4].ant", "odd"),                                  # NF - NL = 3
    (_loop_table(f5={"sigma": 0}), 3, "frames[4].sigma", "closing frame is fixed"),
    (_loop_table(f4={"sigma": 2, "FV": 0.0}), 3, "frames[3].sigma", "no cut joint"),
    (_loop_table(f4={"mu": 1}), 3, "frames[3].mu", "passive"),
    (_loop_table(f4={"eta": 1}), 3, "frames[3].eta", "passive"),
    (_loop_table(f5={"ant": 3}), 3, "frames[4].ant", "same link"),
    (_loop_table(f4={"M": 1.0}), 3, "frames[3].M", "carries no link"),
    (_loop_table(f5={"ant": 4}), 3, "frames[4].ant", "hangs from a link"),
])
def test_bad_loops_are_rejected_naming_frame_and_field(frames, links, path, words):
    with pytest.raises(ModelError) as caught:
        MDHRobot.from_table(frames, links=links)
    assert caught.value.path == path
    j = int(path.split("[")[1].split("]")[0]) + 1
    assert str(caught.value).startswith(f"{path}: frame {j}: ") and words in str(caught.value)


def test_a_closing_frame_on_the_same_link_through_a_fixed_frame():
    """The link of a frame is found up its fixed frames: a closing frame on a tool frame of the rocker
    sits on the rocker, the cut joint's own link."""
    frames = _loop_table()
    frames.insert(3, dict(ant=3, sigma=2, r=0.1))                # frame 4: a fixed frame on the rocker
    frames[4].update(ant=3)                                      # cut frame 5 on the rocker
    frames[5].update(ant=4)                                      # closing frame 6 on frame 4, the rocker
    with pytest.raises(ModelError, match="same link") as caught:
        MDHRobot.from_table(frames, links=4)
    assert caught.value.path == "frames[5].ant"


@pytest.mark.parametrize("links", [0, 6, True, 2.5, "3"])
def test_bad_links(links):
    with pytest.raises(ModelError, match="links") as caught:
        MDHRobot.from_table(_loop_table(), links=links)
    assert caught.value.path == "links"


def test_a_tree_has_no_loops():
    robot = MDHRobot.from_table(_loop_table()[:3])
    assert robot.links is None and robot.n_links == 3 and robot.n_loops == 0 and loop_frames(robot) == []
    assert MDHRobot.from_table(_loop_table()[:3], links=3).n_loops == 0


def test_a_tilted_four_bar_is_the_flat_one_under_rotated_gravity():
    """The four-bar mounted on a fixed frame tilted in space (gamma, b, alpha, d, theta all nonzero): the
    closure's rotation rows now mix all three axes. Its motion in its plane is the flat four-bar's under
    the gravity seen from the plane's frame, R1^T g (written by hand from the constant rotation
    Rz(gamma) Rx(alpha) Rz(theta)); the two tables go through the same code, so this checks the spatial
    closure and its Jacobian, not the dynamics (checked above). The two Newton solves close to 1e-14 of the
    size (~3 m), so their joints agree to ~1e-13 rad (levers >= 0.3 m); G, qdd and the torques vary by
    O(1..10) per rad: bounds 1e-11 (q, G), 1e-10 (qdd, up to ~50 rad/s^2) and 1e-11 of the torque scale."""
    gamma, alpha, theta = 0.3, 0.7, 0.4
    cg, sg, ca, sa, ct, st = (f(x) for x in (gamma, alpha, theta) for f in (math.cos, math.sin))
    rot = (np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
           @ np.array([[ct, -st, 0], [st, ct, 0], [0, 0, 1]]))
    gravity = np.array([0.0, 0.0, -G0])
    flat_frames = _four_bar_frames(L0, L1, L2, L3, FOUR_BAR_LINKS)
    tilted_frames = [dict(ant=0, sigma=2, gamma=gamma, b=0.1, alpha=alpha, d=0.2, theta=theta)] + \
        [dict(row, ant=row["ant"] + 1) for row in flat_frames]
    flat = MDHRobot.from_table(flat_frames, gravity=rot.T @ gravity, links=3)
    tilted = MDHRobot.from_table(tilted_frames, gravity=gravity, links=4)
    rng = np.random.default_rng(3)
    for q1 in rng.uniform(-math.pi, math.pi, 4):
        phi2, phi3 = _angles(q1)
        guess = np.array([q1, phi2 - q1, phi3, phi2 - phi3]) + [0.0, 0.05, -0.05, 0.05]
        q = solve_closure(tilted, [q1], guess, tol=1e-14)
        np.testing.assert_allclose(q, solve_closure(flat, [q1], guess, tol=1e-14), rtol=0, atol=1e-11)
        assert np.max(np.abs(closure_error(tilted, q))) <= 1e-14 * 3
        np.testing.assert_allclose(constraint_jacobian(tilted, q), constraint_jacobian(flat, q), rtol=0, atol=1e-11)
        qd, qdd = loop_states(tilted, q, rng.uniform(-3, 3, 1), rng.uniform(-5, 5, 1))
        flat_qd, flat_qdd = loop_states(flat, q, qd[:1], qdd[:1])
        np.testing.assert_allclose(qdd, flat_qdd, rtol=0, atol=1e-10)
        torque = closed_loop_inverse_dynamics(tilted, q, qd, qdd)
        np.testing.assert_allclose(torque, closed_loop_inverse_dynamics(flat, q, flat_qd, flat_qdd), rtol=0,
                                   atol=1e-11 * max(1.0, float(np.max(np.abs(torque)))))
