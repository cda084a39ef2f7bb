"""Frequency responses and automatic tuning (issue 5), against python-control in the same run.

(a) **Frequency response** of a 400-state model: a free 200-mass chain (1 kg masses, 1 MN/m springs,
2 N·s/m of material damping in each spring, no spring to the frame: one rigid-body mode, a double
pole at 0; flexible modes from 1.57 to 2000 rad/s with ζ from about 1.6e-6 to 2e-3), from the force
on the first mass to the position of the last, on 10,000 log-spaced frequencies from 0.1 to 1e4
rad/s. Ours: ``sicomat.lti.response.transfer_at`` (the one evaluator: its diagonal strategy here,
400 > ``DIRECT_MAX_STATES``; building the form and evaluating it both timed). Peer:
``plant.to_control().frequency_response(omega)`` (python-control uses slycot's ``tb05ad`` when slycot
is installed and silently falls back to one dense solve per frequency otherwise; which one ran is
reported; the conversion ``to_control()`` is not timed). Accuracy: ``max|ours − peer| / max|peer|``, the
largest relative difference where ``|peer| > 1e-6 max|peer|`` (below, the true response of a 200-mass
chain falls like ω^-400 and both results are round-off), and both against a reference at 20 of
those frequencies: a direct complex solve of ``(jωI − A) x = B`` refined twice with residuals in
extended precision (``clongdouble``).

(a2) **Small and sampled cases** of the same evaluator (LU per point for the continuous system, the
diagonal form for the sampled one, ``discrete=True`` as the loops ask; the former diagonal form is timed
beside as ``former``, the evaluator before issue 11 used it for both): the 5M4S's servo
plant (mechanics + current loop, from the drive's current to the position sensor) at ``s = jω`` on
2,000 log-spaced frequencies up to the velocity loop's Nyquist frequency, and its exact ZOH at the
velocity period evaluated at ``z = e^{jωTv}``. Peer: python-control's ``frequency_response`` of the
continuous ``StateSpace`` and of the discrete one (``dt = Tv``); accuracy against the same refined
solve as (a).

(b) **Tuning** of the 5M4S (``examples/paper_5m4s.toml``) for a velocity crossover of 125.6 rad/s,
45° velocity phase margin, 80° position phase margin. Peer, the straightforward python-control
approach: the rigid model ``1/(m s)`` (``m = loop.m_rigid``), the lags as one delay
``sicomat.tuning.equivalent_delay(loop)`` as a 3rd-order Padé, a PI ``Kp (1 + 1/(Ti s))``, and
``control.stability_margins`` inside scipy's Nelder–Mead over (Kp, Ti) from the file's gains
minimising ``((PM − 45)/45)² + log(ωc/125.6)²``; then Kv by a 1-D Nelder–Mead for PM 80° on
``Kv · feedback(L_v, 1) / s · Padé₃(τ_p)`` (τ_p = half a position period + the position loop's
computation delay). Two parametrisations are timed: the literal one (Kp, Ti, Kv as they are, scipy's
default tolerances) and a log-parametrised one (fewer evaluations). Ours: the complete two-step
``tune_frequency`` (rigid closed form, then Nelder–Mead on the full digital, flexible model). Both
gain sets are then evaluated on the full digital model (``LoopAnalysis``) to show what each reaches
there.

Times are wall times, best of N interleaved runs (median and worst beside: the machine is shared);
BLAS runs on one thread (see ``benchmarks/_common.py``). Run ``python -m benchmarks.bench_frequency``
(``--quick`` for fewer repeats); ``run()`` returns the figures as a dict.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import EXAMPLE_5M4S, interleaved, speedup, table  # noqa: E402

import warnings  # noqa: E402
from typing import Any, Callable  # noqa: E402

import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402

import sicomat  # noqa: E402
from sicomat.lti.response import Evaluator, transfer_at, zoh_matrices  # noqa: E402
from sicomat.servo.loop import ServoLoop, build_servo_loop  # noqa: E402
from sicomat.frequency.loops import LoopAnalysis  # noqa: E402
from sicomat.frequency.margins import stability_margins  # noqa: E402
from sicomat.mechanics.lumped import build_mechanics  # noqa: E402
from sicomat.description.shorthands import ChainSpec  # noqa: E402
from sicomat.tuning.frequency import TuningTargets, equivalent_delay, tune_frequency  # noqa: E402

N_MASSES = 200
N_FREQ = 10_000
OMEGA_RANGE = (1e-1, 1e4)
N_REFERENCE = 20
SIGNIFICANT = 1e-6
TARGETS = TuningTargets(velocity_crossover=125.6, velocity_phase_margin=45.0, position_phase_margin=80.0)
GOALS = {"response_speedup_min": 10.0, "tuning_speedup_min": 5.0}


# ------------------------------------------------------------------------------------ (a) response
def chain_plant(n: int = N_MASSES):
    """The free chain, force on the first mass to the position of the last."""
    spec = ChainSpec(type="chain", masses=[1.0] * n, stiffnesses=[1e6] * (n - 1), dampings=[2.0] * (n - 1))
    return build_mechanics(spec).state_space().select(outputs=["last"])


def reference_response(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, omega: np.ndarray,
                       refinements: int = 2, points: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """``C (pI − A)⁻¹ B + D`` at ``p = jω`` (or at ``points``) by dense complex solves with iterative
    refinement (residuals in clongdouble).

    Returns the responses and the largest relative size of the last correction (convergence check).
    """
    n = A.shape[0]
    points = 1j * np.asarray(omega) if points is None else np.asarray(points)
    out = np.empty(points.size, complex)
    last = 0.0
    Bl = B.astype(np.clongdouble)
    for i, p in enumerate(points):
        M = p * np.eye(n) - A
        x = np.linalg.solve(M, B.astype(complex))
        Ml = M.astype(np.clongdouble)
        for _ in range(refinements):
            r = Bl - Ml @ x.astype(np.clongdouble)
            dx = np.linalg.solve(M, r.astype(complex))
            x = x + dx
        last = max(last, float(np.max(np.abs(dx)) / np.max(np.abs(x))))
        out[i] = (C @ x + D)[0, 0]
    return out, last


def _peer_path(sys_ct) -> str:
    try:
        sys_ct.slycot_laub(np.array([1j]))
        return "slycot tb05ad (Laub's Hessenberg method)"
    except ImportError:
        return "numpy solve per frequency (slycot not installed)"
    except Exception as exc:  # noqa: BLE001 - python-control falls back silently: say why
        return f"numpy solve per frequency (slycot failed: {type(exc).__name__})"


def bench_response(quick: bool) -> dict[str, Any]:
    plant = chain_plant()
    A, B, C, D = (np.array(m) for m in (plant.A, plant.B, plant.C, plant.D))
    omega = np.logspace(np.log10(OMEGA_RANGE[0]), np.log10(OMEGA_RANGE[1]), N_FREQ)
    sys_ct = plant.to_control()
    path = _peer_path(sys_ct)
    poles = np.linalg.eigvals(A)
    rigid = int(np.sum(np.abs(poles) < 1e-3))
    flex = poles[np.abs(poles) >= 1e-3]
    zeta = -flex.real / np.abs(flex)

    s = 1j * omega

    def ours() -> np.ndarray:
        return transfer_at(A, B, C, D, s)[0, 0]

    form = Evaluator(A, B, C, D)
    ours()
    timings = interleaved({
        "ours": ours,
        "ours_modal_form": lambda: Evaluator(A, B, C, D),
        "ours_response_only": lambda: form(s),
        "peer": lambda: np.asarray(sys_ct.frequency_response(omega).complex).reshape(-1),
    }, {"ours": 2 if quick else 5, "ours_modal_form": 2 if quick else 5, "ours_response_only": 2 if quick else 5,
        "peer": 1 if quick else 2})
    H, P = timings["ours"].value, timings["peer"].value
    scale = np.max(np.abs(P))
    sig = np.abs(P) > SIGNIFICANT * scale
    rel = np.abs(H - P)[sig] / np.abs(P)[sig]
    idx = np.flatnonzero(sig)[np.linspace(0, sig.sum() - 1, N_REFERENCE).round().astype(int)]
    R, converged = reference_response(A, B, C, D, omega[idx])
    err_ours = np.abs(H[idx] - R) / np.abs(R)
    err_peer = np.abs(P[idx] - R) / np.abs(R)
    return {
        "strategy": form.method,
        "model": {"masses": N_MASSES, "states": int(A.shape[0]), "mass_kg": 1.0, "stiffness_N_m": 1e6,
                  "damping_N_s_m": 2.0, "rigid_mode": rigid > 0, "poles_near_zero": rigid,
                  "flexible_rad_s": [float(np.abs(flex).min()), float(np.abs(flex).max())],
                  "zeta": [float(zeta.min()), float(zeta.max())], "input": plant.inputs[0], "output": plant.outputs[0]},
        "omega": {"n": N_FREQ, "range_rad_s": list(OMEGA_RANGE), "spacing": "log"},
        "peer_path": path,
        "times": {k: v.to_dict() for k, v in timings.items()},
        "speedup": speedup(timings["peer"], timings["ours"]),
        "accuracy": {
            "max_abs_diff_rel_to_max": float(np.max(np.abs(H - P)) / scale),
            "significant_fraction": float(sig.mean()),
            "max_rel_diff_significant": float(rel.max()), "median_rel_diff_significant": float(np.median(rel)),
            "reference": {"n": N_REFERENCE, "omega_rad_s": omega[idx],
                          "last_correction_rel": converged,
                          "ours_max_rel_err": float(err_ours.max()), "ours_median_rel_err": float(np.median(err_ours)),
                          "peer_max_rel_err": float(err_peer.max()), "peer_median_rel_err": float(np.median(err_peer)),
                          "ours_rel_err": err_ours, "peer_rel_err": err_peer},
        },
    }


N_SMALL_FREQ = 2_000


def bench_small(quick: bool) -> dict[str, Any]:
    """(a2): the direct strategy on a small plant, continuous and ZOH-sampled, against python-control."""
    import control

    from sicomat.servo.loop import servo_plant

    loop = build_servo_loop(sicomat.load_model(EXAMPLE_5M4S))
    ctrl = loop.controller
    plant = servo_plant(loop)
    A, B = np.asarray(plant.A), np.asarray(plant.B)[:, :1]
    C = np.asarray(plant.C)[[plant.outputs.index(f"sensor.{ctrl.position_sensor}")]]
    D = np.zeros((1, 1))
    T = ctrl.velocity_period
    omega = np.logspace(np.log10(2 * np.pi * 0.5), np.log10(0.999 * np.pi / T), N_SMALL_FREQ)
    Phi, Gamma = zoh_matrices(A, B, T)
    z = np.exp(1j * omega * T)
    cases = {"continuous": (A, B, 1j * omega, control.ss(A, B, C, D), False),
             "sampled": (Phi, Gamma, z, control.ss(Phi, Gamma, C, D, T), True)}
    out: dict[str, Any] = {"states": int(A.shape[0]), "n_omega": N_SMALL_FREQ, "period_s": T}
    for name, (Am, Bm, points, peer_sys, discrete) in cases.items():
        def ours(Am=Am, Bm=Bm, points=points, discrete=discrete) -> np.ndarray:
            return transfer_at(Am, Bm, C, D, points, discrete=discrete)[0, 0]

        def former(Am=Am, Bm=Bm, points=points) -> np.ndarray:
            return transfer_at(Am, Bm, C, D, points, method="diagonal")[0, 0]

        def peer(peer_sys=peer_sys) -> np.ndarray:
            return np.asarray(peer_sys.frequency_response(omega).complex).reshape(-1)

        ours()
        former()
        peer()
        timings = interleaved({"ours": ours, "former": former, "peer": peer}, 3 if quick else 15)
        H, P, F = timings["ours"].value, timings["peer"].value, timings["former"].value
        idx = np.linspace(0, omega.size - 1, N_REFERENCE).round().astype(int)
        R, _ = reference_response(Am, Bm, C, D, omega[idx], points=points[idx])
        out[name] = {"strategy": Evaluator(Am, Bm, C, D, discrete=discrete).method,
                     "times": {k: v.to_dict() for k, v in timings.items()},
                     "speedup": speedup(timings["peer"], timings["ours"]),
                     "vs_former": speedup(timings["former"], timings["ours"]),
                     "former_max_rel_err": float(np.max(np.abs(F[idx] - R) / np.abs(R))),
                     "ours_max_rel_err": float(np.max(np.abs(H[idx] - R) / np.abs(R))),
                     "peer_max_rel_err": float(np.max(np.abs(P[idx] - R) / np.abs(R)))}
    return out


# ------------------------------------------------------------------------------------ (b) tuning
class PythonControlTuner:
    """The straightforward python-control tuning on the rigid model (see the module docstring)."""

    def __init__(self, loop: ServoLoop, targets: TuningTargets = TARGETS, log: bool = False) -> None:
        import control

        self.control = control
        self.loop, self.targets, self.log = loop, targets, log
        ctrl = loop.controller
        self.plant = control.tf([1.0], [loop.m_rigid, 0.0])
        self.pade_v = control.tf(*control.pade(equivalent_delay(loop), 3))
        tau_p = ctrl.position_period / 2 + ctrl.position_delay * ctrl.position_period
        self.pade_p = control.tf(*control.pade(tau_p, 3))
        self.integrator = control.tf([1.0], [1.0, 0.0])
        self.evaluations = 0

    def velocity_loop(self, kp: float, ti: float):
        pi = self.control.tf([kp * ti, kp], [ti, 0.0])
        return pi * self.plant * self.pade_v

    def _margins(self, L) -> tuple[float, float]:
        _, pm, _, _, wgc, _ = self.control.stability_margins(L)
        return float(pm), float(wgc)

    def tune(self) -> dict[str, float]:
        t = self.targets
        self.evaluations = 0
        enc = np.log if self.log else np.asarray
        dec = np.exp if self.log else np.asarray

        def cost_velocity(x) -> float:
            self.evaluations += 1
            kp, ti = dec(x)
            if not (kp > 0 and ti > 0):
                return 1e6
            pm, wc = self._margins(self.velocity_loop(kp, ti))
            if not (np.isfinite(pm) and np.isfinite(wc) and wc > 0):
                return 1e6
            return ((pm - t.velocity_phase_margin) / t.velocity_phase_margin) ** 2 + np.log(wc / t.velocity_crossover) ** 2

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            xv = scipy.optimize.minimize(cost_velocity, enc(np.array([self.loop.Kp, self.loop.Ti])),
                                         method="Nelder-Mead").x
            kp, ti = (float(v) for v in dec(xv))
            n_velocity = self.evaluations
            closed = self.control.feedback(self.velocity_loop(kp, ti), 1)
            base = closed * self.integrator * self.pade_p

            def cost_position(x) -> float:
                self.evaluations += 1
                kv = float(dec(x)[0])
                if not kv > 0:
                    return 1e6
                pm, _ = self._margins(kv * base)
                if not np.isfinite(pm):
                    return 1e6
                return ((pm - t.position_phase_margin) / t.position_phase_margin) ** 2

            xp = scipy.optimize.minimize(cost_position, enc(np.array([self.loop.Kv])), method="Nelder-Mead").x
            kv = float(dec(xp)[0])
            pm_v, wc_v = self._margins(self.velocity_loop(kp, ti))
            pm_p, wc_p = self._margins(kv * base)
        return {"Kp": kp, "Kp_normalized": kp / self.loop.m_rigid, "Ti": ti, "Kv": kv,
                "evaluations": self.evaluations, "velocity_evaluations": n_velocity,
                "rigid_velocity_phase_margin_deg": pm_v, "rigid_velocity_crossover_rad_s": wc_v,
                "rigid_position_phase_margin_deg": pm_p, "rigid_position_crossover_rad_s": wc_p}


def on_full_model(loop: ServoLoop, kp: float, ti: float, kv: float) -> dict[str, float]:
    """What gains reach on the complete digital model: the main (lowest) crossover of each loop."""
    an = LoopAnalysis.of(loop)
    mv = stability_margins(an.response("velocity-open", Kp=kp, Ti=ti))
    mp = stability_margins(an.response("position-open", Kp=kp, Ti=ti, Kv=kv))

    def first(m) -> tuple[float, float]:
        if len(m.gain_crossovers) == 0:
            return float("nan"), float("nan")
        return float(m.phase_margins_deg[0]), float(m.gain_crossovers[0])

    pv, wv = first(mv)
    pp, wp = first(mp)
    return {"velocity_phase_margin_deg": pv, "velocity_crossover_rad_s": wv,
            "velocity_gain_margin_db": float(mv.gain_margin_db), "position_phase_margin_deg": pp,
            "position_crossover_rad_s": wp, "position_gain_margin_db": float(mp.gain_margin_db)}


def bench_tuning(quick: bool) -> dict[str, Any]:
    loop = build_servo_loop(sicomat.load_model(EXAMPLE_5M4S))
    peers = {"literal": PythonControlTuner(loop), "log": PythonControlTuner(loop, log=True)}
    tune_frequency(loop, TARGETS)                   # warm-up (imports, caches)
    for p in peers.values():
        p.tune()
    # "ours" is the whole verb (with the 5M4S's 45° worst phase margin unmet, it also designs a notch and
    # re-tunes with it); "ours_tuning_only" does the work the peers do, the tuning without the notch step
    fns: dict[str, Callable[[], Any]] = {"ours": lambda: tune_frequency(loop, TARGETS),
                                         "ours_tuning_only": lambda: tune_frequency(loop, TARGETS, suggest_notch=False)}
    fns.update({f"peer_{k}": p.tune for k, p in peers.items()})
    timings = interleaved(fns, {"ours": 2 if quick else 5, "ours_tuning_only": 2 if quick else 5,
                                "peer_literal": 1 if quick else 3, "peer_log": 1 if quick else 3})
    res = timings["ours"].value
    ours = {"Kp": res.tuned.Kp, "Kp_normalized": res.tuned.Kp_normalized, "Ti": res.tuned.Ti, "Kv": res.tuned.Kv,
            "evaluations": res.evaluations, "internal_wall_time_s": res.wall_time_s,
            "targets_met": res.targets_met, "unmet": list(res.unmet), "notch_suggested": res.notch is not None,
            "achieved": {"velocity_phase_margin_deg": res.achieved.velocity_phase_margin_deg,
                         "velocity_crossover_rad_s": res.achieved.velocity_crossover_rad_s,
                         "position_phase_margin_deg": res.achieved.position_phase_margin_deg,
                         "gain_margin_db": res.achieved.gain_margin_db}}
    full = {"ours": on_full_model(loop, res.tuned.Kp, res.tuned.Ti, res.tuned.Kv)}
    full["ours_tuning_only"] = full["ours"]         # the same tuned gains: the notch step only adds a variant
    out_peers = {}
    for key in peers:
        g = timings[f"peer_{key}"].value
        out_peers[key] = g
        full[f"peer_{key}"] = on_full_model(loop, g["Kp"], g["Ti"], g["Kv"])
    return {
        "targets": {"velocity_crossover_rad_s": TARGETS.velocity_crossover,
                    "velocity_phase_margin_deg": TARGETS.velocity_phase_margin,
                    "position_phase_margin_deg": TARGETS.position_phase_margin},
        "equivalent_delay_s": equivalent_delay(loop), "m_rigid": loop.m_rigid,
        "times": {k: v.to_dict() for k, v in timings.items()},
        "speedup": {k: speedup(timings[f"peer_{k}"], timings["ours"]) for k in peers},
        "speedup_tuning_only": {k: speedup(timings[f"peer_{k}"], timings["ours_tuning_only"]) for k in peers},
        "ours": ours, "peers": out_peers, "on_full_model": full,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Both benchmarks of issue 5; returns the figures."""
    response = bench_response(quick)
    small = bench_small(quick)
    tuning = bench_tuning(quick)
    return {"response": response, "small": small, "tuning": tuning, "goals": GOALS,
            "goals_met": {"response_10x": response["speedup"]["best"] >= GOALS["response_speedup_min"],
                          "tuning_5x_literal": tuning["speedup"]["literal"]["best"] >= GOALS["tuning_speedup_min"],
                          "tuning_5x_log": tuning["speedup"]["log"]["best"] >= GOALS["tuning_speedup_min"],
                          "tuning_only_5x_literal": tuning["speedup_tuning_only"]["literal"]["best"]
                          >= GOALS["tuning_speedup_min"],
                          "tuning_only_5x_log": tuning["speedup_tuning_only"]["log"]["best"]
                          >= GOALS["tuning_speedup_min"]}}


def report(r: dict[str, Any]) -> str:
    """The tables of ``run()``'s figures."""
    a, t = r["response"], r["tuning"]
    m, acc, ref = a["model"], a["accuracy"], a["accuracy"]["reference"]
    lines = [f"Frequency response (issue 5a): free {m['masses']}-mass chain, {m['states']} states "
             f"({'one rigid-body mode, ' if m['rigid_mode'] else 'no rigid mode, '}modes "
             f"{m['flexible_rad_s'][0]:.3g}..{m['flexible_rad_s'][1]:.4g} rad/s, ζ {m['zeta'][0]:.2g}..{m['zeta'][1]:.2g}), "
             f"{m['input']} -> {m['output']}, {a['omega']['n']} log-spaced frequencies "
             f"{a['omega']['range_rad_s'][0]:g}..{a['omega']['range_rad_s'][1]:g} rad/s"]
    T = a["times"]
    peer_best = T["peer"]["best_s"]
    rows = []
    for key, label in (("ours", f"transfer_at ({a.get('strategy', '?')} strategy)"),
                       ("ours_modal_form", "  of which building the Evaluator"),
                       ("ours_response_only", "  of which evaluating it"),
                       ("peer", f"[peer] python-control frequency_response ({a['peer_path']})")):
        x = T[key]
        rows.append([label, 1e3 * x["best_s"], 1e3 * x["median_s"], 1e3 * x["worst_s"], x["n"],
                     peer_best / x["best_s"] if key != "ours_modal_form" and key != "ours_response_only" else None])
    lines.append(table(["", "best ms", "median ms", "worst ms", "runs", "x faster than peer"], rows))
    lines.append(f"ratio: ours {a['speedup']['best']:.1f}x faster (medians: {a['speedup']['median']:.1f}x; "
                 f"goal >= 10x: {'met' if r['goals_met']['response_10x'] else 'NOT met'})")
    lines.append(table(["accuracy", "value"], [
        ["max|ours - peer| / max|peer|", acc["max_abs_diff_rel_to_max"]],
        [f"max relative difference where |peer| > 1e-6 max ({100 * acc['significant_fraction']:.0f} % of points)",
         acc["max_rel_diff_significant"]],
        ["median relative difference there", acc["median_rel_diff_significant"]],
        [f"ours vs refined solve at {ref['n']} frequencies: max (median) rel. error",
         f"{ref['ours_max_rel_err']:.2e} ({ref['ours_median_rel_err']:.2e})"],
        [f"peer vs refined solve at {ref['n']} frequencies: max (median) rel. error",
         f"{ref['peer_max_rel_err']:.2e} ({ref['peer_median_rel_err']:.2e})"],
        ["reference: last refinement correction (relative)", ref["last_correction_rel"]],
    ]))
    better = "ours" if ref["ours_max_rel_err"] < ref["peer_max_rel_err"] else "the peer"
    lines.append(f"more accurate against the reference (max error): {better}")
    sm = r.get("small")
    if sm:
        lines.append("")
        lines.append(f"Small and sampled cases: 5M4S servo plant, {sm['states']} states, {sm['n_omega']} frequencies "
                     f"up to Nyquist (Tv = {1e6 * sm['period_s']:g} µs)")
        rows = []
        for name in ("continuous", "sampled"):
            c = sm[name]
            rows.append([f"{name} ({c['strategy']})", 1e3 * c["times"]["ours"]["best_s"],
                         1e3 * c["times"]["ours"]["median_s"], 1e3 * c["times"]["former"]["best_s"],
                         1e3 * c["times"]["peer"]["best_s"],
                         1e3 * c["times"]["peer"]["median_s"], c["speedup"]["best"], c["speedup"]["median"],
                         c["vs_former"]["best"], c["ours_max_rel_err"], c["former_max_rel_err"],
                         c["peer_max_rel_err"]])
        lines.append(table(["case", "ours best ms", "ours median ms", "former diag. best ms", "peer best ms",
                            "peer median ms", "x faster (best)", "x faster (median)", "x vs former (best)",
                            "ours max rel err", "former max rel err", "peer max rel err"], rows))

    lines.append("")
    tg = t["targets"]
    lines.append(f"Tuning (issue 5b): 5M4S, targets ωc {tg['velocity_crossover_rad_s']:g} rad/s, PM_v "
                 f"{tg['velocity_phase_margin_deg']:g}°, PM_p {tg['position_phase_margin_deg']:g}°; "
                 f"m_rigid {t['m_rigid']:.1f} kg, equivalent delay {1e6 * t['equivalent_delay_s']:.0f} µs")
    T = t["times"]
    full = t["on_full_model"]
    rows = []
    o = t["ours"]
    for key, label, g, evals in (
            ("ours", "tune_frequency (two steps, full digital model, notch step)", o, o["evaluations"]),
            ("ours_tuning_only", "tune_frequency(suggest_notch=False): the peers' work", o, None),
            ("peer_literal", "[peer] python-control, rigid+Padé3, Nelder-Mead on (Kp, Ti), Kv",
             t["peers"]["literal"], t["peers"]["literal"]["evaluations"]),
            ("peer_log", "[peer] same, Nelder-Mead on log(Kp, Ti), log Kv", t["peers"]["log"],
             t["peers"]["log"]["evaluations"])):
        x = T[key]
        f = full[key]
        rows.append([label, 1e3 * x["best_s"], 1e3 * x["median_s"], 1e3 * x["worst_s"], evals,
                     1e3 * x["best_s"] / evals if evals else None,
                     T["peer_literal"]["best_s"] / x["best_s"], T["peer_log"]["best_s"] / x["best_s"],
                     g["Kp_normalized"], 1e3 * g["Ti"], g["Kv"], f["velocity_phase_margin_deg"],
                     f["velocity_crossover_rad_s"], f["position_phase_margin_deg"]])
    lines.append(table(["", "best ms", "median ms", "worst ms", "evals", "ms/eval", "x vs literal", "x vs log",
                        "Kp/m 1/s", "Ti ms", "Kv 1/s", "PM_v° full", "ωc full", "PM_p° full"], rows))
    lines.append(f"ratios: ours {t['speedup']['literal']['best']:.1f}x faster than the literal peer (medians "
                 f"{t['speedup']['literal']['median']:.1f}x), {t['speedup']['log']['best']:.1f}x than the log-parametrised "
                 f"one (medians {t['speedup']['log']['median']:.1f}x); goal >= 5x: literal "
                 f"{'met' if r['goals_met']['tuning_5x_literal'] else 'NOT met'}, log "
                 f"{'met' if r['goals_met']['tuning_5x_log'] else 'NOT met'}")
    so = t["speedup_tuning_only"]
    lines.append(f"tuning only (no notch step, the peers' work): {so['literal']['best']:.1f}x faster than the literal "
                 f"peer (medians {so['literal']['median']:.1f}x), {so['log']['best']:.1f}x than the log-parametrised one "
                 f"(medians {so['log']['median']:.1f}x); goal >= 5x: literal "
                 f"{'met' if r['goals_met']['tuning_only_5x_literal'] else 'NOT met'}, log "
                 f"{'met' if r['goals_met']['tuning_only_5x_log'] else 'NOT met'}")
    pl = t["peers"]["literal"]
    tgv, tgw, tgp = tg["velocity_phase_margin_deg"], tg["velocity_crossover_rad_s"], tg["position_phase_margin_deg"]

    def off(f: dict[str, float]) -> str:
        return (f"PM_v {f['velocity_phase_margin_deg'] - tgv:+.2f}°, ωc {100 * (f['velocity_crossover_rad_s'] / tgw - 1):+.2f} %, "
                f"PM_p {f['position_phase_margin_deg'] - tgp:+.2f}°")

    lines.append("accuracy ('full' columns: margins of each gain set on the complete digital model, LoopAnalysis, "
                 "lowest crossover of each loop):")
    lines.append(f"  ours off target by {off(full['ours'])} (its own verdict: "
                 f"{'targets met' if o['targets_met'] else 'unmet: ' + '; '.join(o['unmet'])})")
    lines.append(f"  peer (literal) off target by {off(full['peer_literal'])} on the full model; on its own rigid "
                 f"model it reached PM_v {pl['rigid_velocity_phase_margin_deg']:.2f}°, ωc "
                 f"{pl['rigid_velocity_crossover_rad_s']:.2f} rad/s, PM_p {pl['rigid_position_phase_margin_deg']:.2f}°")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Run this benchmark alone."""
    from benchmarks._common import module_main

    module_main(__doc__, run, report, argv=argv)


if __name__ == "__main__":
    main()
