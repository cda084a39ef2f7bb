"""Shared helpers of the benchmarks: one BLAS thread, timing (best of N), machine info, tables.

Import this module before numpy (the benchmark modules do) so that BLAS runs on one thread for
ours and the peers alike, unless the caller set a thread count already: on a small shared machine
a multi-threaded BLAS makes times vary several-fold between runs (a batched 13×13 ``expm`` went
from 0.9 s to 8 s) and the batch target is stated for one core.
"""

from __future__ import annotations

import os

THREADS_SET_HERE = [v for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS") if v not in os.environ]
"""The thread variables these benchmarks set to 1 (the others were set by the caller and are kept)."""
for _var in THREADS_SET_HERE:
    os.environ[_var] = "1"

import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Callable, Sequence  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE_5M4S = ROOT / "examples" / "paper_5m4s.toml"

OPENBLAS_NOTE = (
    "OPENBLAS_CORETYPE is set in this environment ({value}); it makes OpenBLAS use a generic kernel and "
    "slows numpy, ours and the peers alike. To benchmark against numpy at full speed, unset it together "
    "with OPENBLAS_L2_SIZE for that one command only, e.g. "
    "`env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE python -m benchmarks.run` (the benchmarks never change "
    "either variable; tests and CI keep them)."
)


class Timing:
    """Wall times (s) of repeated calls: best, median, worst; ``value`` is the last call's result."""

    def __init__(self) -> None:
        self.samples: list[float] = []
        self.value: Any = None

    def add(self, fn: Callable[[], Any]) -> Any:
        t0 = time.perf_counter()
        self.value = fn()
        self.samples.append(time.perf_counter() - t0)
        return self.value

    @property
    def best(self) -> float:
        return min(self.samples)

    @property
    def median(self) -> float:
        return statistics.median(self.samples)

    @property
    def worst(self) -> float:
        return max(self.samples)

    def to_dict(self) -> dict[str, Any]:
        return {"best_s": self.best, "median_s": self.median, "worst_s": self.worst, "n": len(self.samples),
                "samples_s": self.samples}


def interleaved(fns: dict[str, Callable[[], Any]], rounds: int | dict[str, int]) -> dict[str, Timing]:
    """Time each function ``rounds`` times, interleaved round by round so all see the same load."""
    counts = {k: rounds for k in fns} if isinstance(rounds, int) else dict(rounds)
    out = {k: Timing() for k in fns}
    for r in range(max(counts.values())):
        for key, fn in fns.items():
            if r < counts[key]:
                out[key].add(fn)
    return out


def speedup(peer: Timing | float, ours: Timing | float) -> dict[str, float]:
    """How many times faster ours is: ratio of the bests and of the medians."""
    pb = peer if isinstance(peer, float) else peer.best
    pm = peer if isinstance(peer, float) else peer.median
    ob = ours if isinstance(ours, float) else ours.best
    om = ours if isinstance(ours, float) else ours.median
    return {"best": pb / ob, "median": pm / om}


def _version(module: str) -> str | None:
    try:
        mod = __import__(module)
    except Exception:  # noqa: BLE001 - an absent optional package is a fact to report
        return None
    return str(getattr(mod, "__version__", "unknown"))


def _git(*args: str) -> str | None:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=10,
                              check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        return None


def machine_info() -> dict[str, Any]:
    """Versions, BLAS and thread settings, cores, load: what the figures depend on."""
    import numpy as np

    cpu = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        blas = np.__config__.CONFIG["Build Dependencies"]["blas"]
        blas = {k: blas.get(k) for k in ("name", "version", "openblas configuration")}
    except Exception:  # noqa: BLE001
        blas = None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return {
        "python": sys.version.split()[0], "implementation": platform.python_implementation(),
        "platform": platform.platform(), "cpu": cpu,
        "nproc": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "cpu_count": os.cpu_count(),
        "loadavg_at_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "versions": {name: _version(name) for name in ("numpy", "scipy", "numba", "control", "slycot", "sicomat")},
        "blas": blas,
        "env": {k: v for k, v in sorted(os.environ.items())
                if k.startswith(("OPENBLAS", "OMP_", "MKL_", "NUMBA_", "NVPL_"))},
        "thread_variables_set_by_benchmarks": THREADS_SET_HERE,
        "openblas_coretype_set": "OPENBLAS_CORETYPE" in os.environ,
        "git_head": _git("rev-parse", "HEAD"), "git_tracked_changes": None if status is None else bool(status),
    }


def openblas_note() -> str | None:
    """The OPENBLAS_CORETYPE note when the variable is set, else None."""
    value = os.environ.get("OPENBLAS_CORETYPE")
    return None if value is None else OPENBLAS_NOTE.format(value=value)


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]], title: str | None = None) -> str:
    """A plain aligned text table (numbers right-aligned)."""
    cells = [[_cell(v) for v in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]
    numeric = [all(_is_num(row[i]) for row in rows if row[i] is not None) for i in range(len(headers))]

    def line(values: Sequence[str]) -> str:
        return "  ".join(v.rjust(w) if num else v.ljust(w) for v, w, num in zip(values, widths, numeric)).rstrip()

    out = [] if title is None else [title]
    out.append(line(list(headers)))
    out.append("  ".join("-" * w for w in widths))
    out += [line(r) for r in cells]
    return "\n".join(out)


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _cell(v: Any) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if v != v:
            return "nan"
        a = abs(v)
        if a == 0:
            return "0"
        if 1e-3 <= a < 1e5:
            return f"{v:.4g}"
        return f"{v:.3e}"
    return str(v)


def fmt_s(seconds: float) -> str:
    """A duration with a readable unit."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def to_json(data: Any) -> str:
    """JSON with numpy scalars and arrays converted, non-finite floats as null."""
    import numpy as np

    def clean(x: Any) -> Any:
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, np.ndarray):
            return clean(x.tolist())
        if isinstance(x, (np.bool_, bool)):
            return bool(x)
        if isinstance(x, np.integer):
            return int(x)
        if isinstance(x, (np.floating, float)):
            x = float(x)
            return x if np.isfinite(x) else None
        if isinstance(x, complex):
            return [x.real, x.imag]
        return x

    return json.dumps(clean(data), indent=2, ensure_ascii=False)


def module_main(doc: str, run, report, quick_help: str = "fewer repeats", argv=None) -> None:
    """The ``__main__`` entry of one benchmark module: parse ``--quick``, print the OPENBLAS note and the report."""
    import argparse

    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=quick_help)
    args = parser.parse_args(argv)
    note = openblas_note()
    if note:
        print("NOTE: " + note)
    print(report(run(quick=args.quick)))
