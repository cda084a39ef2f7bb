"""Time-series results of simulations: named signals, metrics, pandas/CSV export and plots."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

if TYPE_CHECKING:  # pragma: no cover
    import pandas

__all__ = ["TimeSeries", "StepMetrics", "StepFigures", "step_metrics", "step_figures", "step_figures_many",
           "following_figures_many"]


@dataclass(frozen=True)
class StepMetrics:
    """Figures of merit of a positioning move (metres and seconds, SI)."""

    max_following_error: float
    rms_following_error: float
    final_error: float
    overshoot_percent: float
    rise_time: float | None
    settling_time: float | None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class StepFigures:
    """The figures of one step response (seconds; overshoot in percent of the step)."""

    overshoot_percent: float
    rise_time: float | None
    settling_time: float | None


def step_figures(time: np.ndarray, response: np.ndarray, amplitude: float, *, final: float | None = None,
                 start: float = 0.0, band: float = 0.02) -> StepFigures:
    """Overshoot, rise time and settling time of a step response: the one definition behind
    ``simulate``, ``step`` and ``tune --method time``.

    ``response`` starts from 0 and steps by ``amplitude`` (a commanded distance, or the final value
    of a unit step response); ``final`` is the value it settles to (default ``amplitude``; a move's
    last setpoint). Definitions, with ``σ = sign(amplitude)``:

    * overshoot: ``max(0, max σ·(response − final)) / |amplitude|`` in percent;
    * rise time: from the first crossing of 10 % to the first crossing of 90 % of ``amplitude``,
      each located by linear interpolation between the two samples around it (an error ``O(h²)``
      in the sample spacing ``h``, against ``O(h)`` for the first sample beyond); ``None`` when one
      level is never reached;
    * settling time: the first sample after the last one outside ``band``·|amplitude| of ``final``,
      minus ``start`` (the time the step is commanded); 0 when never outside, ``None`` when still
      outside at the last sample.

    A response that does not settle (an unstable loop) has no figures: its caller says so (see
    :func:`sicomat.tuning.time.velocity_step`). ``amplitude`` must not be 0.

    Examples
    --------
    The sampled first-order lag ``1 − exp(−t)``: rise time ``ln 9`` = 2.1972; 2 % settling at
    ``ln 50`` = 3.9120, i.e. the next sample of the 1 ms grid:

    >>> t = np.linspace(0.0, 10.0, 10001)
    >>> f = step_figures(t, 1 - np.exp(-t), 1.0)
    >>> round(f.rise_time, 6), round(f.settling_time, 3), f.overshoot_percent
    (2.197225, 3.913, 0.0)
    """
    time = np.asarray(time, dtype=float)
    response = np.asarray(response, dtype=float)
    (overshoot,), (settling,) = step_figures_many(time, response[None, :], amplitude, final=final, start=start,
                                                  band=band)
    sign, size = float(np.sign(amplitude)), abs(float(amplitude))
    progress = sign * response / size
    t10 = _first_crossing(time, progress, 0.1)
    t90 = _first_crossing(time, progress, 0.9)
    rise = float(t90 - t10) if t10 is not None and t90 is not None else None
    return StepFigures(float(overshoot), rise, None if np.isnan(settling) else float(settling))


def step_figures_many(time: np.ndarray, responses: np.ndarray, amplitude: float, *, final: float | None = None,
                      start: float = 0.0, band: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Overshoot (percent) and settling time (s) of every row of ``responses`` (shape ``(n_runs,
    len(time))``): :func:`step_figures`'s definitions (it computes them here, for one row), NaN where a row has
    no settling time (still outside the band at its last sample); :func:`step_metrics`'s convention for
    ``amplitude == 0`` (a move that does not end): overshoot 0, no settling time (NaN)."""
    time = np.ascontiguousarray(time, dtype=float)
    responses = np.ascontiguousarray(np.atleast_2d(responses), dtype=float)
    n_runs, n = responses.shape
    if amplitude == 0 or n == 0:
        return np.zeros(n_runs), np.full(n_runs, np.nan)
    target = float(amplitude if final is None else final)
    sign, size = float(np.sign(amplitude)), abs(float(amplitude))
    overshoot, settling = np.empty(n_runs), np.empty(n_runs)
    for v in range(n_runs):
        overshoot[v], settling[v] = _step_row(time, responses[v], target, sign, size, float(start), float(band))
    return overshoot, settling


@njit(cache=True, error_model="numpy")
def _step_row(time, response, target, sign, size, start, band):
    """:func:`step_figures_many` of one row in one pass (compiled: a study's batches have thousands of rows
    of thousands of samples): the overshoot ``max(0, max(sign (r - target)) / size * 100)`` (NaN if a sample
    is NaN, as numpy's max) and the settling time, the sample after the last one outside
    ``|r - target| > band size`` (0 if none is, NaN if the last one is)."""
    n = response.shape[0]
    peak = -np.inf
    nan = False
    limit = band * size
    last = -1
    for i in range(n):
        r = response[i]
        d = sign * (r - target)
        if d != d:
            nan = True
        elif d > peak:
            peak = d
        if abs(r - target) > limit:
            last = i
    overshoot = np.nan if nan else max(0.0, peak / size * 100)
    if last < 0:
        settling = 0.0
    elif last < n - 1:
        settling = time[last + 1] - start
    else:
        settling = np.nan
    return overshoot, settling


def following_figures_many(time: np.ndarray, setpoint: np.ndarray, readings: np.ndarray, gains: np.ndarray,
                           effort: np.ndarray, scale: np.ndarray, amplitude: float, *, start: float = 0.0,
                           band: float = 0.02) -> tuple[np.ndarray, ...]:
    """:func:`step_metrics`' figures of many runs of one move, from each run's position readings:

    ``error = setpoint - readings[v] / gains[v]`` (the following error, ``readings`` in sensor units), its
    maximum magnitude, RMS and last value, the overshoot and settling time of ``setpoint - error`` against
    the final setpoint (as :func:`step_figures_many`), and the peak effort ``scale[v] max |effort[v]|``.
    One compiled pass per run, no array of the batch's size beside the inputs (the numpy expressions
    took 0.6 ms per run of 8000 samples, as long as preparing the run). The RMS sums the squares in
    four partial sums (numpy's mean sums pairwise: the two agree to ``n eps / 4`` relative, 2e-13 for
    8000 samples). Returns ``max_error, rms_error, final_error, overshoot_percent, settling_time,
    max_effort``, each of shape ``(n_runs,)``."""
    setpoint = np.ascontiguousarray(setpoint, dtype=float)
    readings = np.asarray(readings, dtype=float)    # views of the kernel's records: strided, not copied
    effort = np.asarray(effort, dtype=float)
    n_runs = readings.shape[0]
    out = np.empty((6, n_runs))
    sign, size = float(np.sign(amplitude)), abs(float(amplitude))
    _following_rows(np.ascontiguousarray(time, dtype=float), setpoint, readings,
                    np.ascontiguousarray(gains, dtype=float), effort, np.ascontiguousarray(scale, dtype=float),
                    float(setpoint[-1]), sign, size, float(start), float(band), amplitude != 0, out)
    return tuple(out)


@njit(cache=True, error_model="numpy")
def _following_rows(time, setpoint, readings, gains, effort, scale, target, sign, size, start, band, moves, out):
    """The rows of :func:`following_figures_many` into ``out`` (shape ``(6, n_runs)``)."""
    n = setpoint.shape[0]
    actual = np.empty(n)
    for v in range(readings.shape[0]):
        g = gains[v]
        peak = 0.0
        s0 = s1 = s2 = s3 = 0.0
        nan = False
        e = 0.0
        for i in range(n):
            e = setpoint[i] - readings[v, i] / g
            a = abs(e)
            if a != a:
                nan = True
            elif a > peak:
                peak = a
            q = e * e
            k = i & 3
            if k == 0:
                s0 += q
            elif k == 1:
                s1 += q
            elif k == 2:
                s2 += q
            else:
                s3 += q
            actual[i] = setpoint[i] - e
        out[0, v] = np.nan if nan else peak
        out[1, v] = np.sqrt(((s0 + s1) + (s2 + s3)) / n)
        out[2, v] = e
        if moves:
            out[3, v], out[4, v] = _step_row(time, actual, target, sign, size, start, band)
        else:
            out[3, v], out[4, v] = 0.0, np.nan
        top = 0.0
        nan = False
        for i in range(n):
            a = abs(effort[v, i])
            if a != a:
                nan = True
            elif a > top:
                top = a
        out[5, v] = scale[v] * (np.nan if nan else top)


def step_metrics(time: np.ndarray, setpoint: np.ndarray, actual: np.ndarray, distance: float,
                 start: float = 0.0, band: float = 0.02) -> StepMetrics:
    """Following error and step-response figures.

    ``setpoint`` and ``actual`` are the desired and measured axis positions at ``time``; ``distance``
    the commanded displacement (0 for moves that do not end, e.g. ramps: no overshoot, rise or
    settling). The step figures are :func:`step_figures` of ``actual`` with the final setpoint as
    final value: rise time 10 %→90 % of ``distance``, settling time after ``start`` within
    ``band``·|distance| of the final setpoint.
    """
    error = setpoint - actual
    metrics: dict[str, Any] = dict(max_following_error=float(np.max(np.abs(error))),
                   rms_following_error=float(np.sqrt(np.mean(error ** 2))),
                   final_error=float(error[-1]), overshoot_percent=0.0, rise_time=None, settling_time=None)
    if distance != 0:
        figures = step_figures(time, actual, distance, final=setpoint[-1], start=start, band=band)
        metrics.update(figures.__dict__)
    return StepMetrics(**metrics)


def _first_crossing(time: np.ndarray, values: np.ndarray, level: float) -> float | None:
    above = np.flatnonzero(values >= level)
    if above.size == 0:
        return None
    i = above[0]
    if i == 0:
        return float(time[0])
    t0, t1, v0, v1 = time[i - 1], time[i], values[i - 1], values[i]
    return float(t0 + (level - v0) / (v1 - v0) * (t1 - t0)) if v1 != v0 else float(t1)


@dataclass(frozen=True, eq=False)
class TimeSeries:
    """Signals sampled at the simulator's base step, by name (SI units), with the run's metrics.

    Signal names: ``setpoint.position`` / ``.velocity`` / ``.acceleration`` (as the position loop
    samples them), ``setpoint.fine`` (at the base step), ``position.measured``, ``position.error``,
    ``following_error``, ``tool_error``, ``velocity.command``, ``velocity.measured``,
    ``velocity.error``, ``velocity.integral`` (the PI's integral action, N or N·m),
    ``current.command`` / ``.applied`` / ``.lower`` / ``.upper``, ``effort.command``,
    ``drive.current``, ``drive.effort``, ``tool.position``, every dof's ``<body>.x`` / ``<body>.v``
    (or ``.theta`` / ``.omega``), ``sensor.<name>``, ``friction.<name>``.
    """

    time: np.ndarray
    signals: dict[str, np.ndarray]
    metrics: StepMetrics | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.signals[name]

    @property
    def names(self) -> list[str]:
        """Signal names, in recording order."""
        return list(self.signals)

    def to_pandas(self) -> "pandas.DataFrame":
        """A DataFrame indexed by time (s), one column per signal."""
        import pandas as pd

        frame = pd.DataFrame(self.signals, index=pd.Index(self.time, name="time"))
        return frame

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write the signals as CSV (atomically: temporary file, then rename)."""
        from ..io.csv import write_frame_csv

        return write_frame_csv(self.to_pandas(), path)

    def plot(self, signals: list[str] | None = None):
        """Setpoint and position, following error, and effort against time; returns the Figure."""
        from ..plots.time import plot_timeseries

        return plot_timeseries(self, signals)
