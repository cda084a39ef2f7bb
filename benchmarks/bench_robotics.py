"""Robotics dynamics (issue 13): inverse dynamics and the inertia matrix of a six-axis robot, against Pinocchio.

Robot: the Stäubli RX-90 of the working notes (MDH ``alpha = 0, pi/2, 0, -pi/2, pi/2, -pi/2``,
``d3 = r4 = 0.45`` m), six revolute joints, each link a physical rigid body (mass, first moments and
a full inertia tensor about the frame origin, fixed seed) with rotor inertia ``IA``. No friction
(``FV = FS = 0``): Pinocchio has none, so both sides compute the same torques (Pinocchio's
``armature`` carries ``IA``). The Pinocchio model is built from the same MDH table (joint placements
from the constant parts of the transforms, ``JointModelRZ``), as the tests do.

(a) **One call**: ``sicomat.robotics.inverse_dynamics`` against ``pinocchio.rnea`` and
``inertia_matrix`` against ``pinocchio.crba``, both called from Python on numpy vectors (the
binding's cost is part of Pinocchio's call as it is of ours). One timed sample is ``CALLS`` calls at
the same state, the per-call time its mean; samples of ours and Pinocchio's are interleaved.

(b) **Batch of 10,000 states**: ``inverse_dynamics_batch`` / ``inertia_matrix_batch`` (one call, the
loop over states compiled) against Pinocchio called once per state from a Python loop (the per-state
time the issue's target names), and, for the inverse dynamics, against ``pinocchio.rneaInParallel``
with one thread (Pinocchio's own C++ loop over the batch, no Python in it: the strict peer).
Pinocchio's ``crba`` fills the upper triangle only; it is timed without the symmetrisation.

Ratios are ours / Pinocchio's time (<= 5 for one call and <= 1 per state in the batch are the
issue's targets), from the best-of and from the medians of interleaved samples. The accuracy columns
are the largest differences from Pinocchio over the batch states. Run ``python -m
benchmarks.bench_robotics`` (``--quick`` for fewer repeats); ``run()`` returns the figures as a dict.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import Timing, fmt_s, interleaved, table  # noqa: E402

import math  # noqa: E402
from typing import Any, Callable  # noqa: E402

import numpy as np  # noqa: E402

from sicomat.robotics import (MDHRobot, inertia_matrix, inertia_matrix_batch, inverse_dynamics,  # noqa: E402
                              inverse_dynamics_batch)

N_STATES = 10_000
CALLS = 2_000
GOALS = {"one_call_ratio_max": 5.0, "batch_ratio_max": 1.0}
RX90 = [(0.0, 0.0, 0.0), (math.pi / 2, 0.0, 0.0), (0.0, 0.45, 0.0), (-math.pi / 2, 0.0, 0.45),
        (math.pi / 2, 0.0, 0.0), (-math.pi / 2, 0.0, 0.0)]
"""(alpha, d, r) of each frame."""


def rx90_table(seed: int = 13) -> list[dict[str, float]]:
    """The RX-90 frames with physical random links (inertia about the centre of mass plus the offset)."""
    rng = np.random.default_rng(seed)
    rows = []
    for j, (alpha, d, r) in enumerate(RX90):
        m = rng.uniform(1.0, 10.0)
        c = rng.uniform(-0.1, 0.1, 3)
        a = rng.uniform(-1, 1, (3, 3))
        jg = a @ a.T * 0.05 + 0.01 * np.eye(3)
        jo = jg + m * (c @ c * np.eye(3) - np.outer(c, c))
        rows.append({"ant": j, "sigma": 0, "mu": 1, "alpha": alpha, "d": d, "r": r, "M": m,
                     "MX": m * c[0], "MY": m * c[1], "MZ": m * c[2], "XX": jo[0, 0], "XY": jo[0, 1],
                     "XZ": jo[0, 2], "YY": jo[1, 1], "YZ": jo[1, 2], "ZZ": jo[2, 2],
                     "IA": rng.uniform(0.1, 1.0)})
    return rows


def pinocchio_model(frames: list[dict[str, float]], gravity=(0.0, 0.0, -9.81)):
    """Pinocchio's model of a serial revolute MDH table (armature = IA)."""
    import pinocchio as pin

    def rz(t: float) -> np.ndarray:
        return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1.0]])

    def rx(t: float) -> np.ndarray:
        return np.array([[1.0, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])

    model = pin.Model()
    model.gravity.linear = np.array(gravity, dtype=float)
    parent = 0
    for row in frames:
        assert row["sigma"] == 0 and row["ant"] == parent
        g = lambda key: row.get(key, 0.0)  # noqa: E731
        c = rz(g("gamma")) @ rx(g("alpha"))
        rot = c @ rz(g("theta"))
        pos = np.array([0, 0, g("b")]) + c @ np.array([g("d"), 0, 0]) + rot[:, 2] * g("r")
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3(rot, pos), f"joint{parent + 1}")
        params = np.array([g("M"), g("MX"), g("MY"), g("MZ"), g("XX"), g("XY"), g("YY"), g("XZ"), g("YZ"), g("ZZ")])
        model.appendBodyToJoint(parent, pin.Inertia.FromDynamicParameters(params), pin.SE3.Identity())
    model.armature = np.array([row.get("IA", 0.0) for row in frames])
    return model


def _per_call(fn: Callable[[], Any], calls: int) -> Callable[[], Any]:
    def many() -> Any:
        out = None
        for _ in range(calls):
            out = fn()
        return out
    return many


def _ratios(ours: Timing, peer: Timing, ours_scale: float = 1.0, peer_scale: float = 1.0) -> dict[str, float]:
    """ours / peer (times scaled per call or per state): < 1 means ours is faster."""
    return {"best": (ours.best * ours_scale) / (peer.best * peer_scale),
            "median": (ours.median * ours_scale) / (peer.median * peer_scale)}


def run(quick: bool = False) -> dict[str, Any]:
    import pinocchio as pin

    frames = rx90_table()
    robot = MDHRobot.from_table(frames)
    model = pinocchio_model(frames)
    data = model.createData()
    rng = np.random.default_rng(1)
    q, qd, qdd = (rng.uniform(-math.pi, math.pi, (N_STATES, 6)) for _ in range(3))
    q0, qd0, qdd0 = q[0].copy(), qd[0].copy(), qdd[0].copy()
    calls = 200 if quick else CALLS
    rounds = 5 if quick else 30

    # warm-up (numba's compile or cache load) before any timing
    inverse_dynamics(robot, q0, qd0, qdd0)
    inertia_matrix(robot, q0)
    inverse_dynamics_batch(robot, q[:2], qd[:2], qdd[:2])
    inertia_matrix_batch(robot, q[:2])

    one = interleaved({
        "ours_rnea": _per_call(lambda: inverse_dynamics(robot, q0, qd0, qdd0), calls),
        "pin_rnea": _per_call(lambda: pin.rnea(model, data, q0, qd0, qdd0), calls),
        "ours_crba": _per_call(lambda: inertia_matrix(robot, q0), calls),
        "pin_crba": _per_call(lambda: pin.crba(model, data, q0), calls),
    }, rounds)

    pool = pin.ModelPool(model, 1)
    qt, qdt, qddt = (np.asfortranarray(x.T) for x in (q, qd, qdd))
    tau_par = np.zeros((6, N_STATES), order="F")

    def pin_rnea_loop() -> np.ndarray:
        return np.array([pin.rnea(model, data, q[i], qd[i], qdd[i]) for i in range(N_STATES)])

    def pin_crba_loop() -> list[np.ndarray]:
        return [pin.crba(model, data, q[i]).copy() for i in range(N_STATES)]

    def pin_rnea_parallel() -> np.ndarray:
        pin.rneaInParallel(1, pool, qt, qdt, qddt, tau_par)
        return tau_par.T.copy()

    batch_rounds = 2 if quick else 7
    batch = interleaved({
        "ours_rnea": lambda: inverse_dynamics_batch(robot, q, qd, qdd),
        "pin_rnea_loop": pin_rnea_loop,
        "pin_rnea_in_parallel_1_thread": pin_rnea_parallel,
        "ours_crba": lambda: inertia_matrix_batch(robot, q),
        "pin_crba_loop": pin_crba_loop,
    }, batch_rounds)

    tau = batch["ours_rnea"].value
    scale_tau = float(np.max(np.abs(batch["pin_rnea_loop"].value)))
    a_ours = batch["ours_crba"].value
    a_pin = np.array([np.triu(m) + np.triu(m, 1).T for m in batch["pin_crba_loop"].value])
    per_call = 1.0 / calls
    per_state = 1.0 / N_STATES
    ratios = {
        "one_call_rnea": _ratios(one["ours_rnea"], one["pin_rnea"]),
        "one_call_crba": _ratios(one["ours_crba"], one["pin_crba"]),
        "batch_rnea_vs_pin_loop": _ratios(batch["ours_rnea"], batch["pin_rnea_loop"]),
        "batch_rnea_vs_pin_in_parallel_1_thread": _ratios(batch["ours_rnea"], batch["pin_rnea_in_parallel_1_thread"]),
        "batch_crba_vs_pin_loop": _ratios(batch["ours_crba"], batch["pin_crba_loop"]),
    }
    goals = {
        "one_call_rnea_within_5x": ratios["one_call_rnea"]["best"] <= GOALS["one_call_ratio_max"],
        "one_call_crba_within_5x": ratios["one_call_crba"]["best"] <= GOALS["one_call_ratio_max"],
        "batch_rnea_at_or_below_pin_per_state": ratios["batch_rnea_vs_pin_loop"]["best"] <= GOALS["batch_ratio_max"],
        "batch_crba_at_or_below_pin_per_state": ratios["batch_crba_vs_pin_loop"]["best"] <= GOALS["batch_ratio_max"],
        "batch_rnea_at_or_below_pin_cpp_loop": (
            ratios["batch_rnea_vs_pin_in_parallel_1_thread"]["best"] <= GOALS["batch_ratio_max"]),
    }
    return {
        "robot": {"name": "RX-90 (MDH, working notes)", "joints": 6, "frames": frames, "friction": False},
        "pinocchio": pin.__version__,
        "one_call": {"calls_per_sample": calls, "rounds": rounds,
                     "per_call_s": {k: {"best": v.best * per_call, "median": v.median * per_call} for k, v in one.items()},
                     "samples": {k: v.to_dict() for k, v in one.items()}},
        "batch": {"states": N_STATES, "rounds": batch_rounds,
                  "per_state_s": {k: {"best": v.best * per_state, "median": v.median * per_state}
                                  for k, v in batch.items()},
                  "samples": {k: {kk: vv for kk, vv in v.to_dict().items()} for k, v in batch.items()}},
        "ratios_ours_over_pinocchio": ratios,
        "goals": GOALS,
        "goals_met": goals,
        "accuracy": {
            "rnea_max_abs_diff": float(np.max(np.abs(tau - batch["pin_rnea_loop"].value))),
            "rnea_in_parallel_max_abs_diff": float(np.max(np.abs(tau - batch["pin_rnea_in_parallel_1_thread"].value))),
            "rnea_scale": scale_tau,
            "crba_max_abs_diff": float(np.max(np.abs(a_ours - a_pin))),
            "crba_scale": float(np.max(np.abs(a_pin))),
        },
    }


def report(r: dict[str, Any]) -> str:
    """The tables of ``run()``'s figures."""
    o, b, q = r["one_call"]["per_call_s"], r["batch"]["per_state_s"], r["ratios_ours_over_pinocchio"]
    rows = [
        ["one call: inverse_dynamics vs pin.rnea", fmt_s(o["ours_rnea"]["best"]), fmt_s(o["pin_rnea"]["best"]),
         q["one_call_rnea"]["best"], q["one_call_rnea"]["median"], "<= 5"],
        ["one call: inertia_matrix vs pin.crba", fmt_s(o["ours_crba"]["best"]), fmt_s(o["pin_crba"]["best"]),
         q["one_call_crba"]["best"], q["one_call_crba"]["median"], "<= 5"],
        [f"batch {r['batch']['states']}: inverse_dynamics_batch vs pin.rnea loop (per state)",
         fmt_s(b["ours_rnea"]["best"]), fmt_s(b["pin_rnea_loop"]["best"]),
         q["batch_rnea_vs_pin_loop"]["best"], q["batch_rnea_vs_pin_loop"]["median"], "<= 1"],
        [f"batch {r['batch']['states']}: inverse_dynamics_batch vs pin.rneaInParallel(1 thread)",
         fmt_s(b["ours_rnea"]["best"]), fmt_s(b["pin_rnea_in_parallel_1_thread"]["best"]),
         q["batch_rnea_vs_pin_in_parallel_1_thread"]["best"], q["batch_rnea_vs_pin_in_parallel_1_thread"]["median"],
         "(C++ loop)"],
        [f"batch {r['batch']['states']}: inertia_matrix_batch vs pin.crba loop (per state)",
         fmt_s(b["ours_crba"]["best"]), fmt_s(b["pin_crba_loop"]["best"]),
         q["batch_crba_vs_pin_loop"]["best"], q["batch_crba_vs_pin_loop"]["median"], "<= 1"],
    ]
    acc = r["accuracy"]
    return (table(["case (RX-90, 6 revolute joints)", "ours", "Pinocchio", "ours/pin best", "ours/pin median",
                   "target"], rows,
                  title=f"Robotics dynamics vs Pinocchio {r['pinocchio']} (< 1: ours faster)")
            + f"\naccuracy over the batch: torques {acc['rnea_max_abs_diff']:.2e} (scale {acc['rnea_scale']:.3g}), "
              f"inertia matrix {acc['crba_max_abs_diff']:.2e} (scale {acc['crba_scale']:.3g})"
            + "\ngoals met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in r["goals_met"].items()))


def main(argv: list[str] | None = None) -> None:
    """Run this benchmark alone."""
    from benchmarks._common import module_main

    module_main(__doc__, run, report, argv=argv)


if __name__ == "__main__":
    main()
