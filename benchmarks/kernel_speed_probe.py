"""Speed probe of the simulation kernel: a 14-state two-rate servo loop at 8 kHz against the bare loop.

Run with ``python benchmarks/kernel_speed_probe.py``; prints wall time per simulated second.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg

from sicomat.servo import program as p
from sicomat.simulation.kernel import bare_loop, run, run_batch

H = 1.0 / 8000.0          # base step: 8 kHz velocity loop
POSITION_PERIOD = 4       # 2 kHz position loop
N_MASSES = 7              # 14 continuous states


def chain_plant(n: int = N_MASSES, m: float = 10.0, k: float = 2e7, c: float = 2e3):
    """A chain of n masses driven by a force on mass 0; states (q, q̇)."""
    M = np.full(n, m)
    K = np.zeros((n, n))
    for i in range(n - 1):
        K[i:i + 2, i:i + 2] += k * np.array([[1, -1], [-1, 1]])
    Dm = K * (c / k)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K / M[:, None], -Dm / M[:, None]]])
    B = np.zeros((2 * n, 1))
    B[n, 0] = 1.0 / m
    return A, B


def servo(scale: float = 1.0, n_steps: int = 8000, friction: bool = False) -> p.HybridProgram:
    """Position P loop (period 4) around a velocity PI loop with filter, limit, quantizer, delay."""
    n = N_MASSES
    A, B = chain_plant()
    C = np.zeros((2, 2 * n))
    C[0, 0] = 1.0                 # motor position
    C[1, n] = 1.0                 # motor velocity
    names = ["y.pos", "y.vel", "r.pos", "r.vel", "pos.err", "v.cmd", "v.err", "v.filt", "f.pi",
             "f.sat", "f.q", "f.cmd", "fric"]
    s = {name: i for i, name in enumerate(names)}
    kp = 3e4 * scale
    ti = 0.01
    pi = p.LinearBlock(A=np.array([[1.0]]), B=np.array([[H]]), C=np.array([[kp / ti]]), D=np.array([[kp]]),
                       inputs=(s["v.err"],), outputs=(s["f.pi"],))
    a = np.exp(-2 * np.pi * 1000 * H)
    lp = p.LinearBlock(A=np.array([[a]]), B=np.array([[1 - a]]), C=np.array([[1.0]]), D=np.array([[0.0]]),
                       inputs=(s["y.vel"],), outputs=(s["v.filt"],))
    ops = (
        p.Setpoint(period=POSITION_PERIOD, column=0, output=s["r.pos"]),
        p.Sum(period=POSITION_PERIOD, inputs=(s["r.pos"], s["y.pos"]), weights=(1.0, -1.0), output=s["pos.err"]),
        p.Sum(period=POSITION_PERIOD, inputs=(s["pos.err"],), weights=(60.0,), output=s["v.cmd"]),
        p.LinearOutput(block=1), p.LinearUpdate(block=1),
        p.Sum(inputs=(s["v.cmd"], s["v.filt"]), weights=(1.0, -1.0), output=s["v.err"]),
        p.LinearOutput(block=0), p.LinearUpdate(block=0),
        p.Saturate(input=s["f.pi"], output=s["f.sat"], lower=-5e3, upper=5e3),
        p.Quantize(input=s["f.sat"], output=s["f.q"], step=0.01),
        p.Delay(input=s["f.q"], output=s["f.cmd"], samples=1),
    )
    nf = 1 if friction else 0
    F = np.zeros((2 * n, nf))
    G = np.zeros((nf, 2 * n))
    if friction:
        F[2 * n - 1, 0] = 1.0 / 10.0
        G[0, 2 * n - 1] = 1.0
    cont = p.ContinuousPart(A=A, B=B, C=C, D=np.zeros((2, 1)), F=F, G=G,
                            coulomb=np.full(nf, 50.0), static=np.full(nf, 80.0), x0=np.zeros(2 * n),
                            input_slots=(s["f.cmd"],), output_slots=(s["y.pos"], s["y.vel"]),
                            friction_slots=(s["fric"],) if friction else ())
    t = np.arange(n_steps // POSITION_PERIOD + 1) * H * POSITION_PERIOD
    table = np.array([0.01 * np.sin(2 * np.pi * 2 * t)])
    return p.HybridProgram(step=H, slot_names=tuple(names), continuous=cont, blocks=(pi, lp), ops=ops,
                           table=table, record=(s["y.pos"], s["pos.err"], s["f.cmd"], s["fric"]))


def best_of(fn, repeat: int = 7) -> float:
    """Smallest CPU time of ``repeat`` calls (process time: robust to other processes' load)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    n_steps = 80000                     # 10 simulated seconds
    seconds = n_steps * H
    prog = servo(n_steps=n_steps)
    run(prog, 10)                       # compile / load the cache
    A, B = chain_plant()
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, A.shape[0] + 1))]]) * H)
    Phi, Gamma = E[:-1, :-1], E[:-1, -1:]
    K = np.zeros((1, A.shape[0]))
    K[0, N_MASSES] = 1e3
    bare_loop(Phi, Gamma, K, 10)

    prog_f = servo(n_steps=n_steps, friction=True)
    run(prog_f, 10)
    t_bare = t_run = t_fric = np.inf
    for _ in range(5):                  # interleaved, so that all see the same machine load
        t_bare = min(t_bare, best_of(lambda: bare_loop(Phi, Gamma, K, n_steps), 3))
        t_run = min(t_run, best_of(lambda: run(prog, n_steps), 3))
        t_fric = min(t_fric, best_of(lambda: run(prog_f, n_steps), 3))
    events = run(prog_f, n_steps).events
    print(f"14-state loop, 8 kHz, 2 rates, {len(prog.ops)} ops ({seconds:g} s simulated, CPU time):")
    print(f"  bare_loop           {1e3 * t_bare / seconds:8.3f} ms per simulated s")
    print(f"  run (no friction)   {1e3 * t_run / seconds:8.3f} ms per simulated s  "
          f"({t_run / t_bare:.2f}x bare, incl. discretisation and result arrays)")
    print(f"  run (1 friction)    {1e3 * t_fric / seconds:8.3f} ms per simulated s  "
          f"({t_fric / t_bare:.2f}x bare, {events} stick/slip events)")

    n_var, n_b = 1000, 8000
    variants = [servo(scale=1.0 + 0.2 * i / n_var, n_steps=n_b) for i in range(n_var)]
    run_batch(variants[:2], 10, record_every=8)
    t_batch = best_of(lambda: run_batch(variants, n_b, record_every=8), 2)
    t_bare_b = best_of(lambda: bare_loop(Phi, Gamma, K, n_var * n_b), 2)
    t0 = time.perf_counter()
    res = run_batch(variants, n_b, record_every=8)
    wall = time.perf_counter() - t0
    print(f"batch {n_var} variants x {n_b} steps: {t_batch:.2f} s CPU in total, {wall:.2f} s wall "
          f"({1e6 * t_batch / n_var:.0f} us per variant, Python preparation included); "
          f"bare loop for the same steps {t_bare_b:.2f} s; records {res.records.shape}")


if __name__ == "__main__":
    main()
