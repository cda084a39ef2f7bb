"""Run every benchmark, print one table per benchmark and write ``benchmarks/results.json``.

    python -m benchmarks.run            # full run (a few minutes)
    python -m benchmarks.run --quick    # smoke run: fewer repeats, the ODE peer on the first 0.1 s

Benchmarks: ``bench_simulation`` (issue 3: closed-loop simulation vs python-control's
``input_output_response``, the bare compiled loop, a 1000-variant batch), ``bench_frequency`` (issue 5:
frequency responses vs ``frequency_response``, tuning vs a python-control Nelder–Mead tuner),
``bench_reduction`` (model reduction vs python-control's slycot reductions), ``bench_robotics``
(issue 13: inverse dynamics and the inertia matrix of a six-axis robot vs Pinocchio, one call and a
10,000-state batch; its ratios are ours / Pinocchio's time) and ``bench_studies`` (issue 14: a
10,000-variant study of the 5M4S on 1 and 2 local Dask workers vs the same work in a plain loop over the
public API; parallel efficiency and Dask's overhead per variant; ``--quick``: 400 variants). Ours and the peers run
side by side in the same process; figures are wall times and ratios (how many times faster ours is).
BLAS runs on one thread unless the caller set ``OPENBLAS_NUM_THREADS`` (or OMP/MKL) already.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks import _common  # noqa: E402  (first: sets the BLAS thread count before numpy loads)

import argparse  # noqa: E402
import os  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from typing import Any, Callable  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results.json"
NAMES = ("simulation", "frequency", "reduction", "robotics", "studies")


def _reduction(quick: bool) -> dict[str, Any]:
    from benchmarks import bench_reduction

    return bench_reduction.run(repeat=1 if quick else 3)


def _reduction_report(r: dict[str, Any]) -> str:
    import contextlib
    import io

    from benchmarks import bench_reduction

    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            bench_reduction._print(r)        # its own table (ratios there are ours / peer time)
        own = buf.getvalue().strip()
    except Exception as exc:  # noqa: BLE001 - another engineer's module: never lose the run for its printer
        own = f"(bench_reduction's table could not be printed: {type(exc).__name__}: {exc})"
    rows = []
    for case in r.get("cases", []):
        peers = {p["method"]: p for p in case.get("peers", []) if "seconds" in p}
        for row in case.get("ours", []):
            rows.append([case["case"], row["method"], 1e3 * row["seconds"],
                         *(peers[k]["seconds"] / row["seconds"] if k in peers else None
                           for k in ("balred", "modal_form+modred")),
                         row.get("hinf_relative_error"),
                         peers["balred"]["hinf_relative_error"] if "balred" in peers else None])
    speed = _common.table(["case", "method", "ours ms", "x faster than balred", "x faster than modal+modred",
                           "rel. H∞ err", "balred rel. H∞ err"], rows,
                          title="Reduction speedups (peer time / our time; > 1: ours faster)")
    return f"Model reduction (bench_reduction.py, 200-mass chain, 400 -> {r.get('order')} states)\n{own}\n\n{speed}"


def _summary(results: dict[str, Any]) -> str:
    rows = []
    sim = results.get("simulation", {}).get("result")
    if sim:
        q, t = sim["ratios"], sim["targets_met"]
        pw = sim["peer"]
        rows.append([f"simulation: kernel.run vs python-control ({pw['simulated_s']:g} s of 5M4S)",
                     f"{1e3 * pw['ours_same_window']['run']['best_s']:.2f} ms", f"{pw['wall_s']:.2f} s",
                     f"{q['speedup_vs_python_control']['best']:.0f}x faster", ">= 1000x",
                     t["speedup_vs_python_control"]])
        rows.append([f"simulation: kernel.run vs bare compiled loop ({sim['bare']['states']} states)", f"{1e3 * sim['ours']['run']['best_s']:.2f} ms",
                     f"{1e3 * sim['ours']['bare_loop']['best_s']:.2f} ms",
                     f"{q['slowdown_vs_bare']['best']:.1f}x slower", "<= 5x", t["within_5x_of_bare"]])
        b = sim["batch"]
        rows.append([f"simulation: batch of {b['variants']} variants, end to end", f"{b['end_to_end_s']['best']:.2f} s",
                     "—", f"run_batch alone {b['run_batch_s']['best']:.2f} s", "< 5 s", t["batch_under_5_s_end_to_end"]])
        if "vs_bare_over_cores" in b:
            rows.append([f"simulation: batch of {b['variants']} vs {b['variants']} bare loops over {b['cores']} cores",
                         f"{b['end_to_end_s']['best']:.2f} s", f"{b['bare_limit_s']['best']:.2f} s",
                         f"{b['vs_bare_over_cores']['best']:.1f}x slower", "<= 2.5x",
                         t["batch_within_2_5x_of_bare_over_cores"]])
    fr = results.get("frequency", {}).get("result")
    if fr:
        a, tu, g = fr["response"], fr["tuning"], fr["goals_met"]
        rows.append(["frequency response, 400 states x 10,000 ω", f"{1e3 * a['times']['ours']['best_s']:.0f} ms",
                     f"{a['times']['peer']['best_s']:.2f} s", f"{a['speedup']['best']:.1f}x faster", ">= 10x",
                     g["response_10x"]])
        rows.append(["tuning 5M4S (with the notch step) vs python-control (literal)",
                     f"{1e3 * tu['times']['ours']['best_s']:.1f} ms", f"{1e3 * tu['times']['peer_literal']['best_s']:.0f} ms",
                     f"{tu['speedup']['literal']['best']:.1f}x faster", ">= 5x", g["tuning_5x_literal"]])
        rows.append(["tuning 5M4S (with the notch step) vs python-control (log params)",
                     f"{1e3 * tu['times']['ours']['best_s']:.1f} ms", f"{1e3 * tu['times']['peer_log']['best_s']:.0f} ms",
                     f"{tu['speedup']['log']['best']:.1f}x faster", ">= 5x", g["tuning_5x_log"]])
        for peer, name in (("literal", "literal"), ("log", "log params")):
            rows.append([f"tuning only (no notch step) vs python-control ({name})",
                         f"{1e3 * tu['times']['ours_tuning_only']['best_s']:.1f} ms",
                         f"{1e3 * tu['times'][f'peer_{peer}']['best_s']:.0f} ms",
                         f"{tu['speedup_tuning_only'][peer]['best']:.1f}x faster", ">= 5x",
                         g[f"tuning_only_5x_{peer}"]])
    red = results.get("reduction", {}).get("result")
    if red:
        for case in red.get("cases", []):
            peers = {p["method"]: p for p in case.get("peers", []) if "seconds" in p}
            ours = {o["method"]: o for o in case.get("ours", [])}
            if "balred" in peers and "balanced" in ours:
                bad = (peers["balred"].get("hinf_relative_error") or 0.0) > 1.0
                rows.append([f"reduction ({case['case']}): balanced vs balred",
                             f"{1e3 * ours['balanced']['seconds']:.0f} ms", f"{1e3 * peers['balred']['seconds']:.0f} ms",
                             f"{peers['balred']['seconds'] / ours['balanced']['seconds']:.1f}x faster"
                             + (" (balred's model unusable here)" if bad else ""), "—", None])
    rob = results.get("robotics", {}).get("result")
    if rob:
        o, b = rob["one_call"]["per_call_s"], rob["batch"]["per_state_s"]
        q, g = rob["ratios_ours_over_pinocchio"], rob["goals_met"]
        for label, ours, peer, ratio, target, met in (
                ("robotics: inverse_dynamics, one call vs pin.rnea", o["ours_rnea"], o["pin_rnea"],
                 q["one_call_rnea"], "<= 5x", g["one_call_rnea_within_5x"]),
                ("robotics: inertia_matrix, one call vs pin.crba", o["ours_crba"], o["pin_crba"],
                 q["one_call_crba"], "<= 5x", g["one_call_crba_within_5x"]),
                ("robotics: inverse_dynamics_batch per state vs pin.rnea loop", b["ours_rnea"], b["pin_rnea_loop"],
                 q["batch_rnea_vs_pin_loop"], "<= 1x", g["batch_rnea_at_or_below_pin_per_state"]),
                ("robotics: inertia_matrix_batch per state vs pin.crba loop", b["ours_crba"], b["pin_crba_loop"],
                 q["batch_crba_vs_pin_loop"], "<= 1x", g["batch_crba_at_or_below_pin_per_state"])):
            rows.append([label, _common.fmt_s(ours["best"]), _common.fmt_s(peer["best"]),
                         f"{ratio['best']:.2f}x Pinocchio's time", target, met])
    stu = results.get("studies", {}).get("result")
    if stu:
        st, q, g, n = stu["study"], stu["ratios"], stu["targets_met"], stu["case"]["variants"]
        loop_ms = 1e3 * stu["loop"]["per_variant_s"]["best"]
        rows.append([f"study: {n} variants, 1 worker (started cluster) vs plain loop, per variant",
                     f"{1e3 * st['started_w1']['per_variant_s']['best']:.1f} ms", f"{loop_ms:.1f} ms",
                     f"loop/study {q['loop_over_study_1_worker']['best']:.2f} (> 1: study faster per core)", "—", None])
        rows.append([f"study: {n} variants, 2 workers (started cluster) vs plain loop, per variant",
                     f"{1e3 * st['started_w2']['per_variant_s']['best']:.1f} ms", f"{loop_ms:.1f} ms",
                     f"loop/study {q['loop_over_study_2_workers']['best']:.2f}", "—", None])
        for label, key, run in (("end to end", "end_to_end", "end_to_end"),
                                ("started cluster", "started_cluster", "started")):
            rows.append([f"study: parallel efficiency T1/(2 T2), {label}",
                         f"T2 {st[run + '_w2']['wall_s']['best']:.1f} s", f"T1 {st[run + '_w1']['wall_s']['best']:.1f} s",
                         f"{q[f'parallel_efficiency_{key}']['best']:.2f}", ">= 0.8", g[f"parallel_efficiency_{key}"]])
        for w in (1, 2):
            f = st[f"started_w{w}"]
            rows.append([f"study: Dask overhead per variant, {w} worker{'s' if w > 1 else ''} (started cluster)",
                         f"{1e3 * f['dask_overhead_per_variant_s']['best']:.2f} ms",
                         f"{1e3 * f['compute_per_variant_s']['best']:.1f} ms work",
                         f"{100 * f['dask_overhead_fraction']['best']:.1f} %", "< 5 %",
                         g[f"dask_overhead_started_w{w}"]])
    return _common.table(["benchmark", "ours", "peer", "ratio", "target", "met"], rows,
                         title="Summary (best-of times; see each table for medians and ranges)")


def _kept_from_earlier(output: Path, results: dict[str, Any]) -> dict[str, Any]:
    """With ``--only``: the other benchmarks' entries of the existing results file, kept (each still
    names the run it came from: ``created_in_run``, or the file's ``created`` for older entries)."""
    import json

    try:
        earlier = json.loads(output.read_text())
    except (OSError, ValueError):
        return {}
    kept = {}
    for name, entry in (earlier.get("benchmarks") or {}).items():
        if name not in results and isinstance(entry, dict):
            kept[name] = {**entry, "created_in_run": entry.get("created_in_run", earlier.get("created")),
                          "quick": entry.get("quick", earlier.get("quick"))}
    return kept


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Run SICOMAT's benchmarks side by side with their peers.")
    parser.add_argument("--quick", action="store_true", help="smoke run: fewer repeats, shorter ODE peer")
    parser.add_argument("--only", choices=NAMES, action="append",
                        help="run only this benchmark (repeatable); the others' entries in the output are kept")
    parser.add_argument("--output", type=Path, default=RESULTS, help=f"JSON output (default {RESULTS})")
    args = parser.parse_args(argv)

    start = time.perf_counter()
    info = _common.machine_info()
    print(f"SICOMAT benchmarks{' (--quick)' if args.quick else ''}: python {info['python']}, "
          + ", ".join(f"{k} {v}" for k, v in info["versions"].items() if v) + f"; {info['nproc']} cores "
          f"(load average {', '.join(f'{x:.2f}' for x in info['loadavg_at_start'] or [])}); "
          f"BLAS {((info['blas'] or {}).get('name'))} {((info['blas'] or {}).get('version'))}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    notes = []
    note = _common.openblas_note()
    if note:
        notes.append(note)
        print("NOTE: " + note)
    else:
        print("OPENBLAS_CORETYPE is not set in this environment (numpy runs its own OpenBLAS kernel).")
    print("Timings are wall times on a shared machine: best of N interleaved runs, with median and worst beside.")

    from benchmarks import bench_frequency, bench_robotics, bench_simulation, bench_studies

    benches: dict[str, tuple[Callable[[bool], dict[str, Any]], Callable[[dict[str, Any]], str]]] = {
        "simulation": (lambda q: bench_simulation.run(quick=q), bench_simulation.report),
        "frequency": (lambda q: bench_frequency.run(quick=q), bench_frequency.report),
        "reduction": (_reduction, _reduction_report),
        "robotics": (lambda q: bench_robotics.run(quick=q), bench_robotics.report),
        "studies": (lambda q: bench_studies.run(quick=q), bench_studies.report),
    }
    results: dict[str, Any] = {}
    failed = []
    for name in args.only or NAMES:
        fn, report = benches[name]
        print(f"\n{'=' * 100}\n[{name}]", flush=True)
        t0 = time.perf_counter()
        try:
            r = fn(args.quick)
        except Exception as exc:  # noqa: BLE001 - one failing benchmark must not hide the others
            traceback.print_exc()
            results[name] = {"seconds": time.perf_counter() - t0, "error": f"{type(exc).__name__}: {exc}"}
            failed.append(name)
            continue
        results[name] = {"seconds": time.perf_counter() - t0, "result": r,
                         "created_in_run": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "quick": args.quick}
        print(report(r))
        print(f"({name}: {results[name]['seconds']:.1f} s)", flush=True)

    total = time.perf_counter() - start
    print(f"\n{'=' * 100}")
    print(_summary(results))
    info["loadavg_at_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    created = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    kept = _kept_from_earlier(args.output, results) if args.only else {}
    payload = {"quick": args.quick, "total_seconds": total, "machine": info, "notes": notes,
               "benchmarks": results, "failed": failed, "created": created}
    if kept:
        payload["benchmarks"] = {**{k: v for k, v in kept.items()}, **results}
        payload["kept_from_earlier_runs"] = {k: v.get("created_in_run") for k, v in kept.items()}
    args.output.write_text(_common.to_json(payload) + "\n")
    print(f"\nTotal {total:.1f} s; results written to {args.output}"
          + (f"; FAILED: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
