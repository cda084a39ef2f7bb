"""Batches of variants: each variant's results do not depend on the batch or on the threads, and the
batch's per-variant figures are simulate()'s."""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import pytest
from numpy.testing import assert_array_equal

import sicomat
from sicomat.errors import ModelError
from sicomat.motion.setpoints import profile_from_spec, step_profile
from sicomat.servo.loop import build_servo_loop
from sicomat.simulation import loop_programs, simulate, simulate_batch
from sicomat.simulation.kernel import batch_threads, run, run_batch
from sicomat.simulation.timeseries import step_figures, step_figures_many

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "paper_5m4s.toml"


@pytest.fixture(scope="module")
def case():
    """The paper's 5M4S axis (stick-slip friction, limits, quantizer, two rates) and gain/mass variants."""
    machine = sicomat.load_model(EXAMPLE)
    loop = build_servo_loop(machine)
    profile = profile_from_spec(machine.axes[loop.axis].trajectory)
    # position gain x1 .. x3 and velocity gain x0.5, x1.2: no overshoot to 19 %, settled or not within 0.3 s
    loops = [loop.with_gains(Kv=loop.Kv * f, Kp=loop.Kp * g) for f in (1.0, 1.5, 2.0, 3.0) for g in (0.5, 1.2)]
    return machine, loop, profile, loops


def _programs(loops, profile, duration=0.3, nonlinear=True):
    return loop_programs(loops, profile, duration, nonlinear=nonlinear)


def test_a_variant_is_bit_identical_alone_in_a_batch_and_on_any_thread_count(case):
    _, _, profile, loops = case
    programs, n = _programs(loops, profile)
    record = ["sensor.scale", "current.command", "friction.motor"]
    one = run_batch(programs, n, record=record, threads=1)
    two = run_batch(programs, n, record=record, threads=2)
    # the same compiled code on the same numbers: bit for bit, not within a tolerance
    assert_array_equal(one.records, two.records)
    assert_array_equal(one.final_states, two.final_states)
    assert_array_equal(one.diverged_step, two.diverged_step)
    # each variant alone, in a batch of one, and through run() with every slot recorded
    for v in (0, 3, 7):
        alone = run_batch([programs[v]], n, record=record, threads=2)
        assert_array_equal(alone.records[0], one.records[v])
        assert_array_equal(alone.final_states[0], one.final_states[v])
        single = run(programs[v], n)
        cols = [programs[v].slot_names.index(name) for name in record]
        assert_array_equal(single.records[:, cols], one.records[v])
        assert_array_equal(single.final_state, one.final_states[v])
    # another batch composition (other neighbours, another order, repeated variants): the same rows
    order = [5, 0, 5, 2]
    mixed = run_batch([programs[v] for v in order], n, record=record, threads=2)
    for row, v in enumerate(order):
        assert_array_equal(mixed.records[row], one.records[v])
    # the variants really differ and stick/slip really happens (the event machinery is exercised)
    assert len({float(r[-1, 0]) for r in one.records}) == len(programs)
    assert run(programs[0], n).stuck.any()


def test_the_thread_count_follows_numba_and_is_checked(case):
    _, _, profile, loops = case
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)               # as a Dask worker does
        assert batch_threads() == 1
        programs, n = _programs(loops[:3], profile, 0.05)
        serial = run_batch(programs, n, record=["sensor.scale"])
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        assert batch_threads() == numba.config.NUMBA_NUM_THREADS
        assert_array_equal(run_batch(programs, n, record=["sensor.scale"]).records, serial.records)
    finally:
        numba.set_num_threads(before)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ModelError, match="threads"):
            run_batch(programs, n, threads=bad)


def test_batch_metrics_are_simulates_variant_by_variant(case):
    _, _, profile, loops = case
    duration = 0.3
    batch = simulate_batch(loops, profile, duration)
    assert not batch.diverged.any()
    serial = simulate_batch(loops, profile, duration, threads=1)
    for name in ("max_following_error", "overshoot_percent", "settling_time", "max_effort"):
        assert_array_equal(getattr(serial, name), getattr(batch, name))
    settled = 0
    for v, loop in enumerate(loops):
        series = simulate(loop, profile, duration)
        m = series.metrics
        # the following error: simulate() reads the sensor from the states (numpy's product), the batch from
        # the kernel's output slot (the kernel's sum); the scale's row is one coefficient, so both are exact
        # to the last bit here, but 1e-12 allows another summation order
        assert batch.max_following_error[v] == pytest.approx(m.max_following_error, rel=1e-12)
        assert batch.overshoot_percent[v] == pytest.approx(m.overshoot_percent, rel=1e-12, abs=1e-12)
        # the settling time is a sample time: it moves only if a sample lies within rounding (1e-12 of the
        # move) of the band's edge, which the margin below rules out for these runs
        actual = series["setpoint.fine"] - series["following_error"]
        margin = np.min(np.abs(np.abs(actual - series["setpoint.fine"][-1]) - 0.02 * abs(profile.distance)))
        assert margin > 1e-12 * abs(profile.distance)
        if m.settling_time is None:
            assert np.isnan(batch.settling_time[v])
        else:
            settled += 1
            assert batch.settling_time[v] == m.settling_time
        # the peak effort: kt times the applied current, as simulate() records it
        peak = loop.drive.kt * np.max(np.abs(series["current.applied"]))
        assert batch.max_effort[v] == pytest.approx(peak, rel=1e-15)
    # the figures are really compared: settled and unsettled runs, overshoots from none to several percent
    assert settled >= 2 and np.isnan(batch.settling_time).any()
    assert np.min(batch.overshoot_percent) == 0.0 and np.max(batch.overshoot_percent) > 5.0
    frame = batch.to_pandas()
    assert {"overshoot_percent", "settling_time", "max_effort"} <= set(frame.columns)
    assert len(frame) == len(loops)


def test_the_batch_limit_cycle_is_simulates_check_variant_by_variant(case):
    """``BatchMetrics.limit_cycle`` is ``sicomat simulate``'s saturation-bound limit-cycle check
    (``limit_cycle_warning``) on each variant's run: with the position gain x1000 the drive's current limits hold
    the unstable loop in a bounded oscillation, with x1 and x3 the loop settles."""
    from sicomat.simulation.checks import limit_cycle_warning

    _, loop, profile, _ = case
    loops = [loop.with_gains(Kp=loop.Kp * g) for g in (1.0, 1000.0, 3.0, 2000.0)]
    batch = simulate_batch(loops, profile, 0.3)
    assert not batch.diverged.any()
    one_by_one = [limit_cycle_warning(simulate(lp, profile, 0.3)) is not None for lp in loops]
    assert list(batch.limit_cycle) == one_by_one == [False, True, False, True]
    assert list(batch.to_pandas()["limit_cycle"]) == one_by_one
    linear = simulate_batch(loops, profile, 0.3, nonlinear=False)   # no current limits simulated: no check
    assert not linear.limit_cycle.any()


def test_step_figures_many_row_by_row_equals_step_figures():
    # rows that settle, overshoot, never leave the band and never settle; a negative move
    t = np.linspace(0.0, 1.0, 1001)
    rows = np.array([1.0 - np.exp(-8 * t), 1.0 - np.exp(-6 * t) * np.cos(20 * t), np.full_like(t, 1.0),
                     1.0 - np.exp(-0.5 * t)])
    for amplitude, responses in ((1.0, rows), (-1.0, -rows)):
        overshoot, settling = step_figures_many(t, responses, amplitude, start=0.1)
        for i, response in enumerate(responses):
            ref = step_figures(t, response, amplitude, start=0.1)
            assert overshoot[i] == ref.overshoot_percent
            if ref.settling_time is None:
                assert np.isnan(settling[i])
            else:
                assert settling[i] == ref.settling_time
    # a move that does not end (distance 0): no overshoot, no settling time, as step_metrics says
    overshoot, settling = step_figures_many(t, rows, 0.0)
    assert np.all(overshoot == 0.0) and np.all(np.isnan(settling))


def test_following_figures_many_are_the_numpy_definitions():
    # the compiled pass against numpy written out from step_metrics' definitions: readings in sensor units
    # (gain 1e4 per metre), a settling, a ringing, an unsettled and a NaN run, both move directions
    from sicomat.simulation.timeseries import following_figures_many

    t = np.linspace(0.0, 0.5, 4001)
    gains = np.array([1e4, 2e4, 5e3, 1e4])
    for distance in (0.01, -0.01):
        setpoint = distance * np.minimum(t / 0.1, 1.0)
        errors = distance * np.array([np.exp(-30 * t), np.exp(-20 * t) * np.cos(60 * t), 0.5 * np.exp(-t),
                                      np.exp(-30 * t)])
        readings = (setpoint - errors) * gains[:, None]
        effort = np.sin(np.outer([1.0, 2.0, 3.0, 4.0], t)) * np.array([[3.0], [-2.0], [1.0], [5.0]])
        readings[3, 100] = np.nan
        kt = np.array([1.5, 2.0, 0.5, 1.0])
        got = following_figures_many(t, setpoint, readings, gains, effort, kt, distance, start=0.0)
        error = setpoint[None, :] - readings / gains[:, None]
        overshoot, settling = step_figures_many(t, setpoint[None, :] - error, distance, final=setpoint[-1])
        with np.errstate(invalid="ignore"):
            want = [np.max(np.abs(error), axis=1), np.sqrt(np.mean(error ** 2, axis=1)), error[:, -1], overshoot,
                    settling, kt * np.max(np.abs(effort), axis=1)]
        for name, g, w in zip(("max", "rms", "final", "overshoot", "settling", "effort"), got, want):
            # RMS: four partial sums against numpy's pairwise sum, n eps / 4 relative (see the function);
            # every run, the NaN one included (NaN where numpy gives NaN)
            rtol = 4001 * np.finfo(float).eps / 4 if name == "rms" else 0.0
            np.testing.assert_allclose(g, w, rtol=rtol, atol=0.0, err_msg=name)
        assert np.isnan(got[4][2])                   # still outside the band at its last sample
        assert got[3][1] > 0.0 and got[3][0] == 0.0  # the ringing run overshoots, the settling one does not
    still = following_figures_many(t, np.zeros_like(t), readings[:2] * 0.0, gains[:2], effort[:2], kt[:2], 0.0)
    assert np.all(still[3] == 0.0) and np.all(np.isnan(still[4]))


def test_diverged_variants_have_nan_figures(case):
    _, loop, _, _ = case
    # 60x the velocity gain: the linear loop is unstable (the nonlinear one would only ring at its current limit)
    loops = [loop, loop.with_gains(Kp=loop.Kp * 60.0)]
    batch = simulate_batch(loops, step_profile(1e-4), 0.05, nonlinear=False)
    assert list(batch.diverged) == [False, True]
    for name in ("max_following_error", "overshoot_percent", "settling_time", "max_effort"):
        values = getattr(batch, name)
        assert np.isfinite(values[0]) or name == "settling_time"
        assert np.isnan(values[1])


def test_a_batch_prepared_in_pieces_gives_each_variant_its_own_results(case):
    from sicomat.simulation import kernel

    _, loop, profile, _ = case
    factors = np.linspace(0.7, 1.3, 3 * kernel.MIN_PIECE + 5)      # several pieces, the last one short
    loops = [loop.with_gains(Kp=loop.Kp * f) for f in factors]
    programs, n = _programs(loops, profile, 0.06)
    assert kernel._piece_size(len(programs), 2) < len(programs)      # really pipelined
    piecewise = run_batch(programs, n, record=["sensor.scale", "current.command"], threads=2)
    whole = run_batch(programs, n, record=["sensor.scale", "current.command"], threads=1)
    assert_array_equal(piecewise.records, whole.records)
    assert_array_equal(piecewise.final_states, whole.final_states)
    for v in (0, kernel.MIN_PIECE, len(programs) - 1):
        assert_array_equal(run_batch([programs[v]], n, record=["sensor.scale", "current.command"]).records[0],
                           piecewise.records[v])
    # a variant of another structure in a later piece: the batch is refused, as a whole
    other, _ = _programs([loop], step_profile(1e-4), 0.06, nonlinear=False)
    with pytest.raises(ModelError, match=f"variant {len(programs) - 1} does not have the structure"):
        run_batch(programs[:-1] + other, n, threads=2)


def test_batches_run_at_once_from_several_threads_are_independent(case):
    # as in a threaded Dask worker: concurrent run_batch calls, each on its own threads
    from concurrent.futures import ThreadPoolExecutor

    _, _, profile, loops = case
    programs, n = _programs(loops, profile, 0.05)
    alone = run_batch(programs, n, record=["sensor.scale"], threads=1)
    with ThreadPoolExecutor(max_workers=3) as pool:
        results = list(pool.map(lambda k: run_batch(programs[k:] + programs[:k], n, record=["sensor.scale"],
                                                    threads=2), range(3)))
    for k, res in enumerate(results):
        assert_array_equal(res.records, np.roll(alone.records, -k, axis=0))
