"""Conformance of every registered block type (description/registry.py): setpoint generators and mechanical
structures run through the same checks, parametrized over the registry, so a newly registered type is
tested here without editing this file. Each type's examples are its ``json_schema_extra["examples"]``."""

from __future__ import annotations

import numpy as np
import pytest

from sicomat.description import registry
from sicomat.description.mechanics import GROUND, LumpedSpec
from sicomat.errors import ModelError
from sicomat.io.modelfile import dump_model, load_model, machine_from_dict
from sicomat.mechanics.lumped import build_mechanics
from sicomat.motion.setpoints import lowers, profile_from_spec

EPS = np.finfo(float).eps
SOURCE = "kinds.toml"
# an axis for the setpoints to sit on (any valid mechanics will do)
AXIS_MECHANICS = {"type": "chain", "masses": [1.0, 2.0], "stiffnesses": [100.0]}


def _examples(kind: str) -> list[tuple[str, int, dict]]:
    cases = []
    for type_name in registry.registered_types(kind):
        cls = registry.spec_class(kind, type_name)
        extra = cls.model_config.get("json_schema_extra") or {}
        examples = extra.get("examples") if isinstance(extra, dict) else None
        # a registered type without examples cannot be checked: it fails here, visibly
        cases += [(type_name, i, ex) for i, ex in enumerate(examples or [None])]
    return cases


def _params(kind: str):
    return [pytest.param(kind, t, ex, id=f"{t}-{i}") for t, i, ex in _examples(kind)]


ALL = _params("mechanics") + _params("setpoint")
SETPOINTS = _params("setpoint")
MECHANICS = _params("mechanics")


def _machine_data(kind: str, table: dict) -> dict:
    key = registry.KINDS[kind][0]
    axis = {key: table} if kind == "mechanics" else {"mechanics": AXIS_MECHANICS, key: table}
    return {"name": "kinds", "axes": {"X": axis}}


def _load_error(kind: str, table: dict) -> ModelError:
    with pytest.raises(ModelError) as info:
        machine_from_dict(_machine_data(kind, table), source=SOURCE)
    return info.value


# --------------------------------------------------------------------------- every kind
@pytest.mark.parametrize(("kind", "type_name", "example"), ALL)
def test_example_is_of_its_type(kind, type_name, example):
    assert example is not None, f"{type_name}: give its class json_schema_extra={{'examples': [...]}}"
    assert example["type"] == type_name
    spec = registry.spec_class(kind, type_name).model_validate(example)
    assert isinstance(spec, registry.KINDS[kind][1])          # the kind's protocol


@pytest.mark.parametrize(("kind", "type_name", "example"), ALL)
def test_round_trip_through_the_model_file(tmp_path, kind, type_name, example):
    machine = machine_from_dict(_machine_data(kind, example), source=SOURCE)
    block = getattr(machine.axes["X"], registry.KINDS[kind][0])
    assert type(block) is registry.spec_class(kind, type_name)
    path = tmp_path / "model.toml"
    path.write_text(dump_model(machine), encoding="utf-8")
    # the file holds SI floats written by repr (shortest round-trip form): equal, not close
    assert load_model(path) == machine


@pytest.mark.parametrize(("kind", "type_name", "example"), ALL)
def test_unknown_key_is_located(kind, type_name, example):
    error = _load_error(kind, {**example, "bogus": 1})
    key = registry.KINDS[kind][0]
    assert error.path == f"axes.X.{key}.bogus"
    assert "unknown key" in str(error) and SOURCE in str(error)


@pytest.mark.parametrize(("kind", "type_name", "example"), ALL)
def test_missing_required_keys_are_located(kind, type_name, example):
    cls = registry.spec_class(kind, type_name)
    key = registry.KINDS[kind][0]
    required = [name for name, field in cls.model_fields.items() if field.is_required() and name != "type"]
    for name in required:
        error = _load_error(kind, {k: v for k, v in example.items() if k != name})
        assert error.path == f"axes.X.{key}.{name}", name
        assert "missing required key" in str(error)


@pytest.mark.parametrize(("kind", "type_name", "example"), ALL)
def test_bad_values_are_located(kind, type_name, example):
    # every parameter of the example replaced by a word: no field (number, quantity, list, table, name
    # pattern, literal) accepts it, and the error names the parameter's key path and the word
    key = registry.KINDS[kind][0]
    for name in example:
        if name == "type":
            continue
        error = _load_error(kind, {**example, name: "wrong"})
        assert error.path is not None and error.path.startswith(f"axes.X.{key}.{name}"), (name, error)
        assert "'wrong'" in str(error), (name, error)


@pytest.mark.parametrize("kind", list(registry.KINDS))
def test_unknown_and_missing_type_list_every_registered_type(kind):
    key = registry.KINDS[kind][0]
    known = registry.registered_types(kind)
    error = _load_error(kind, {"type": "no-such-type"})
    assert error.path == f"axes.X.{key}"
    assert str(error).endswith("unknown type; expected one of " + ", ".join(repr(t) for t in known)
                               + " (got 'no-such-type')")
    error = _load_error(kind, {})
    assert error.path == f"axes.X.{key}"
    assert "missing key 'type'; expected one of " + ", ".join(sorted(known)) in str(error)
    with pytest.raises(ModelError) as info:            # the same error from Python
        registry.spec_class(kind, "no-such-type")
    assert info.value.path == key and all(repr(t) in str(info.value) for t in known)


# --------------------------------------------------------------------------- the registry itself
def test_register_refuses_what_the_file_could_not_read():
    from typing import Literal

    from sicomat.description.base import Spec

    class NoLiteral(Spec):
        type: str = "x"

    class Lumped2(Spec):
        type: Literal["lumped"]

        def to_lumped(self):  # pragma: no cover - never called
            raise NotImplementedError

    class NoLowering(Spec):
        type: Literal["rigid"]

    class Late(Spec):
        type: Literal["late"]
        start: float = 0.0

    with pytest.raises(ValueError, match="Literal"):
        registry.register("setpoint")(NoLiteral)
    with pytest.raises(ValueError, match="Literal\\['other'\\]"):
        registry.register("setpoint", "other")(Late)
    with pytest.raises(ValueError, match="already registered by LumpedSpec"):
        registry.register("mechanics")(Lumped2)
    with pytest.raises(ValueError, match="lacks to_lumped"):
        registry.register("mechanics")(NoLowering)
    # after the union is built a new type would be listed here but refused by the loader: refused now
    with pytest.raises(ValueError, match="union is already built"):
        registry.register("setpoint")(Late)
    with pytest.raises(ValueError, match="unknown block kind"):
        registry.register("gearbox")
    assert "late" not in registry.registered_types("setpoint")
    with pytest.raises(ValueError, match="no setpoint type 'late'"):
        lowers("late")


# --------------------------------------------------------------------------- setpoint generators
def _left_limits(profile, name_of_value: str, name_of_rate: str) -> np.ndarray:
    """Left limit, at each break, of a piecewise polynomial quantity (acceleration from jerk, velocity
    from acceleration, ...): the previous piece's value at its end; 0 before the first break."""
    b = np.asarray(profile.breaks)
    value = np.asarray(getattr(profile, name_of_value), dtype=float)
    rate = np.asarray(getattr(profile, name_of_rate, np.zeros_like(b)), dtype=float)
    left = np.zeros_like(b)
    left[1:] = value[:-1] + rate[:-1] * np.diff(b)
    return left


@pytest.mark.parametrize(("kind", "type_name", "example"), SETPOINTS)
def test_setpoint_profile_is_consistent(kind, type_name, example):
    spec = registry.spec_class(kind, type_name).model_validate(example)
    profile = profile_from_spec(spec)
    start = spec.start
    assert profile.breaks[0] == start                       # the move begins at 'start', not before
    if start > 0:
        before = np.linspace(0.0, start, 101)[:-1]
        for column in profile.evaluate(before):
            assert np.all(column == 0.0)

    end = profile.end_time + max(0.1 * (profile.end_time - start), 0.05)
    n = 20001
    t = np.linspace(start, end, n)
    h = (end - start) / (n - 1)
    p, v, a = profile.evaluate(t)
    span = end - start
    jerks = np.asarray(getattr(profile, "jerks", np.zeros(len(profile.breaks))), dtype=float)
    acc = np.asarray(profile.accelerations, dtype=float)
    da = np.abs(acc - _left_limits(profile, "accelerations", "jerks"))    # jumps of a (kinks of v)
    dj = np.abs(np.diff(np.concatenate(([0.0], jerks, [0.0]))))            # jumps of j (kinks of a)
    rounding = lambda scale: (n + 10) * EPS * scale   # noqa: E731  summing n terms, evaluating p, v

    # p(t) - p(start) = ∫ v by the trapezoid rule. Its error (Peano kernel (s-a)(b-s)/2 >= 0): on each
    # interval ≤ h³/12 · max|v''| = h³/12 · max|jerk| (v' = a is continuous there), plus ≤ h²/8 · |Δa|
    # on an interval holding a break where a jumps by Δa (a kink of v); total as below, plus rounding
    integral = np.concatenate(([0.0], np.cumsum(h * (v[1:] + v[:-1]) / 2)))
    vmax, pmax = np.max(np.abs(v)), np.max(np.abs(p))
    bound = span * h ** 2 / 12 * np.max(np.abs(jerks)) + h ** 2 / 8 * da.sum() + rounding(vmax * span + pmax)
    assert np.max(np.abs(p - p[0] - integral)) <= bound

    # v(t) - v(start) = ∫ a: exact inside pieces (a is linear), ≤ h²/8 · |Δj| where the jerk jumps (a
    # kink of a) and ≤ h/2 · |Δa| where a itself jumps (an interval's trapezoid averages the two sides)
    integral = np.concatenate(([0.0], np.cumsum(h * (a[1:] + a[:-1]) / 2)))
    bound = h / 2 * da.sum() + h ** 2 / 8 * dj.sum() + rounding(np.max(np.abs(a)) * span + vmax)
    assert np.max(np.abs(v - v[0] - integral)) <= bound

    distance = getattr(spec, "distance", None)
    if distance is not None:
        # at rest at 'distance' once the move ends: the last piece's position is the sum of at most
        # 7 pieces' displacements (4 roundings each, ≤ eps/2 · |D|): 16 eps · |D| covers it
        after = t >= profile.end_time
        assert after.sum() > 1000
        assert np.max(np.abs(p[after] - distance)) <= 16 * EPS * abs(distance)
        assert np.max(np.abs(v[after])) <= 16 * EPS * vmax
        assert np.max(np.abs(a[after])) <= 16 * EPS * np.max(np.abs(a))
        assert profile.distance == pytest.approx(distance, rel=16 * EPS)


# --------------------------------------------------------------------------- mechanical structures
def _rigid_motions(lumped: LumpedSpec) -> np.ndarray:
    """Oracle from the spec's graph, not from K: the motions no coupling resists (columns).

    A coupling asks r0·q[b0] = r1·q[b1] (a ground end or a zero ratio pins the other end to 0).
    Propagate q = 1 from one body of each group of bodies joined by couplings; the group moves
    rigidly unless a pin or a loop of inconsistent ratios stops it."""
    names = list(lumped.bodies)
    index = {name: i for i, name in enumerate(names)}
    edges: dict[str, list[tuple[str, float, float]]] = {name: [] for name in names}
    pinned: set[str] = set()
    for c in lumped.couplings.values():
        if c.stiffness == 0:
            continue
        (b0, b1), (r0, r1) = c.between, c.ratios
        ends = [(b, r) for b, r in ((b0, r0), (b1, r1)) if b != GROUND and r != 0]
        if len(ends) == 1:
            pinned.add(ends[0][0])
        else:
            edges[b0].append((b1, r0, r1))         # r0 q0 = r1 q1
            edges[b1].append((b0, r1, r0))
    motions, seen = [], set()
    for root in names:
        if root in seen:
            continue
        q = {root: 1.0}
        stack, ok = [root], True
        while stack:
            a = stack.pop()
            ok &= a not in pinned
            for b, ra, rb in edges[a]:
                value = ra * q[a] / rb
                if b in q:
                    ok &= abs(q[b] - value) <= 1e-12 * abs(value)
                else:
                    q[b] = value
                    stack.append(b)
        seen.update(q)
        if ok:
            column = np.zeros(len(names))
            for name, value in q.items():
                column[index[name]] = value
            motions.append(column)
    return np.array(motions).T.reshape(len(names), len(motions))


def _quadratic(terms: list[tuple[float, np.ndarray]], q: np.ndarray) -> tuple[float, float]:
    """Σ w·(g·q)² and Σ |w|·(|g|·|q|)² (the scale of its rounding)."""
    value = sum(w * float(g @ q) ** 2 for w, g in terms)
    scale = sum(abs(w) * float(np.abs(g) @ np.abs(q)) ** 2 for w, g in terms)
    return value, scale


@pytest.mark.parametrize(("kind", "type_name", "example"), MECHANICS)
def test_mechanics_lowering_builds_what_the_spec_says(kind, type_name, example):
    spec = registry.spec_class(kind, type_name).model_validate(example)
    lumped = spec.to_lumped()
    assert isinstance(lumped, LumpedSpec)
    mech = build_mechanics(spec)
    assert mech.dof_names == tuple(lumped.bodies)
    n = len(lumped.bodies)
    index = {name: i for i, name in enumerate(lumped.bodies)}

    def stretch(between, ratios) -> np.ndarray:
        g = np.zeros(n)
        for end, ratio, sign in zip(between, ratios, (1.0, -1.0)):
            if end != GROUND:
                g[index[end]] += sign * ratio
        return g

    springs = [(c.stiffness, stretch(c.between, c.ratios)) for c in lumped.couplings.values()]
    dampers = [(c.damping, stretch(c.between, c.ratios)) for c in lumped.couplings.values()] + \
              [(f.viscous, stretch(f.between, f.ratios)) for f in lumped.frictions.values()]
    masses = [(b.value, np.eye(n)[i]) for i, b in enumerate(lumped.bodies.values())]

    # static stiffness (and damping, mass): qᵀKq is the springs' energy Σ k (stretch)² for any q. Both
    # sides are sums of ≤ n² + 2·(links) products of ≤ 4 factors: |error| ≤ 8 (n² + links + 4) eps · scale
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = rng.standard_normal(n)
        for matrix, terms in ((mech.stiffness, springs), (mech.damping, dampers), (mech.mass, masses)):
            value, scale = _quadratic(terms, q)
            assert abs(float(q @ matrix @ q) - value) <= 8 * (n * n + len(terms) + 4) * EPS * scale

    # rigid-body count: the motions the graph oracle finds span K's null space. K r = 0 up to the rounding
    # of K's entries (≤ 4 eps ‖K‖ each, Weyl: singular values of a singular K stay below 4 n eps ‖K‖)
    rigid = _rigid_motions(lumped)
    sigma = np.linalg.svd(mech.stiffness, compute_uv=False)
    norm = sigma[0] if sigma.size and sigma[0] > 0 else 1.0
    tol = 4 * n * EPS * norm
    assert np.sum(sigma <= tol) == rigid.shape[1]
    assert np.all(sigma[sigma > tol] > 1e3 * tol)       # the example's count is not a near tie
    for r in rigid.T:
        assert np.linalg.norm(mech.stiffness @ r) <= tol * np.linalg.norm(r)


def test_rigid_motion_oracle_sees_ground_springs_and_locked_loops():
    # the oracle itself on hand cases: a free pair (1 rigid motion), the pair tied to the ground (0),
    # and the pair joined twice with inconsistent ratios (stretches a − b and 2a − b: locked, 0)
    free = LumpedSpec(bodies={"a": {"mass": 1}, "b": {"mass": 1}},
                      couplings={"k": {"between": ["a", "b"], "stiffness": 1}})
    tied = LumpedSpec(bodies={"a": {"mass": 1}, "b": {"mass": 1}},
                      couplings={"k": {"between": ["a", "b"], "stiffness": 1},
                                 "g": {"between": ["b", "ground"], "stiffness": 1}})
    locked = LumpedSpec(bodies={"a": {"mass": 1}, "b": {"mass": 1}},
                        couplings={"k": {"between": ["a", "b"], "stiffness": 1},
                                   "k2": {"between": ["a", "b"], "ratios": [2, 1], "stiffness": 1}})
    assert _rigid_motions(free).shape == (2, 1) and np.allclose(_rigid_motions(free)[:, 0], [1, 1])
    assert _rigid_motions(tied).shape == (2, 0)
    assert _rigid_motions(locked).shape == (2, 0)


def test_setpoint_lowering_serves_the_cli_options():
    # --step and --move are lowered by the same profile_from_spec as the model's trajectory
    from sicomat.description.motion import TrapezoidSetpoint
    from sicomat.tasks.simulate import choose_profile

    step, duration = choose_profile(None, 2.0, None, None, None)
    assert step.kind == "step" and step.positions == (2e-3,) and duration == 0.3
    model = TrapezoidSetpoint(type="trapezoid", distance=0.1, max_velocity=1.0, max_acceleration=5.0)
    move, _ = choose_profile(model, None, 10.0, None, None)
    expected = profile_from_spec(model.model_copy(update={"distance": 0.01}))
    assert move == expected
