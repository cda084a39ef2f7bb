"""Probe: what a kernel specialised per structure buys against the bare loop (issue 14's suggested way).

Issue 14 asks for 1000 variants of the 5M4S within 2.5x of 1000 bare loops over the cores, i.e. "variants
of one structure within 2x of the bare loop", and names "a kernel specialised per structure, compiled once
and cached" as one way. This probe measures that way without building it: it copies the source of
``sicomat/simulation/kernel.py`` into a temporary module in which the structure of the benchmark's program
is fixed at compile time (numba compiles module globals as constants):

- the sizes (states, inputs, outputs, friction links, recorded slots) read from the arrays in
  ``_simulate_steps`` and its inlined helpers become module constants, so LLVM unrolls the fixed-length loops;
- the op list, the op rows, the index table, the slot maps and the sparsity of ``[C D]`` become constant
  arrays in ``_simulate_steps``.

It is the same kernel otherwise (the same operations in the same order: its records equal the kernel's
bit for bit, checked here). The bare loop (``kernel.bare_loop``) is specialised the same way (its state and
input counts as constants): the issue's ratio compares work per step, so a fair reference gains what the
kernel gains from constant sizes.

Prints, over interleaved rounds (best and median): the time loop of one 1 s run of the benchmark's case
(``kernel.run`` with 8000 steps minus with 1 step), generic and specialised, and the bare 15-state loop,
generic and specialised, with the ratios. Run ``python -m benchmarks.specialisation_probe`` (about 1 min:
two numba compilations). Findings are in ``docs/servo.md`` (issue 14, "kernel specialised per structure").
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import interleaved  # noqa: E402  (first: one BLAS thread)

import importlib.util  # noqa: E402
import re  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
from types import ModuleType  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.bench_simulation import DURATION, _bare_system, load_case  # noqa: E402
from sicomat.simulation import kernel, loop_program  # noqa: E402
from sicomat.simulation.lowering import lower, sparse_outputs  # noqa: E402

ROUNDS = 9
REPEAT = 7          # interleaved calls of each timing within a round (their best is the round's time)


def _replace(src: str, old: str, new: str, count: int = 1) -> str:
    """``src`` with ``old`` replaced by ``new``, which must occur exactly ``count`` times (so that a change
    of the kernel's source stops the probe instead of leaving a part of it generic)."""
    found = src.count(old)
    if found != count:
        raise SystemExit(f"specialisation_probe: {old!r} occurs {found} times in kernel.py, expected {count}")
    return src.replace(old, new)


def specialised_source(program, bare_shape: tuple[int, int]) -> str:
    """The kernel's source with ``program``'s structure and the bare loop's sizes as module constants."""
    src = Path(kernel.__file__).read_text(encoding="utf-8")
    src = src.replace("cache=True", "cache=False")
    src = re.sub(r"^from \.\.(\w)", r"from sicomat.\1", src, flags=re.M)
    src = re.sub(r"^from \.(\w)", r"from sicomat.simulation.\1", src, flags=re.M)
    low = lower(program)
    s = low.struct
    out_ptr, out_col, _ = sparse_outputs(low.nums["CD"][None])
    nx, nu, nf = low.nx, s["in_slots"].size, low.links.size
    sizes = {"NX": nx, "NU": nu, "NY": s["out_slots"].size, "NF": nf, "NZ": nx + nu + nf,
             "NREC": s["rec_slots"].size, "BARE_NX": bare_shape[0], "BARE_NU": bare_shape[1]}
    arrays = {"op_code": s["op_code"], "op_period": s["op_period"], "op_ip": s["op_ip"], "idx": s["idx"],
              "in_slots": s["in_slots"], "out_slots": s["out_slots"], "fr_slots": s["fr_slots"],
              "rec_slots": s["rec_slots"], "out_ptr": out_ptr, "out_col": out_col}
    # sizes: in _simulate_steps, then in the inlined helpers (z.shape[0] is nz, stuck.shape[0] is nf)
    src = _replace(src, "    nx = x0.shape[0]\n    nu = in_slots.shape[0]\n    ny = out_slots.shape[0]",
                   "".join(f"    {k} = C_{k}\n" for k in arrays) + "    nx = NX\n    nu = NU\n    ny = NY")
    src = _replace(src, "    nf = coulomb.shape[0]\n    nz = nx + nu + nf\n    n_rec = rec_slots.shape[0]",
                   "    nf = NF\n    nz = NZ\n    n_rec = NREC")
    src = _replace(src, "nz = z.shape[0]", "nz = NZ", 4)
    src = _replace(src, "stuck.shape[0]", "NF", 6)
    src = _replace(src, "_dot2(Lz, c, j, z, z.shape[0])", "_dot2(Lz, c, j, z, NZ)")
    src = _replace(src, "    if z.shape[0] == 0:\n        return\n", "")
    # the bare loop
    src = _replace(src, "    nx = Phi.shape[0]\n    nu = Gamma.shape[1]\n", "    nx = BARE_NX\n    nu = BARE_NU\n")
    consts = "".join(f"{k} = {v}\n" for k, v in sizes.items())
    consts += "".join(f"C_{k} = np.array({v.tolist()!r}, dtype=np.{v.dtype})\n" for k, v in arrays.items())
    return src + "\n\n# the program's structure, compiled as constants\n" + consts


def _load(src: str, folder: Path) -> ModuleType:
    path = folder / "kernel_specialised.py"
    path.write_text(src, encoding="utf-8")
    spec = importlib.util.spec_from_file_location("kernel_specialised", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def main() -> None:
    _, loop, profile = load_case()
    program, n_steps = loop_program(loop, profile, DURATION)
    Phi, Gamma, K = _bare_system(program)
    with tempfile.TemporaryDirectory() as folder:
        spec = _load(specialised_source(program, (Phi.shape[0], Gamma.shape[1])), Path(folder))
        generic_run, spec_run = kernel.run(program, n_steps), spec.run(program, n_steps)
        if not (np.array_equal(generic_run.records, spec_run.records, equal_nan=True)
                and generic_run.events == spec_run.events):
            raise SystemExit("specialisation_probe: the specialised kernel's records differ from the kernel's")
        assert np.array_equal(kernel.bare_loop(Phi, Gamma, K, 100), spec.bare_loop(Phi, Gamma, K, 100))
        rows: dict[str, list[float]] = {k: [] for k in ("kernel", "kernel_spec", "bare", "bare_spec")}
        calls = {"bare": lambda: kernel.bare_loop(Phi, Gamma, K, n_steps),
                 "bare_spec": lambda: spec.bare_loop(Phi, Gamma, K, n_steps),
                 "kernel": lambda: kernel.run(program, n_steps), "kernel_setup": lambda: kernel.run(program, 1),
                 "kernel_spec": lambda: spec.run(program, n_steps), "kernel_spec_setup": lambda: spec.run(program, 1)}
        for _ in range(ROUNDS):
            best = {k: t.best for k, t in interleaved(calls, REPEAT).items()}
            for key in rows:     # a kernel's time loop: its run less its one-step run (the setup)
                rows[key].append(best[key] - best.get(key + "_setup", 0.0))
    print(f"5M4S, 1 s ({n_steps} steps), every effect on: time loop of kernel.run; bare loop of "
          f"{Phi.shape[0]} states. {ROUNDS} rounds, each the best of {REPEAT} interleaved calls.")
    for key, label in (("kernel", "kernel, generic"), ("kernel_spec", "kernel, structure as constants"),
                       ("bare", "bare loop, generic"), ("bare_spec", "bare loop, sizes as constants")):
        print(f"  {label:32s} best {1e3 * min(rows[key]):.3f} ms  median {1e3 * statistics.median(rows[key]):.3f} ms")

    def ratio(a: str, b: str) -> str:
        per_round = [x / y for x, y in zip(rows[a], rows[b])]
        return f"best {min(rows[a]) / min(rows[b]):.2f}x  median {statistics.median(per_round):.2f}x"

    print(f"  specialised kernel / generic kernel:       {ratio('kernel_spec', 'kernel')}")
    print(f"  specialised bare / generic bare:           {ratio('bare_spec', 'bare')}")
    print(f"  generic kernel / generic bare (today):     {ratio('kernel', 'bare')}")
    print(f"  specialised kernel / generic bare:         {ratio('kernel_spec', 'bare')}")
    print(f"  specialised kernel / specialised bare:     {ratio('kernel_spec', 'bare_spec')}")


if __name__ == "__main__":
    main()
