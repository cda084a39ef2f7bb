"""Model reduction speed against python-control's slycot-based peers, same run, same chain.

The model: a 200-mass chain (400 states), masses 1–1.5 kg and springs 1–1.5 MN/m (seeded), 20 N·s/m
of material damping in each spring and 0.05 N·s/m of viscous guide friction per body, so every
mode is lightly damped (ζ from about 1e-3 to 1e-2). Two cases:

- ``grounded``: the first body also sits on a 1 MN/m spring to the frame (all poles stable);
  this is the case the ratios are computed on (python-control's ``balred`` needs a stable model).
- ``free``: no spring to the frame, so one rigid-body mode (a pole at 0): the peers are tried too
  and skipped with the reason if they fail.

Each method reduces to 20 states. Times are the best of a few runs (``time.perf_counter``) of the
reduction alone (our reductors compute their error figures lazily, afterwards; that time is shown
separately). The H∞ error of every reduced model, ours and the peers', is measured the same way,
on our pole-aware grid (log-spaced plus every pole's damped and natural frequency and half-power
points of both models); with slycot, one of them is cross-checked against the exact L∞ norm of
``ab13dd`` (``control.linfnorm``).

BLAS runs on one thread for ours and the peers alike (``OPENBLAS_NUM_THREADS`` and friends are set
to 1 before numpy loads unless already set; with ``threadpoolctl`` installed, ``run()`` also limits
them when imported late): on a small shared machine, multi-threaded BLAS made a 400×400 Schur form
vary from 0.2 s to 2 s between runs.

Run ``python benchmarks/bench_reduction.py``; ``run()`` returns the figures as a dict.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import contextlib  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from typing import Any, Callable  # noqa: E402

import numpy as np  # noqa: E402

from sicomat.mechanics.lumped import build_mechanics  # noqa: E402
from sicomat.description.shorthands import ChainSpec  # noqa: E402
from sicomat.lti.plant import Plant  # noqa: E402
from sicomat.reduction import (balanced_truncation, error_metrics, frequency_limited_truncation,  # noqa: E402
                               hankel_norm_approximation, modal_truncation, physical_reduction,
                               schur_truncation)

N_MASSES = 200
ORDER = 20
BAND_HZ = (0.0, 20.0)


def chain_spec(n: int = N_MASSES, grounded: bool = True, seed: int = 0) -> ChainSpec:
    """The benchmark chain (see the module docstring)."""
    rng = np.random.default_rng(seed)
    return ChainSpec(type="chain", masses=list(1.0 + 0.5 * rng.random(n)),
                     stiffnesses=list(1e6 * (1.0 + 0.5 * rng.random(n - 1))),
                     dampings=[20.0] * (n - 1), viscous=[0.05] * n,
                     ground_stiffness=1e6 if grounded else 0.0)


def _best(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _plant(sys, like: Plant) -> Plant:
    n = sys.nstates
    return Plant(sys.A, sys.B, sys.C, sys.D, tuple(f"x{i}" for i in range(n)), like.inputs, like.outputs)


def _peers(plant: Plant) -> tuple[dict[str, Callable[[], Plant]], str | None]:
    try:
        import control
        import slycot  # noqa: F401
    except ImportError as exc:
        return {}, f"python-control's balred needs slycot ({exc}); pip install slycot"
    sys = plant.to_control()

    def modal_modred() -> Plant:
        msys, _ = control.modal_form(sys)
        A = msys.A
        n = A.shape[0]
        mag = np.abs(np.diag(A)).astype(float)
        i = 0
        while i < n:  # |λ| of each 2×2 block of the modal form
            if i + 1 < n and (A[i, i + 1] != 0 or A[i + 1, i] != 0):
                mag[i] = mag[i + 1] = np.sqrt(abs(np.linalg.det(A[i:i + 2, i:i + 2])))
                i += 2
            else:
                i += 1
        elim = np.argsort(mag, kind="stable")[ORDER:]
        return _plant(control.modred(msys, np.sort(elim), method="matchdc"), plant)

    return {
        "balred": lambda: _plant(control.balred(sys, ORDER), plant),
        "balred-matchdc": lambda: _plant(control.balred(sys, ORDER, method="matchdc"), plant),
        "modal_form+modred": modal_modred,
    }, None


def _case(grounded: bool, repeat: int) -> dict[str, Any]:
    spec = chain_spec(grounded=grounded)
    plant = build_mechanics(spec).state_space()
    poles = np.linalg.eigvals(plant.A)
    osc = poles[np.abs(poles.imag) > 0]
    zeta = -osc.real / np.abs(osc)
    ours: dict[str, Callable[[], Any]] = {
        "modal": lambda: modal_truncation(plant, ORDER),
        "balanced": lambda: balanced_truncation(plant, ORDER),
        "balanced-dc": lambda: balanced_truncation(plant, ORDER, match_dc=True),
        "schur": lambda: schur_truncation(plant, ORDER),
        "frequency-limited": lambda: frequency_limited_truncation(plant, ORDER, BAND_HZ),
        "hankel": lambda: hankel_norm_approximation(plant, ORDER),
        "physical": lambda: physical_reduction(spec, order=ORDER),
    }
    rows: list[dict[str, Any]] = []
    for name, fn in ours.items():
        seconds, result = _best(fn, repeat)
        t0 = time.perf_counter()
        m = result.metrics
        rows.append({"method": name, "seconds": seconds, "metrics_seconds": time.perf_counter() - t0,
                     "order": result.order_after, "hinf_error": m.hinf_error,
                     "hinf_relative_error": m.hinf_relative_error, "error_bound": result.error_bound,
                     "dc_gain_relative_error": m.dc_gain_relative_error, "reduced": result.reduced})
    peers, skipped = _peers(plant)
    peer_rows: list[dict[str, Any]] = []
    for name, fn in peers.items():
        try:
            with warnings.catch_warnings():  # balred warns "System is unstable" on the rigid mode
                warnings.simplefilter("ignore")
                seconds, reduced = _best(fn, repeat)
        except Exception as exc:  # a peer failing on this model is a result, not a crash
            peer_rows.append({"method": name, "failed": f"{type(exc).__name__}: {str(exc).strip()[:120]}"})
            continue
        m = error_metrics(plant, reduced)
        peer_rows.append({"method": name, "seconds": seconds, "order": reduced.n_states,
                          "hinf_error": m.hinf_error, "hinf_relative_error": m.hinf_relative_error,
                          "dc_gain_relative_error": m.dc_gain_relative_error, "reduced": reduced})
    timed = {r["method"]: r["seconds"] for r in peer_rows if "seconds" in r}
    for row in rows:
        for peer in ("balred", "modal_form+modred"):
            row[f"ratio_to_{peer}"] = row["seconds"] / timed[peer] if peer in timed else None
    check = None
    if not skipped and grounded:  # the exact L∞ norm needs an error system without poles at 0
        import control

        bt = next(r for r in rows if r["method"] == "balanced")
        exact, _ = control.linfnorm(plant.to_control() - bt["reduced"].to_control())
        check = {"method": "balanced", "grid": bt["hinf_error"], "exact_ab13dd": float(exact),
                 "relative_difference": abs(bt["hinf_error"] - float(exact)) / float(exact)}
    for row in rows + peer_rows:
        row.pop("reduced", None)
    return {"case": "grounded" if grounded else "free (one rigid mode)", "states": plant.n_states,
            "damping_ratio_range": [float(zeta.min()), float(zeta.max())],
            "ours": rows, "peers": peer_rows, "peers_skipped": skipped, "hinf_check": check}


def _one_thread():
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def run(repeat: int = 3) -> dict[str, Any]:
    """Time every reductor and the peers on the 200-mass chain; return the figures."""
    with _one_thread():
        return {"order": ORDER, "band_hz": list(BAND_HZ), "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
                "cases": [_case(True, repeat), _case(False, repeat)]}


def _fmt(value: Any, spec: str = ".3g") -> str:
    width = "".join(ch for ch in spec.split(".")[0] if ch.isdigit())
    return ("—".rjust(int(width)) if width else "—") if value is None else format(value, spec)


def _print(report: dict[str, Any]) -> None:
    for case in report["cases"]:
        lo, hi = case["damping_ratio_range"]
        print(f"\n{N_MASSES}-mass chain, {case['case']}: {case['states']} states → {report['order']}, "
              f"ζ from {lo:.2g} to {hi:.2g}")
        print(f"{'method':20s} {'time (s)':>9s} {'/balred':>8s} {'/modal+modred':>14s} {'states':>6s} "
              f"{'H∞ error':>10s} {'rel. H∞':>8s} {'bound':>10s} {'rel. DC':>9s}")
        for r in case["ours"]:
            print(f"{r['method']:20s} {r['seconds']:9.3f} {_fmt(r['ratio_to_balred'], '8.2f')} "
                  f"{_fmt(r['ratio_to_modal_form+modred'], '14.2f')} {r['order']:6d} {r['hinf_error']:10.3e} "
                  f"{_fmt(r['hinf_relative_error'], '8.3g')} {_fmt(r['error_bound'], '10.3e')} "
                  f"{_fmt(r['dc_gain_relative_error'], '9.1e')}")
        if case["peers_skipped"]:
            print(f"peers skipped: {case['peers_skipped']}")
        for r in case["peers"]:
            if "failed" in r:
                print(f"{'[peer] ' + r['method']:20s} failed: {r['failed']}")
                continue
            wrong = r["hinf_relative_error"] is not None and r["hinf_relative_error"] > 1.0
            print(f"{'[peer] ' + r['method']:20s} {r['seconds']:9.3f} {'':8s} {'':14s} {r['order']:6d} "
                  f"{r['hinf_error']:10.3e} {_fmt(r['hinf_relative_error'], '8.3g')} {'':10s} "
                  f"{_fmt(r['dc_gain_relative_error'], '9.1e')}"
                  + ("  <- error larger than the model itself" if wrong else ""))
        chk = case["hinf_check"]
        if chk:
            print(f"H∞ grid check ({chk['method']}): grid {chk['grid']:.6e}, exact (ab13dd) "
                  f"{chk['exact_ab13dd']:.6e}, relative difference {chk['relative_difference']:.1e}")
    print("\nTimes: best of a few runs of the reduction alone; our error figures (computed lazily "
          "afterwards) took the 'metrics' time listed by run().")


if __name__ == "__main__":
    _print(run())
