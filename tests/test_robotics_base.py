"""Base inertial parameters (issue 13): :func:`sicomat.robotics.base_parameters`.

Where the expected numbers come from (none is taken from this code's output):
- the counts and the kept parameters of the Stäubli RX-90 and the PUMA 560, and the elastic XY
  cross-slide's 24: ``shared/reference/robotics-formalism.md`` §3.1 and §2.7 (pitfall a);
- the RX-90 regrouping relations: the notes' §3.2, which the symbolic rules of Gautier & Khalil
  (notes §2.7) reproduce (checked by hand for the ones used here);
- the planar 2R arm and the rigid XY cross-slide: counted by hand below from their closed forms
  (notes §3.3 and §4);
- base-parameter torques: the robot's own inverse dynamics (Newton–Euler, checked against Pinocchio in
  ``test_robotics_core.py``).

Tolerances. The counts are integers. A regrouping coefficient is a product of lengths and unit
factors of order 0.01..1; beta comes from a least-squares fit of columns that are exact combinations,
so its error is rounding times the conditioning of the kept columns (~1e2 here): ~1e-13, and 1e-9
leaves a margin of 1e4 while a wrong coefficient (a missing term, D3 for D3^2, a sign) is off by
O(0.1). Torques are O(1..100) N m computed in a few hundred operations: rounding ~1e-13 of their
scale, against 1e-9 of it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sicomat.robotics import BaseParameters, MDHRobot, base_parameters, inverse_dynamics_batch, regressor_batch
from sicomat.robotics.table import PARAMETER_FIELDS

from robotics_models import elastic_cross_slide_frames, physical_inertia

PI = math.pi
COEF = 1e-9
REL = 1e-9
D3, RL4 = 0.45, 0.35      # the notes use 0.45 for both; different values catch a D3/RL4 swap


# --------------------------------------------------------------------------- robots
_physical = physical_inertia


def _six_axis(alpha, d, r, seed: int = 0) -> MDHRobot:
    rng = np.random.default_rng(seed)
    rows = []
    for j in range(6):
        row = {"ant": j, "sigma": 0, "mu": 1, "alpha": alpha[j], "d": d[j], "r": r[j], **_physical(rng)}
        row.update(IA=rng.uniform(0.01, 0.2), FV=rng.uniform(0.0, 0.5), FS=rng.uniform(0.0, 0.5))
        rows.append(row)
    return MDHRobot.from_table(rows, gravity=(0.0, 0.0, -9.81))


def rx90(seed: int = 0) -> MDHRobot:
    """SYMORO's RX-90 sample (notes §3.1): alpha = 0, pi/2, 0, -pi/2, pi/2, -pi/2; d3 = D3, r4 = RL4."""
    return _six_axis([0, PI / 2, 0, -PI / 2, PI / 2, -PI / 2], [0, 0, D3, 0, 0, 0], [0, 0, 0, RL4, 0, 0], seed)


def puma560(seed: int = 0) -> MDHRobot:
    """Craig's MDH table of the PUMA 560 (notes §3.1) in Khalil's fields: d_j = a_{j-1}, r_j = d_j."""
    return _six_axis([0, -PI / 2, 0, -PI / 2, PI / 2, -PI / 2], [0, 0, 0.4318, 0.0203, 0, 0],
                     [0, 0, 0.15005, 0.4318, 0, 0], seed)


L = 0.7


def planar_2r(gravity=(0.0, 0.0, -9.81)) -> MDHRobot:
    """Two parallel revolute axes z1 = z2 = z0, d2 = L (notes §3.3)."""
    rng = np.random.default_rng(7)
    rows = [{"ant": 0, "sigma": 0, "mu": 1, **_physical(rng), "IA": 0.05, "FV": 0.1, "FS": 0.2},
            {"ant": 1, "sigma": 0, "mu": 1, "d": L, **_physical(rng), "IA": 0.03, "FV": 0.2, "FS": 0.1}]
    return MDHRobot.from_table(rows, gravity=gravity)


def cross_slide() -> MDHRobot:
    """The rigid XY cross-slide of the notes §4 (x1 = z0): A = diag(M1+M2+IA1, M2+IA2)."""
    rng = np.random.default_rng(3)
    rows = [{"ant": 0, "sigma": 1, "mu": 1, "gamma": PI / 2, "alpha": PI / 2, "theta": PI / 2, **_physical(rng),
             "IA": 40.0, "FV": 100.0, "FS": 20.0},
            {"ant": 1, "sigma": 1, "mu": 1, "alpha": PI / 2, **_physical(rng), "IA": 25.0, "FV": 80.0, "FS": 15.0}]
    return MDHRobot.from_table(rows, gravity=(0.0, 0.0, -9.81))


def elastic_cross_slide() -> MDHRobot:
    """The elastic XY cross-slide of the notes §4 (the table in ``tests/robotics_models.py``)."""
    return MDHRobot.from_table(elastic_cross_slide_frames(), gravity=(0.0, 0.0, -9.81))


def _states(robot: MDHRobot, seed: int, count: int = 25):
    rng = np.random.default_rng(seed)
    n = robot.n_joints
    return rng.uniform(-PI, PI, (count, n)), rng.uniform(-2, 2, (count, n)), rng.uniform(-5, 5, (count, n))


def _coefficient(base: BaseParameters, kept: str, dropped: str) -> float:
    row = base.names.index(kept)
    return float(base.beta[row, base.dropped.index(dropped)]) if dropped in base.dropped else 0.0


def _assert_relation(base: BaseParameters, kept: str, expected: dict[str, float]) -> None:
    """The row of ``kept`` in beta is exactly ``expected`` (every other dropped parameter 0)."""
    assert kept in base.names
    for name in expected:
        assert name in base.dropped, f"{name} should be regrouped into {kept}"
    found = {name: _coefficient(base, kept, name) for name in base.dropped}
    for name, value in found.items():
        assert value == pytest.approx(expected.get(name, 0.0), abs=COEF), (kept, name)


# --------------------------------------------------------------------------- counts (notes §3.1)
def _kept_pattern(with_joint_terms: bool) -> set[str]:
    """The notes' 'kept' column: ZZ1; links 2-6: XX XY XZ YZ ZZ MX MY; IA3-6; FV/FS x6."""
    kept = {"ZZ1"} | {f"{p}{j}" for j in range(2, 7) for p in ("XX", "XY", "XZ", "YZ", "ZZ", "MX", "MY")}
    if with_joint_terms:
        kept |= {f"IA{j}" for j in range(3, 7)} | {f"{p}{j}" for j in range(1, 7) for p in ("FV", "FS")}
    return kept


@pytest.mark.parametrize("make", [rx90, puma560], ids=["RX-90", "PUMA 560"])
@pytest.mark.parametrize("parameters, count", [("inertial", 36), ("all", 52)])
def test_six_axis_counts_and_kept_parameters(make, parameters, count):
    base = make().base_parameters(parameters=parameters)
    assert base.count == count
    assert set(base.names) == _kept_pattern(parameters == "all")
    considered = 6 * (10 if parameters == "inertial" else 13)
    assert base.count + len(base.dropped) + len(base.unidentifiable) == considered


def test_planar_2r_counts_by_hand():
    """Vertical axes: gravity does no work, so only the inertia terms of §3.3 remain:
    tau1 = (ZZ1R + ZZ2 + 2a) qdd1 + (ZZ2 + a) qdd2 - b(2 qd1 qd2 + qd2^2), tau2 = (ZZ2 + a) qdd1 +
    (ZZ2 + IA2) qdd2 + b qd1^2, a and b linear in MX2, MY2. Independent functions of the state multiply
    ZZ1R ([qdd1, 0]), ZZ2 ([qdd1 + qdd2, qdd1 + qdd2]), MX2, MY2 (the a, b terms, in quadrature) and IA2
    ([0, qdd2]): 4 inertial, 5 with IA (IA1 goes into ZZ1R), 9 with FV, FS of both joints."""
    robot = planar_2r()
    assert robot.base_parameters(parameters="inertial").count == 4
    base = robot.base_parameters()
    assert base.count == 9
    assert set(base.names) == {"ZZ1", "ZZ2", "MX2", "MY2", "IA2", "FV1", "FS1", "FV2", "FS2"}
    _assert_relation(base, "ZZ1", {"IA1": 1.0, "M2": L ** 2})     # ZZ1R = ZZ1 + L^2 M2 + IA1 (§3.2, §3.3)
    for name in ("ZZ2", "MX2", "MY2", "IA2"):
        _assert_relation(base, name, {})
    chi = dict(zip(robot.parameter_names(), robot.standard_parameters()))
    values = dict(zip(base.names, base.values))
    assert values["ZZ1"] == pytest.approx(chi["ZZ1"] + L ** 2 * chi["M2"] + chi["IA1"], rel=REL)


def test_planar_2r_with_gravity_in_its_plane():
    """Gravity along -y0 (axes horizontal): the potential energy g (MX1 s1 + MY1 c1 + L M2 s1 + MX2 s12 +
    MY2 c12) adds MX1R = MX1 + L M2 (§3.2) and MY1 to the 4 of the vertical arm: 6 inertial."""
    base = planar_2r(gravity=(0.0, -9.81, 0.0)).base_parameters(parameters="inertial")
    assert base.count == 6
    assert set(base.names) == {"ZZ1", "MX1", "MY1", "ZZ2", "MX2", "MY2"}
    _assert_relation(base, "MX1", {"M2": L})
    _assert_relation(base, "ZZ1", {"M2": L ** 2})


def test_rigid_cross_slide():
    """Notes §4: A = diag(M1+M2+IA1, M2+IA2), no Coriolis, no gravity (both axes horizontal): the torques
    are two independent functions of the state times (M1+M2+IA1) and (M2+IA2), so 2 base parameters
    (with or without IA), 2 more per joint with friction."""
    robot = cross_slide()
    assert robot.base_parameters(parameters="inertial").count == 2
    base = robot.base_parameters()
    assert base.count == 6
    assert set(base.names) == {"M1", "M2", "FV1", "FS1", "FV2", "FS2"}
    chi = dict(zip(robot.parameter_names(), robot.standard_parameters()))
    values = dict(zip(base.names, base.values))
    # columns M1 = [qdd1, 0], M2 = [qdd1, qdd2]: tau = values[M1] [qdd1, 0] + values[M2] [qdd1, qdd2]
    assert values["M1"] + values["M2"] == pytest.approx(chi["M1"] + chi["M2"] + chi["IA1"], rel=REL)
    assert values["M2"] == pytest.approx(chi["M2"] + chi["IA2"], rel=REL)


def test_elastic_cross_slide_leading_zero_columns():
    """Notes §2.7 pitfall (a): the elastic XY model (a massless first link, so its first columns are zero)
    has 24 base parameters (13 per link), which an unpivoted QR's diagonal reads as 22."""
    robot = elastic_cross_slide()
    base = robot.base_parameters()
    assert base.count == 24
    assert "XX1" in base.unidentifiable
    assert "IA1" in base.dropped and _coefficient(base, "M1", "IA1") == pytest.approx(1.0, abs=COEF)  # IA1 = M1
    assert "IA4" in base.names                                   # IA4 is not M4: M4 is carried by joints 1-3


def test_the_elastic_cross_slide_is_a_pitfall_case():
    """The case above has teeth: on its stacked regressor the diagonal of an unpivoted QR (zero columns
    first) shows fewer than the 24 of the notes, as §2.7 (a) says (22 there)."""
    import scipy.linalg

    robot = elastic_cross_slide()
    q, qd, qdd = _states(robot, seed=0, count=60)
    w = regressor_batch(robot, q, qd, qdd).reshape(-1, 13 * robot.n_frames)
    diagonal = np.abs(np.diag(scipy.linalg.qr(w, mode="r")[0]))
    assert np.sum(diagonal > 1e-8 * diagonal.max()) < 24


# --------------------------------------------------------------------------- relations (notes §3.2)
@pytest.mark.parametrize("parameters", ["inertial", "all"])
def test_rx90_regrouping_relations(parameters):
    base = rx90().base_parameters(parameters=parameters)
    mr3 = {f"M{j}": 1.0 for j in (3, 4, 5, 6)}
    mr4 = {f"M{j}": 1.0 for j in (4, 5, 6)}

    def times(factor: float, terms: dict[str, float]) -> dict[str, float]:
        return {name: factor * value for name, value in terms.items()}

    # ZZ1R, by the notes' §2.7 rules by hand: joint 2 (alpha2 = pi/2, d2 = r2 = 0) sends ZZ1 += YY2',
    # joint 3 (alpha3 = 0, d3 = D3) made YY2' = YY2 + YY3' + D3^2 MR3, joint 4 (alpha4 = -pi/2, d4 = 0)
    # leaves YY3' = YY3; IA1 joins ZZ1 (j = r1)
    _assert_relation(base, "ZZ1", {"YY2": 1.0, "YY3": 1.0, **times(D3 ** 2, mr3),
                                   **({"IA1": 1.0} if parameters == "all" else {})})
    _assert_relation(base, "XX2", {"YY2": -1.0, **times(-D3 ** 2, mr3)})
    _assert_relation(base, "XZ2", {"MZ3": -D3})
    _assert_relation(base, "ZZ2", {**times(D3 ** 2, mr3), **({"IA2": 1.0} if parameters == "all" else {})})
    _assert_relation(base, "MX2", times(D3, mr3))
    _assert_relation(base, "XX3", {"YY3": -1.0, "YY4": 1.0, "MZ4": 2 * RL4, **times(RL4 ** 2, mr4)})
    _assert_relation(base, "ZZ3", {"YY4": 1.0, "MZ4": 2 * RL4, **times(RL4 ** 2, mr4)})
    _assert_relation(base, "MY3", {"MZ4": 1.0, **times(RL4, mr4)})
    labels = dict(zip(base.names, base.labels))
    assert labels["XX2"] == "XX2R" and labels["XY2"] == "XY2"
    relation = base.relations[base.names.index("MX2")]
    assert relation.startswith("MX2R = MX2 + 0.45 M3 + 0.45 M4")


# --------------------------------------------------------------------------- the base model is the model
@pytest.mark.parametrize("make", [rx90, puma560, planar_2r, cross_slide, elastic_cross_slide],
                         ids=["RX-90", "PUMA 560", "2R", "XY", "elastic XY"])
def test_base_torques_equal_standard_torques(make):
    robot = make()
    base = robot.base_parameters()
    q, qd, qdd = _states(robot, seed=99)                 # not the states the base parameters were found on
    tau = inverse_dynamics_batch(robot, q, qd, qdd)
    phi = regressor_batch(robot, q, qd, qdd)
    scale = np.max(np.abs(tau))
    np.testing.assert_allclose(phi[:, :, base.indices] @ base.values, tau, rtol=0, atol=REL * scale)
    # any other standard parameters of the same geometry regroup the same way
    other = np.random.default_rng(5).uniform(-1, 1, robot.standard_parameters().shape)
    np.testing.assert_allclose(phi[:, :, base.indices] @ base.regroup(other), phi @ other, rtol=0,
                               atol=REL * np.max(np.abs(phi @ other)))


def test_inertial_base_torques_are_the_rigid_body_torques():
    robot = rx90()
    base = robot.base_parameters(parameters="inertial")
    q, qd, qdd = _states(robot, seed=98)
    rows = robot.joint_frames
    ia, fv, fs = (robot.chi[rows, PARAMETER_FIELDS.index(p)] for p in ("IA", "FV", "FS"))
    rigid = inverse_dynamics_batch(robot, q, qd, qdd) - (ia * qdd + fv * qd + fs * np.sign(qd))
    phi = regressor_batch(robot, q, qd, qdd)
    np.testing.assert_allclose(phi[:, :, base.indices] @ base.values, rigid, rtol=0,
                               atol=REL * np.max(np.abs(rigid)))


def _random_tree(seed: int) -> MDHRobot:
    """Any structure: branches, prismatic joints, fixed frames, nonzero gamma and b (as in the core's tests)."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, float]] = []
    for j in range(1, int(rng.integers(4, 8)) + 1):
        sigma = int(rng.choice([0, 1, 2], p=[0.5, 0.35, 0.15])) if j > 1 else int(rng.integers(0, 2))
        row: dict[str, float] = {"ant": int(rng.integers(0, j)), "sigma": sigma, **_physical(rng)}
        row.update({key: rng.uniform(-PI, PI) for key in ("gamma", "alpha", "theta")})
        row.update({key: rng.uniform(-0.5, 0.5) for key in ("b", "d", "r")})
        if sigma != 2:
            row.update(IA=rng.uniform(0.0, 0.2), FV=rng.uniform(0.0, 0.5), FS=rng.uniform(0.0, 0.5))
        rows.append(row)
    return MDHRobot.from_table(rows, gravity=(0.0, 0.0, -9.81))


@pytest.mark.parametrize("seed", range(6))
def test_any_tree(seed):
    """The numerical method needs no structure: the base model reproduces the torques, and the count is
    the rank of a fresh stack of regressors by numpy's own SVD (its default tolerance)."""
    robot = _random_tree(seed)
    base = robot.base_parameters()
    q, qd, qdd = _states(robot, seed=seed + 50, count=80)
    tau = inverse_dynamics_batch(robot, q, qd, qdd)
    phi = regressor_batch(robot, q, qd, qdd)
    np.testing.assert_allclose(phi[:, :, base.indices] @ base.values, tau, rtol=0, atol=REL * np.max(np.abs(tau)))
    assert base.count == np.linalg.matrix_rank(phi.reshape(-1, phi.shape[-1]))


@pytest.mark.parametrize("make", [rx90, puma560, planar_2r, cross_slide, elastic_cross_slide],
                         ids=["RX-90", "PUMA 560", "2R", "XY", "elastic XY"])
def test_count_is_the_rank_by_svd(make):
    robot = make()
    q, qd, qdd = _states(robot, seed=77, count=80)
    phi = regressor_batch(robot, q, qd, qdd)
    assert robot.base_parameters().count == np.linalg.matrix_rank(phi.reshape(-1, phi.shape[-1]))


def test_a_selection_short_of_the_rank_is_reported(monkeypatch):
    """The guard between the column selection and the pivoted-QR rank (they disagree only when the
    tolerance meets the conditioning of the states) raises instead of returning a wrong count."""
    from sicomat.errors import AnalysisError
    from sicomat.robotics import base as module

    real = module._pivoted_rank
    monkeypatch.setattr(module, "_pivoted_rank", lambda columns, tol: real(columns, tol) + 1)
    with pytest.raises(AnalysisError, match="rank"):
        rx90().base_parameters()


def test_regroup_checks_its_input():
    base = planar_2r().base_parameters()
    with pytest.raises(ValueError, match="26 standard parameters"):
        base.regroup(np.zeros(20))


# --------------------------------------------------------------------------- determinism, samples
def test_deterministic_under_a_seed():
    robot = puma560()
    first, second = robot.base_parameters(seed=3), robot.base_parameters(seed=3)
    assert first.names == second.names and first.dropped == second.dropped
    np.testing.assert_array_equal(first.beta, second.beta)
    np.testing.assert_array_equal(first.values, second.values)


@pytest.mark.parametrize("samples", [13, 40, 250])     # 13 = ceil(78 parameters / 6 joints), the minimum
def test_independent_of_seed_and_samples_above_the_minimum(samples):
    robot = rx90()
    reference = robot.base_parameters()
    base = robot.base_parameters(samples=samples, seed=11)
    assert base.names == reference.names and base.dropped == reference.dropped
    assert base.unidentifiable == reference.unidentifiable
    np.testing.assert_allclose(base.beta, reference.beta, rtol=0, atol=COEF)
    np.testing.assert_allclose(base.values, reference.values, rtol=0, atol=REL * np.max(np.abs(reference.values)))


def test_too_few_samples_and_bad_arguments_are_rejected():
    robot = rx90()
    with pytest.raises(ValueError, match="samples >= 13"):
        robot.base_parameters(samples=12)
    with pytest.raises(ValueError, match="parameters"):
        robot.base_parameters(parameters="friction")
    with pytest.raises(ValueError, match="tol"):
        robot.base_parameters(tol=0.0)
    fixed = MDHRobot.from_table([{"ant": 0, "sigma": 2, "M": 1.0}])
    with pytest.raises(ValueError, match="no joint"):
        base_parameters(fixed)


def test_to_dict_is_plain_data():
    import json

    base = planar_2r().base_parameters(parameters="inertial")
    data = json.loads(json.dumps(base.to_dict()))
    assert data["count"] == 4 and data["names"] == list(base.names)
    assert data["relations"][0].startswith("ZZ1R = ZZ1 + ")
    assert len(data["values"]) == 4
