"""Parameter studies (issue 14, "Speed"): a study of the 5M4S on Dask against the same work in a plain loop.

The study: the paper's 5M4S (``examples/paper_5m4s.toml``, copied into a temporary folder beside the study
file), the load mass uniform within ±20 % and the load coupling's stiffness uniform within ±10 % (relative,
seed 14), analyses ``["modal", "tune", "margins", "simulate"]``: the first modes, the demo's tuning
(velocity crossover 125.6 rad/s at 45° phase margin, position phase margin 80°, no notch step), the margins
of the tuned loops and a 0.2 s simulation of the axis's own move (10 mm trapezoid) on the tuned loop.
N = 10,000 variants (``--variants N``; ``--quick``: 400), chunked by the engine's own rule.

What is timed (wall clock, ``time.perf_counter``):

- **study, end to end**: ``Study(path, out).run(workers=W)`` for W = 1 and 2: the plan, the embedded
  ``LocalCluster`` of W worker processes started and closed, the workers' imports and compiled kernels
  (loaded from numba's cache), the chunks computed and written (Parquet), the table read back and written.
- **study on a started cluster**: a ``distributed.Client(LocalCluster(W workers, 1 thread each))`` started
  beforehand and warmed (every worker runs one variant first: imports, numba's cache), then
  ``Study(path, out).run(client)`` timed alone: the study without the cluster's start. The cluster's start
  and the warm-up are timed and reported beside it.
- **plain loop**: the same work for the same variants through the public API, one by one, in this process:
  ``load_model(base, study.settings(v))``, ``modal_analysis(axis_mechanics(...))`` (and the moving mass the
  table holds), ``build_servo_loop``, ``tune_frequency(..., suggest_notch=False)`` and its tuned loop,
  ``LoopAnalysis.of`` + ``stability_margins`` of velocity-open and position-open + ``loop_verdict``, and
  ``simulate`` of the tuned loop for 0.2 s. On the full run the loop is timed on the first 2,000 variants
  (the per-variant times are compared); on ``--quick`` on all of them. Per-stage times are summed.

Before any timing, the kernels are compiled (or loaded from numba's cache) in this process: a first run of
a fresh checkout compiles them and writes the cache the workers then read. Each round runs the loop, the
two end-to-end studies and the two studies on a started cluster, interleaved; ``--quick`` does 2 rounds,
the full run 1 (about 20-30 min on two cores). Figures are best-of and median over the rounds.

Checked (the run fails otherwise): on the first variants the loop's figures equal the study's table (modes,
moving mass, tuned gains and achieved margins, the tuned loop's margins to rtol 1e-12: the same arithmetic
in the same order but for a few sums; the following errors to 1e-12 m: the study simulates each chunk in
one batch), and every study run gives the same table.

Figures: the time per variant of the study (wall / N) with 1 and 2 workers and of the loop; loop / study
with 1 worker (how many times faster the study is per core); the parallel efficiency T1 / (2 T2) with and
without the cluster's start (goal >= 0.8); Dask's overhead per variant, (W x wall - compute) / N, where
compute is the sum of the chunks' compute seconds measured on the workers, as a fraction of the work per
variant, compute / N (goal < 5 %); the cores the work used, compute / wall, and on a started cluster
the CPU seconds of the workers and of this process per wall second. In an end-to-end run each worker's
first chunk also holds its imports and the loading of the compiled kernels (1-2.5 s measured on this
machine): they count as compute there, which raises the compute per variant and lowers the overhead
fraction; the started-cluster runs (workers warmed first) give Dask's overhead proper. On a machine shared
with other work, 2 workers cannot both have a whole core: the load average at the start and the end is
reported beside the figures.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import EXAMPLE_5M4S, table  # noqa: E402

import math  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

DEFAULT_VARIANTS = 10_000
QUICK_VARIANTS = 400
LOOP_SUBSET = 2_000
"""The plain loop runs on at most this many variants (the first ones; ~35 ms each)."""
CHECKED = 5
"""Variants whose loop figures are checked against the study's table."""
WORKERS = (1, 2)
TARGETS = {"parallel_efficiency_min": 0.8, "dask_overhead_fraction_max": 0.05}
AXIS = "X"
DURATION = 0.2
TUNE = {"velocity_crossover": 125.6, "velocity_phase_margin": 45.0, "position_phase_margin": 80.0}

STUDY = """\
# written by benchmarks/bench_studies.py
name = "bench-5m4s"
base = "paper_5m4s.toml"
seed = 14
analyses = ["modal", "tune", "margins", "simulate"]

[[parameters]]
path = "axes.X.mechanics.bodies.load.mass"
distribution = "uniform"
low = 0.8
high = 1.2
relative = true
samples = {n}

[[parameters]]
path = "axes.X.mechanics.couplings.load.stiffness"
distribution = "uniform"
low = 0.9
high = 1.1
relative = true
samples = {n}

[tune]
velocity_crossover = "125.6 rad/s"
velocity_phase_margin = 45
position_phase_margin = 80

[simulate]
duration = "0.2 s"
"""


def write_study(folder: Path, variants: int) -> Path:
    """The study file in ``folder``, the base model copied beside it."""
    shutil.copy(EXAMPLE_5M4S, folder / "paper_5m4s.toml")
    path = folder / "study.toml"
    path.write_text(STUDY.format(n=variants))
    return path


# ------------------------------------------------------------------------------------------- the plain loop
STAGES = ("load_model", "modal", "servo_loop", "tune", "margins", "simulate")


def one_variant(base: Path, settings: list[str], stages: dict[str, float] | None = None) -> dict[str, Any]:
    """One variant's work through the public API; its figures under the study table's column names."""
    from sicomat import (LoopAnalysis, TuningTargets, build_servo_loop, load_model, loop_verdict, modal_analysis,
                         simulate, stability_margins, tune_frequency)
    from sicomat.robotics.lowering import axis_mechanics
    from sicomat.tasks.simulate import choose_profile
    from sicomat.simulation.checks import limit_cycle_warning

    two_pi = 2 * math.pi
    row: dict[str, Any] = {}
    clock = [time.perf_counter()]

    def lap(stage: str) -> None:
        now = time.perf_counter()
        if stages is not None:
            stages[stage] = stages.get(stage, 0.0) + now - clock[0]
        clock[0] = now

    machine = load_model(base, settings)
    lap("load_model")
    modes = modal_analysis(axis_mechanics(machine, AXIS))
    flexible = sorted((m for m in modes.modes if not m.rigid), key=lambda m: m.undamped_hz)
    row.update({f"modal.f{k + 1}_hz": flexible[k].undamped_hz for k in range(3)})
    row["modal.zeta1"] = flexible[0].damping_ratio
    row["modal.f_meca_hz"] = math.nan if modes.f_meca_hz is None else modes.f_meca_hz
    lap("modal")
    loop = build_servo_loop(machine, AXIS)
    mech = loop.mechanics     # the moving mass the table holds: phi' M phi, phi the rigid motion per unit axis
    phi, _ = mech.rigid_motion(mech.actuator(loop.actuator).vector, loop.tool)
    row["modal.moving_mass"] = float(phi @ mech.mass @ phi)
    lap("servo_loop")
    tuned = tune_frequency(loop, TuningTargets(**TUNE), suggest_notch=False)
    g, a = tuned.tuned, tuned.achieved
    row.update({"tune.targets_met": bool(tuned.targets_met), "tune.stable": tuned.stable, "tune.Kp": g.Kp,
                "tune.Kp_normalized": g.Kp_normalized, "tune.Ti": g.Ti, "tune.Kv": g.Kv})
    for name in ("velocity", "position"):
        bandwidth = getattr(a, f"{name}_bandwidth_rad_s")
        row.update({f"tune.{name}_phase_margin_deg": getattr(a, f"{name}_phase_margin_deg"),
                    f"tune.{name}_gain_margin_db": getattr(a, f"{name}_gain_margin_db"),
                    f"tune.{name}_crossover_hz": getattr(a, f"{name}_crossover_rad_s") / two_pi,
                    f"tune.{name}_bandwidth_hz": (math.nan if bandwidth is None else bandwidth) / two_pi})
    tuned_loop = tuned.tuned_loop()
    lap("tune")
    an = LoopAnalysis.of(tuned_loop)
    for name in ("velocity", "position"):
        m = stability_margins(an.response(f"{name}-open"))
        row.update({f"margins.{name}.phase_margin_deg": m.phase_margin_deg,
                    f"margins.{name}.gain_margin_db": m.gain_margin_db,
                    f"margins.{name}.crossover_hz": m.gain_crossover_rad_s / two_pi,
                    f"margins.{name}.bandwidth_hz": (math.nan if m.bandwidth_rad_s is None
                                                     else m.bandwidth_rad_s) / two_pi,
                    f"margins.{name}.delay_margin": m.delay_margin_s,
                    f"margins.{name}.modulus_margin": m.modulus_margin})
    row["margins.stable"] = loop_verdict(tuned_loop, an=an).stable
    lap("margins")
    profile, _ = choose_profile(machine.axes[AXIS].trajectory, None, None, None, None)
    series = simulate(tuned_loop, profile, DURATION)
    metrics = series.metrics
    if metrics is None:   # simulate gives the following-error figures of every move on the axis
        raise RuntimeError("simulate() gave no following-error figures")
    row.update({"simulate.max_following_error": metrics.max_following_error,
                "simulate.rms_following_error": metrics.rms_following_error,
                "simulate.final_error": metrics.final_error,
                # sicomat simulate's verdict, as the study's simulate.stable: the poles (margins') and the run
                "simulate.stable": bool(row["margins.stable"]) and limit_cycle_warning(series) is None})
    lap("simulate")
    return row


def plain_loop(base: Path, settings: list[list[str]]) -> tuple[float, dict[str, float], list[dict[str, Any]]]:
    """Wall seconds of the loop over ``settings``, its per-stage seconds and the first rows (checked)."""
    stages: dict[str, float] = {}
    rows = []
    start = time.perf_counter()
    for k, s in enumerate(settings):
        row = one_variant(base, s, stages)
        if k < CHECKED:
            rows.append(row)
    return time.perf_counter() - start, stages, rows


def check_rows(table: Any, rows: list[dict[str, Any]]) -> int:
    """Raise ``AssertionError`` unless the loop's rows equal the study table's first rows; the number of
    values compared. Floats to rtol 1e-12 (the same arithmetic, a few sums in another order), following
    errors to 1e-12 m (a batch against one run: a few ulps of the 10 mm positions they are differences of)."""
    compared = 0
    for k, row in enumerate(rows):
        line = table.iloc[k]
        for name, ours in row.items():
            theirs = line[name]
            if isinstance(ours, bool) or name.endswith(("targets_met", "stable")):
                ok = bool(theirs) == bool(ours)
            elif name.startswith("simulate."):
                ok = abs(float(theirs) - float(ours)) <= 1e-12
            else:
                ours, theirs = float(ours), float(theirs)
                ok = (ours == theirs or (math.isnan(ours) and math.isnan(theirs))
                      or math.isclose(ours, theirs, rel_tol=1e-12, abs_tol=0.0))
            if not ok:
                raise AssertionError(f"variant {k}: {name} is {theirs!r} in the study's table, {ours!r} in the "
                                     "plain loop: the two do not time the same work")
            compared += 1
    return compared


# ------------------------------------------------------------------------------------------- the study
def _study_run(path: Path, out: Path, *, workers: int | None = None, client: Any = None) -> dict[str, Any]:
    from sicomat.studies import Study

    cpu0 = time.process_time()
    t0 = time.perf_counter()
    results = Study(path, out=out).run(client, workers=None if client is not None else workers)
    wall = time.perf_counter() - t0
    info = results.info
    return {"wall_s": wall, "compute_s": info["compute_time"], "chunks": info["chunks"]["total"],
            "workers_seen": info["workers"], "client_cpu_s": time.process_time() - cpu0,
            "table": results.table}


def warm_worker(base: str) -> float:
    """On a worker (``client.run``): imports and compiled kernels ready, as after a first chunk; seconds."""
    from sicomat import build_servo_loop, load_model, simulate_batch
    from sicomat.studies import analyses  # noqa: F401  (what run_chunk imports)
    from sicomat.tasks.simulate import choose_profile

    t0 = time.perf_counter()
    one_variant(Path(base), [])
    machine = load_model(base)
    profile, _ = choose_profile(machine.axes[AXIS].trajectory, None, None, None, None)
    simulate_batch([build_servo_loop(machine, AXIS)], profile, 0.01)
    return time.perf_counter() - t0


def _started_cluster_run(path: Path, out: Path, workers: int) -> dict[str, Any]:
    """The study on a cluster started and warmed beforehand; the start and the warm-up timed apart."""
    import logging

    import psutil
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    client = Client(cluster)
    start_s = time.perf_counter() - t0
    try:
        t0 = time.perf_counter()
        warm = client.run(warm_worker, str(path.parent / "paper_5m4s.toml"))
        warm_s = time.perf_counter() - t0
        procs = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
        before = [sum(p.cpu_times()[:2]) for p in procs]
        r = _study_run(path, out, client=client)
        r["workers_cpu_s"] = sum(sum(p.cpu_times()[:2]) - b for p, b in zip(procs, before))
    finally:
        client.close()
        cluster.close()
    r.update({"cluster_start_s": start_s, "warm_up_s": warm_s, "warm_up_on_workers_s": list(warm.values())})
    return r


def _warm_here(folder: Path) -> float:
    """Compile (or load from numba's cache) every kernel in this process before timing: a fresh checkout
    compiles here and writes the cache the workers read. A 2-variant study on an in-process client."""
    from distributed import Client

    t0 = time.perf_counter()
    path = write_study(folder, 2)
    one_variant(path.parent / "paper_5m4s.toml", [])
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as client:
        _study_run(path, folder / "out", client=client)
    return time.perf_counter() - t0


def _stats(samples: list[float]) -> dict[str, Any]:
    return {"best": min(samples), "median": statistics.median(samples), "worst": max(samples), "n": len(samples),
            "samples": samples}


def _ratio(a: dict[str, Any], b: dict[str, Any], k: float = 1.0) -> dict[str, float]:
    """a / (k b), from the bests and from the medians."""
    return {"best": a["best"] / (k * b["best"]), "median": a["median"] / (k * b["median"])}


# ------------------------------------------------------------------------------------------- run
def run(quick: bool = False, variants: int | None = None, repeat: int | None = None,
        loop_variants: int | None = None) -> dict[str, Any]:
    """Time the study (1 and 2 workers, end to end and on a started cluster) and the plain loop."""
    import pandas as pd

    from sicomat.studies import Study
    from sicomat.studies.engine import chunk_size_for

    n = variants or (QUICK_VARIANTS if quick else DEFAULT_VARIANTS)
    rounds = repeat or (2 if quick else 1)
    n_loop = min(n, loop_variants or LOOP_SUBSET)
    load0 = list(os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="sicomat-bench-studies-") as tmp:
        folder = Path(tmp)
        (folder / "warm").mkdir()
        warm_here_s = _warm_here(folder / "warm")
        path = write_study(folder, n)
        study = Study(path)
        chunks = study.plan.spec.chunk_size or chunk_size_for(n)
        base = path.parent / "paper_5m4s.toml"
        settings = [study.settings(v) for v in range(n_loop)]
        runs: dict[str, list[dict[str, Any]]] = {f"{kind}_w{w}": [] for kind in ("end_to_end", "started")
                                                 for w in WORKERS}
        loops: list[tuple[float, dict[str, float]]] = []
        reference: Any = None
        checked = 0
        for r in range(rounds):
            loop_s, stages, rows = plain_loop(base, settings)
            loops.append((loop_s, stages))
            for w in WORKERS:
                for kind in ("end_to_end", "started"):
                    out = folder / f"out-{kind}-w{w}-r{r}"
                    res = (_study_run(path, out, workers=w) if kind == "end_to_end"
                           else _started_cluster_run(path, out, w))
                    tab = res.pop("table")
                    if reference is None:
                        reference = tab
                    else:     # every run gives the same table
                        pd.testing.assert_frame_equal(tab, reference)
                    shutil.rmtree(out, ignore_errors=True)
                    runs[f"{kind}_w{w}"].append(res)
            checked = check_rows(reference, rows)
        failed = int(reference["error"].notna().sum())
        targets_met_share = float(reference["tune.targets_met"].astype(float).mean())
    loop_wall = _stats([w for w, _ in loops])
    loop_per = _stats([w / n_loop for w, _ in loops])
    stage_ms = {s: 1e3 * min(st.get(s, 0.0) for _, st in loops) / n_loop for s in STAGES}

    figures: dict[str, Any] = {}
    for key, samples in runs.items():
        w = int(key[-1])
        wall = _stats([s["wall_s"] for s in samples])
        per = _stats([s["wall_s"] / n for s in samples])
        compute = [s["compute_s"] for s in samples]
        overhead = [(w * s["wall_s"] - s["compute_s"]) / s["compute_s"] for s in samples]
        f = {"workers": w, "wall_s": wall, "per_variant_s": per,
             "compute_per_variant_s": _stats([c / n for c in compute]),
             "dask_overhead_per_variant_s": _stats([(w * s["wall_s"] - s["compute_s"]) / n for s in samples]),
             "dask_overhead_fraction": _stats(overhead),
             "cores_used_by_the_work": _stats([s["compute_s"] / s["wall_s"] for s in samples]),
             "client_cpu_s": _stats([s["client_cpu_s"] for s in samples]),
             "workers_seen": [s["workers_seen"] for s in samples]}
        if key.startswith("started"):
            f["cluster_start_s"] = _stats([s["cluster_start_s"] for s in samples])
            f["warm_up_s"] = _stats([s["warm_up_s"] for s in samples])
            f["cores_used_cpu"] = _stats([(s["workers_cpu_s"] + s["client_cpu_s"]) / s["wall_s"] for s in samples])
        figures[key] = f
    e1, e2 = figures["end_to_end_w1"]["wall_s"], figures["end_to_end_w2"]["wall_s"]
    s1, s2 = figures["started_w1"]["wall_s"], figures["started_w2"]["wall_s"]
    ratios = {
        "loop_over_study_1_worker": _ratio(loop_per, figures["started_w1"]["per_variant_s"]),
        "loop_over_study_1_worker_end_to_end": _ratio(loop_per, figures["end_to_end_w1"]["per_variant_s"]),
        "loop_over_study_2_workers": _ratio(loop_per, figures["started_w2"]["per_variant_s"]),
        "parallel_efficiency_end_to_end": _ratio(e1, e2, 2.0),
        "parallel_efficiency_started_cluster": _ratio(s1, s2, 2.0),
    }
    o = {k: figures[k]["dask_overhead_fraction"]["best"] for k in figures}
    met = {
        "parallel_efficiency_end_to_end": ratios["parallel_efficiency_end_to_end"]["best"]
        >= TARGETS["parallel_efficiency_min"],
        "parallel_efficiency_started_cluster": ratios["parallel_efficiency_started_cluster"]["best"]
        >= TARGETS["parallel_efficiency_min"],
        **{f"dask_overhead_{k}": o[k] < TARGETS["dask_overhead_fraction_max"] for k in figures},
    }
    return {
        "case": {"model": str(EXAMPLE_5M4S.relative_to(EXAMPLE_5M4S.parents[1])), "axis": AXIS,
                 "variants": n, "chunk_size": chunks, "chunks": math.ceil(n / chunks),
                 "analyses": ["modal", "tune", "margins", "simulate"], "simulated_s": DURATION, "tune": TUNE,
                 "parameters": {"axes.X.mechanics.bodies.load.mass": "uniform x0.8..1.2",
                                "axes.X.mechanics.couplings.load.stiffness": "uniform x0.9..1.1"},
                 "failed_variants": failed, "tune_targets_met_share": targets_met_share},
        "rounds": rounds, "warm_up_in_this_process_s": warm_here_s,
        "loop": {"variants": n_loop, "wall_s": loop_wall, "per_variant_s": loop_per, "stages_ms_per_variant": stage_ms},
        "study": figures, "ratios": ratios, "targets": TARGETS, "targets_met": met,
        "checked": {"variants": min(CHECKED, n_loop), "values": checked},
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "loadavg": {"start": load0, "end": list(os.getloadavg())},
    }


def report(r: dict[str, Any]) -> str:
    """The tables of ``run()``'s figures."""
    c, lp, st, q, t = r["case"], r["loop"], r["study"], r["ratios"], r["targets_met"]
    n = c["variants"]
    lines = [f"Studies (issue 14): {c['model']}, {n} variants (load mass x0.8..1.2, load coupling stiffness "
             f"x0.9..1.1), modal + tune + margins + {c['simulated_s']:g} s simulation each; {c['chunks']} chunks of "
             f"{c['chunk_size']}; {c['failed_variants']} failed; {r['rounds']} round(s); {r['cores']} cores, "
             f"load average {r['loadavg']['start'][0]:.2f} -> {r['loadavg']['end'][0]:.2f}"]
    rows = []
    label = {"end_to_end_w1": "study, 1 worker, end to end (cluster start included)",
             "end_to_end_w2": "study, 2 workers, end to end (cluster start included)",
             "started_w1": "study, 1 worker, on a started cluster",
             "started_w2": "study, 2 workers, on a started cluster"}
    for key in ("end_to_end_w1", "end_to_end_w2", "started_w1", "started_w2"):
        f = st[key]
        rows.append([label[key], f["wall_s"]["best"], f["wall_s"]["median"], 1e3 * f["per_variant_s"]["best"],
                     1e3 * f["per_variant_s"]["median"], 1e3 * f["compute_per_variant_s"]["best"],
                     1e3 * f["dask_overhead_per_variant_s"]["best"], 100 * f["dask_overhead_fraction"]["best"],
                     100 * f["dask_overhead_fraction"]["median"], f["cores_used_by_the_work"]["best"]])
    rows.append([f"plain loop over the public API ({lp['variants']} variants{'' if lp['variants'] == n else ', a subset'})",
                 lp["wall_s"]["best"], lp["wall_s"]["median"], 1e3 * lp["per_variant_s"]["best"],
                 1e3 * lp["per_variant_s"]["median"], None, None, None, None, None])
    lines.append(table(["run", "wall best s", "wall median s", "ms/variant best", "ms/variant median",
                        "compute ms/variant", "Dask overhead ms/variant", "overhead % best", "overhead % median",
                        "cores used"], rows))
    s1, s2 = st["started_w1"], st["started_w2"]
    lines.append("started clusters: start " + ", ".join(
        f"{k[-2:]} {s['cluster_start_s']['best']:.2f} s" for k, s in (("started_w1", s1), ("started_w2", s2)))
        + "; worker warm-up (imports, numba's cache) " + ", ".join(
        f"{k[-2:]} {s['warm_up_s']['best']:.2f} s" for k, s in (("started_w1", s1), ("started_w2", s2)))
        + "; CPU seconds (workers + this process) per wall second " + ", ".join(
        f"{k[-2:]} {s['cores_used_cpu']['best']:.2f}" for k, s in (("started_w1", s1), ("started_w2", s2)))
        + f"; kernels readied in this process first in {r['warm_up_in_this_process_s']:.1f} s")
    lines.append("plain loop, ms per variant by stage (best round): " + ", ".join(
        f"{k} {v:.2f}" for k, v in lp["stages_ms_per_variant"].items()))
    yes = {True: "met", False: "NOT met"}
    lo, lo_e = q["loop_over_study_1_worker"], q["loop_over_study_1_worker_end_to_end"]
    pe, pe_s = q["parallel_efficiency_end_to_end"], q["parallel_efficiency_started_cluster"]
    lines.append(table(["figure", "best", "median", "goal", "met"], [
        ["loop / study (1 worker, started cluster): x faster per core", lo["best"], lo["median"], "—", None],
        ["loop / study (1 worker, end to end)", lo_e["best"], lo_e["median"], "—", None],
        ["loop / study (2 workers, started cluster)", q["loop_over_study_2_workers"]["best"],
         q["loop_over_study_2_workers"]["median"], "—", None],
        ["parallel efficiency T1/(2 T2), end to end", pe["best"], pe["median"], ">= 0.8",
         t["parallel_efficiency_end_to_end"]],
        ["parallel efficiency T1/(2 T2), started cluster", pe_s["best"], pe_s["median"], ">= 0.8",
         t["parallel_efficiency_started_cluster"]],
        *[[f"Dask overhead / work per variant, {label[k]}", st[k]["dask_overhead_fraction"]["best"],
           st[k]["dask_overhead_fraction"]["median"], "< 0.05", t[f"dask_overhead_{k}"]]
          for k in ("end_to_end_w1", "end_to_end_w2", "started_w1", "started_w2")],
    ], title="Ratios (best: from the best times of the rounds; overhead (W x wall - compute) / compute)"))
    lines.append(f"checked: the loop's figures equal the study's table on its first {r['checked']['variants']} "
                 f"variants ({r['checked']['values']} values; rtol 1e-12, following errors to 1e-12 m) and every "
                 f"study run gave the same table; tuning targets met on {100 * c['tune_targets_met_share']:.0f} % "
                 f"of the variants. Parallel efficiency {yes[t['parallel_efficiency_end_to_end']]} end to end, "
                 f"{yes[t['parallel_efficiency_started_cluster']]} on a started cluster.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Run this benchmark alone: ``python -m benchmarks.bench_studies [--quick] [--variants N]``."""
    import argparse

    from benchmarks._common import openblas_note

    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_VARIANTS} variants, 2 rounds")
    parser.add_argument("--variants", type=int, default=None,
                        help=f"variants in the study (default {DEFAULT_VARIANTS}, {QUICK_VARIANTS} with --quick)")
    parser.add_argument("--repeat", type=int, default=None, help="rounds (default 1, 2 with --quick)")
    parser.add_argument("--loop-variants", type=int, default=None,
                        help=f"variants the plain loop runs (the first ones; default {LOOP_SUBSET})")
    args = parser.parse_args(argv)
    for name in ("variants", "repeat", "loop_variants"):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1")
    note = openblas_note()
    if note:
        print("NOTE: " + note)
    print(report(run(quick=args.quick, variants=args.variants, repeat=args.repeat, loop_variants=args.loop_variants)))


if __name__ == "__main__":
    main()
