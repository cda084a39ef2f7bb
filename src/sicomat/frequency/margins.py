"""Stability margins of a loop gain known on a frequency grid: gain, phase, delay and modulus margins,
all their crossovers, and the −3 dB bandwidth of the closed loop (paper III.B, IV.C).

Conventions (one place; also in the docstrings below)
-----------------------------------------------------
* The loop is closed by **negative feedback**: the characteristic function is ``1 + L``, the
  critical point ``L = −1``; ``T = L/(1 + L)``, ``S = 1/(1 + L)``.
* ``L`` is only known on the grid (it may come from a sampled loop): there are no analytic poles.
  Crossovers are located between grid points by interpolation in ``ln ω`` of ``20 log10|L|`` and of
  the unwrapped phase: a linear estimate, refined by the local cubic through the four nearest grid
  points (kept only when it agrees with the linear one). Crossovers outside the grid are not seen.
* **Gain crossover**: ``|L| = 1``. **Phase crossover**: the unwrapped phase equals ``−180° + k·360°``
  (``L`` on the negative real axis).
* **Phase margin** at a gain crossover: ``PM = 180° + ∠L`` wrapped into ``(−180°, 180°]``. The
  reported one is the *worst*: the closest to the critical point, i.e. the smallest ``|PM|`` (on a
  tie the negative one, then the lowest frequency); with only positive margins it is simply the
  smallest (as python-control).
* **Gain margin** at a phase crossover: ``GM = −20 log10|L|`` (dB), positive when ``|L| < 1`` there.
  The reported one is the smallest in absolute value (as python-control; ties as for the PM).
  ``inf`` with no phase crossover on the grid.
* **Delay margin** at a gain crossover: the smallest added delay that puts ``L`` on ``−1`` there,
  ``(PM mod 360°)·π/180 / ω_c`` (never negative, as MATLAB's ``allmargin``; it equals ``PM/ω_c``
  whenever ``PM ≥ 0``); the reported one is the minimum over all gain crossovers (``inf`` with none).
  For a sampled loop it is also given in sample periods.
* **Modulus margin**: ``min |1 + L| = 1/max|S|`` over the grid (refined between the grid points
  next to the minimum with the local cubics of Re L and Im L) and the frequency where it occurs.
* **Bandwidth** (:func:`closed_loop_bandwidth`, the one definition used by ``margins``, ``bode`` and
  ``tune``): the first frequency where ``|T|`` falls below ``|T(0)|/√2`` (3.0103 dB below the exact
  static gain); ``inf`` when ``|T|`` stays above that level over the whole grid, ``nan`` when it is
  already below at the lowest grid frequency or when ``T(0)`` is 0 or infinite. The static gain is
  exact when known: given to :func:`stability_margins`, or carried by the loop gain in
  ``frf.info["closed_loop_static_gain"]`` (every loop gain of :mod:`sicomat.frequency.loops` does); a bare
  grid response falls back to ``|T(ω_min)|`` (``static_gain_exact`` is then false).
* A **sampled loop** (``sample_period`` set) has a real response at the Nyquist frequency ``π/T``:
  when the grid ends near it (≥ 0.95 π/T) and the phase extrapolated to ``π/T`` is an odd multiple of
  180° (within 15°), a phase crossover at ``π/T`` is added (the Nyquist plot closes on the negative
  real axis there), and the modulus margin may occur at ``π/T``; values at ``π/T`` are extrapolated
  using the symmetry of ``L(e^{jωT})`` about it (|L| even, phase odd).
* Missing values: ``inf`` for a margin without its crossover, ``nan`` for its frequency; in
  :meth:`Margins.to_dict` both become ``None`` (JSON has neither).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ModelError
from ..lti.response import FrequencyResponse

if TYPE_CHECKING:  # pragma: no cover
    import pandas
    from matplotlib.figure import Figure

__all__ = ["Margins", "stability_margins", "closed_loop", "sensitivity", "closed_loop_bandwidth",
           "margins_warnings"]

_MINUS_3DB = 20.0 * np.log10(np.sqrt(0.5))     # −3.0103 dB
_NYQUIST_REACH = 0.95                          # grid must end above this fraction of π/T
_NYQUIST_PHASE_TOL_DEG = 15.0


@dataclass(frozen=True, eq=False)
class Margins:
    """Result of :func:`stability_margins` (see the module docstring for the conventions).

    Attributes
    ----------
    gain_margin_db : float
        Reported gain margin (dB): the one with the smallest ``|GM|``; positive when ``|L| < 1`` at
        its phase crossover; ``inf`` without phase crossover.
    phase_margin_deg : float
        Reported (worst) phase margin (deg) in ``(−180, 180]``: smallest ``|PM|``; ``inf`` without
        gain crossover.
    gain_crossover_rad_s : float
        Gain crossover of the reported phase margin (rad/s); ``nan`` if none.
    phase_crossover_rad_s : float
        Phase crossover of the reported gain margin (rad/s); ``nan`` if none.
    delay_margin_s : float
        Smallest delay margin over all gain crossovers (s); ``inf`` if none.
    delay_margin_samples : float
        ``delay_margin_s / sample_period`` for a sampled loop; ``nan`` for a continuous one.
    modulus_margin : float
        ``min |1 + L| = 1/max|S|`` on the grid.
    modulus_margin_rad_s : float
        Where it occurs (rad/s).
    bandwidth_rad_s : float
        −3 dB bandwidth of ``T = L/(1+L)`` relative to its static gain (rad/s), see
        :func:`closed_loop_bandwidth`; ``inf`` if not reached on the grid.
    gain_crossovers : ndarray, shape (n_g,)
        All gain crossovers (rad/s), ascending.
    phase_crossovers : ndarray, shape (n_p,)
        All phase crossovers (rad/s), ascending.
    phase_margins_deg : ndarray, shape (n_g,)
        Phase margin at each gain crossover (deg), in ``(−180, 180]``.
    gain_margins_db : ndarray, shape (n_p,)
        Gain margin at each phase crossover (dB).
    delay_margins_s : ndarray, shape (n_g,)
        Delay margin at each gain crossover (s), ``≥ 0``.
    sample_period : float or None
        The loop's period (s) for a sampled loop.
    frf : FrequencyResponse
        The loop gain the margins were computed from (for :meth:`plot`).
    closed_loop_static_gain : float
        ``|T(0)|``, the reference of the bandwidth.
    static_gain_exact : bool
        True when that is the exact static gain (given or carried by ``frf.info``); False when it
        is ``|T(ω_min)|`` at the lowest grid frequency of a bare response.
    """

    gain_margin_db: float
    phase_margin_deg: float
    gain_crossover_rad_s: float
    phase_crossover_rad_s: float
    delay_margin_s: float
    delay_margin_samples: float
    modulus_margin: float
    modulus_margin_rad_s: float
    bandwidth_rad_s: float
    gain_crossovers: np.ndarray
    phase_crossovers: np.ndarray
    phase_margins_deg: np.ndarray
    gain_margins_db: np.ndarray
    delay_margins_s: np.ndarray
    sample_period: float | None
    frf: FrequencyResponse
    closed_loop_static_gain: float = float("nan")
    static_gain_exact: bool = False

    @property
    def name(self) -> str:
        """Name of the loop gain."""
        return self.frf.name

    @property
    def stable_hint(self) -> bool:
        """True when the reported gain, phase and modulus margins are all positive.

        A hint, not a proof: it assumes an open loop without unstable poles and says nothing about
        crossovers outside the grid; a conditionally stable loop may have a negative gain margin.
        **Deprecated** as a verdict (kept in :meth:`to_dict` for old readers): the stability of a
        servo loop is :func:`sicomat.servo.stability.loop_verdict`, from the closed loop's poles.
        """
        return bool(self.gain_margin_db > 0 and self.phase_margin_deg > 0 and self.modulus_margin > 0)

    @property
    def gain_crossover_hz(self) -> float:
        """:attr:`gain_crossover_rad_s` in Hz."""
        return self.gain_crossover_rad_s / (2 * np.pi)

    @property
    def phase_crossover_hz(self) -> float:
        """:attr:`phase_crossover_rad_s` in Hz."""
        return self.phase_crossover_rad_s / (2 * np.pi)

    @property
    def bandwidth_hz(self) -> float:
        """:attr:`bandwidth_rad_s` in Hz."""
        return self.bandwidth_rad_s / (2 * np.pi)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping; ``inf`` and ``nan`` (no such crossover, not defined) become ``None``."""
        scalars = ("gain_margin_db", "phase_margin_deg", "gain_crossover_rad_s", "phase_crossover_rad_s",
                   "delay_margin_s", "delay_margin_samples", "modulus_margin", "modulus_margin_rad_s",
                   "bandwidth_rad_s", "closed_loop_static_gain")
        out: dict[str, Any] = {"name": self.name, "sample_period": self.sample_period,
                               "stable_hint": self.stable_hint, "static_gain_exact": self.static_gain_exact}
        out.update({key: _json_float(getattr(self, key)) for key in scalars})
        for key in ("gain_crossovers", "phase_crossovers", "phase_margins_deg", "gain_margins_db",
                    "delay_margins_s"):
            out[key] = [_json_float(v) for v in getattr(self, key)]
        return out

    def to_pandas(self) -> "pandas.DataFrame":
        """All crossovers, one row each, ascending in frequency.

        Columns: ``kind`` (``"gain"`` or ``"phase"``), ``omega`` (rad/s), ``frequency_hz``,
        ``phase_margin_deg`` and ``delay_margin_s`` (gain crossovers), ``gain_margin_db`` (phase
        crossovers), ``reported`` (True for the crossover of the reported PM or GM).
        """
        import pandas as pd

        n_g, n_p = self.gain_crossovers.size, self.phase_crossovers.size
        nan_g, nan_p = np.full(n_g, np.nan), np.full(n_p, np.nan)
        frame = pd.DataFrame({
            "kind": ["gain"] * n_g + ["phase"] * n_p,
            "omega": np.concatenate([self.gain_crossovers, self.phase_crossovers]),
            "phase_margin_deg": np.concatenate([self.phase_margins_deg, nan_p]),
            "delay_margin_s": np.concatenate([self.delay_margins_s, nan_p]),
            "gain_margin_db": np.concatenate([nan_g, self.gain_margins_db]),
            "reported": np.concatenate([self.gain_crossovers == self.gain_crossover_rad_s,
                                        self.phase_crossovers == self.phase_crossover_rad_s]),
        })
        frame.insert(2, "frequency_hz", frame["omega"] / (2 * np.pi))
        return frame.sort_values("omega", kind="stable").reset_index(drop=True)

    def plot(self, kind: str = "bode") -> "Figure":
        """Bode (``kind="bode"``) or Nichols (``kind="nichols"``) figure of the loop with the margins."""
        from ..plots.frequency import bode_figure, nichols_figure

        if kind == "bode":
            return bode_figure([self.frf], margins=[self])
        if kind == "nichols":
            return nichols_figure([self.frf], margins=[self])
        raise ModelError(f"unknown plot kind {kind!r}; expected 'bode' or 'nichols'")


def stability_margins(frf: FrequencyResponse, *, closed_loop_static_gain: float | None = None) -> Margins:
    """Gain, phase, delay and modulus margins of a negative-feedback loop gain ``L`` on a grid.

    Parameters
    ----------
    frf : FrequencyResponse
        The loop gain ``L(jω)`` (or ``L(e^{jωT})`` for a sampled loop, ``sample_period`` set) on an
        ascending grid of at least two positive frequencies (rad/s). It is taken as a loop gain
        whatever its ``open_loop`` flag.
    closed_loop_static_gain : float, optional
        The exact ``T(0)`` of ``T = L/(1+L)`` (1 for a loop with an integrator), the reference of
        the bandwidth. Default: ``frf.info["closed_loop_static_gain"]`` (set by
        :meth:`sicomat.frequency.loops.LoopAnalysis.response`), else ``|T|`` at the lowest grid frequency.

    Returns
    -------
    Margins
        All crossovers and the margins at each, the reported (worst) ones, the delay and modulus
        margins and the −3 dB bandwidth of ``T = L/(1+L)``; conventions in the module docstring.

    Raises
    ------
    ModelError
        If the grid is not 1-D, ascending and positive, or the response is not finite or not of
        the grid's shape.

    Examples
    --------
    ``L = 2/(s(s+1)(s+2))``: phase crossover at √2 rad/s where ``|L| = 2/6``, so GM = 20 log10 3:

    >>> import numpy as np
    >>> from sicomat.lti.response import FrequencyResponse
    >>> w = np.logspace(-2, 2, 2000)
    >>> s = 1j * w
    >>> m = stability_margins(FrequencyResponse(w, 2 / (s * (s + 1) * (s + 2)), open_loop=True))
    >>> round(m.gain_margin_db, 3), round(m.phase_crossover_rad_s, 4), m.stable_hint
    (9.542, 1.4142, True)
    """
    omega, resp = _validated(frf)
    x = np.log(omega)
    with np.errstate(divide="ignore"):
        gain_db = 20.0 * np.log10(np.abs(resp))
    phase = np.asarray(frf.phase_deg, dtype=float)
    period = frf.sample_period
    nyquist = _nyquist_reach(omega, period)

    # gain crossovers: 20 log10|L| = 0
    idx, t = _crossings(gain_db, np.zeros(gain_db.size - 1))
    xg = np.array([_root(x, gain_db, i, ti, 0.0) for i, ti in zip(idx, t)])
    pg = np.array([_value(x, phase, i, xc) for i, xc in zip(idx, xg)])
    xg, pg = _dedupe(xg, pg)
    wg = np.exp(xg)
    pm = _wrap180(180.0 + pg)
    dm = np.radians(np.mod(pm, 360.0)) / wg if wg.size else np.zeros(0)

    # phase crossovers: unwrapped phase = −180 + 360 k (the level nearest each interval's midpoint)
    mid = 0.5 * (phase[:-1] + phase[1:])
    levels = -180.0 + 360.0 * np.round((mid + 180.0) / 360.0)
    idx, t = _crossings(phase, levels)
    xp = np.array([_root(x, phase, i, ti, levels[i]) for i, ti in zip(idx, t)])
    dp = np.array([_value(x, gain_db, i, xc) for i, xc in zip(idx, xp)])
    xp, dp = _dedupe(xp, dp)
    wp = np.exp(xp)
    if nyquist is not None and not (wp.size and wp[-1] >= omega[-2]):
        phase_n = _odd_extrapolation(omega[-2:], phase[-2:], nyquist)
        k = np.round(phase_n / 180.0)
        if int(k) % 2 and abs(phase_n - 180.0 * k) <= _NYQUIST_PHASE_TOL_DEG:
            wp = np.append(wp, nyquist)
            dp = np.append(dp, _even_extrapolation(omega[-2:], gain_db[-2:], nyquist))
    gm = -dp

    # reported values
    if pm.size:
        j = _closest_to_zero(pm)
        pm_worst, wg_worst = float(pm[j]), float(wg[j])
        dm_min = float(dm.min())
    else:
        pm_worst, wg_worst, dm_min = np.inf, np.nan, np.inf
    if gm.size:
        j = _closest_to_zero(gm)
        gm_rep, wp_rep = float(gm[j]), float(wp[j])
    else:
        gm_rep, wp_rep = np.inf, np.nan

    mm, w_mm = _modulus_margin(x, omega, resp, nyquist)
    T = closed_loop(frf)
    if closed_loop_static_gain is None:
        closed_loop_static_gain = frf.info.get("closed_loop_static_gain")
    exact = closed_loop_static_gain is not None
    static = abs(complex(closed_loop_static_gain)) if closed_loop_static_gain is not None else float(np.abs(T.response[0]))
    bandwidth = closed_loop_bandwidth(T, static)
    return Margins(
        gain_margin_db=gm_rep, phase_margin_deg=pm_worst,
        gain_crossover_rad_s=wg_worst, phase_crossover_rad_s=wp_rep,
        delay_margin_s=dm_min,
        delay_margin_samples=dm_min / period if period else np.nan,
        modulus_margin=mm, modulus_margin_rad_s=w_mm, bandwidth_rad_s=bandwidth,
        gain_crossovers=_frozen(wg), phase_crossovers=_frozen(wp), phase_margins_deg=_frozen(pm),
        gain_margins_db=_frozen(gm), delay_margins_s=_frozen(dm), sample_period=period, frf=frf,
        closed_loop_static_gain=static, static_gain_exact=exact)


def closed_loop_bandwidth(frf: FrequencyResponse, static_gain: float) -> float:
    """The −3 dB bandwidth (rad/s) of a closed loop ``T`` known on a grid, relative to its exact
    static gain: the one definition behind ``margins``, ``bode`` and ``tune``.

    Definition: the **first** frequency where ``|T(jω)|`` falls below ``|T(0)|/√2``, i.e. 3.0103 dB
    below the static gain (a resonance peak above the static gain before it does not matter; a
    later dip after a first crossing neither). Located on the first grid interval where
    ``20 log10|T|`` goes from at or above that level to below it, by interpolation in ``ln ω``: the
    linear estimate, refined by the root of the local cubic through the four nearest grid points
    when that root lies in the interval (the crossovers' rule, see the module docstring). The error
    of that cubic is ``O(h⁴)`` in the grid step ``h`` of ``ln ω``.

    Parameters
    ----------
    frf : FrequencyResponse
        The closed loop ``T`` (e.g. :func:`closed_loop` of a loop gain) on an ascending grid of
        positive frequencies, at least two points.
    static_gain : float
        ``T(0)``, exactly (see :meth:`sicomat.frequency.loops.LoopAnalysis.closed_loop_static_gain`); only
        its modulus is used.

    Returns
    -------
    float
        The bandwidth (rad/s); ``inf`` when ``|T|`` stays at or above the level over the whole grid;
        ``nan`` when it is already below at the lowest grid frequency (the crossing lies below
        the grid) or when the static gain is 0 or not finite.

    Examples
    --------
    ``T = 10/(s + 10)``: ``|T(0)| = 1``, −3 dB at 10 rad/s:

    >>> import numpy as np
    >>> w = np.logspace(-1, 3, 400)
    >>> round(closed_loop_bandwidth(FrequencyResponse(w, 10 / (1j * w + 10)), 1.0), 6)
    10.0
    """
    omega, resp = _validated(frf, finite=False)
    static = abs(complex(static_gain))
    if not np.isfinite(static) or static == 0.0:
        return np.nan
    with np.errstate(divide="ignore"):
        t_db = 20.0 * np.log10(np.abs(resp))
    level = 20.0 * np.log10(static) + _MINUS_3DB
    if t_db[0] < level:
        return np.nan
    idx, t = _crossings(t_db, np.full(t_db.size - 1, level))
    down = t_db[idx] >= level
    idx, t = idx[down], t[down]
    if not idx.size:
        return np.inf
    return float(np.exp(_root(np.log(omega), t_db, int(idx[0]), float(t[0]), level)))


def closed_loop(frf: FrequencyResponse) -> FrequencyResponse:
    """The complementary sensitivity ``T = L/(1 + L)`` of a negative-feedback loop gain ``L``.

    Parameters
    ----------
    frf : FrequencyResponse
        The loop gain ``L`` on its grid.

    Returns
    -------
    FrequencyResponse
        ``T`` on the same grid, same ``sample_period``, ``open_loop=False``, named ``"<name> T"``.

    Examples
    --------
    >>> import numpy as np
    >>> w = np.array([1.0, 10.0, 100.0])
    >>> T = closed_loop(FrequencyResponse(w, 10.0 / (1j * w), open_loop=True))
    >>> np.round(np.abs(T.response), 4).tolist()    # 10/(jω + 10)
    [0.995, 0.7071, 0.0995]
    """
    resp = np.asarray(frf.response, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        T = resp / (1.0 + resp)
    return FrequencyResponse(np.asarray(frf.omega, dtype=float), T, _derived_name(frf.name, "T"),
                             frf.sample_period, open_loop=False,
                             info={**frf.info, "transfer": "T = L/(1+L)", "loop": frf.name})


def sensitivity(frf: FrequencyResponse) -> FrequencyResponse:
    """The sensitivity ``S = 1/(1 + L)`` of a negative-feedback loop gain ``L``.

    Parameters
    ----------
    frf : FrequencyResponse
        The loop gain ``L`` on its grid.

    Returns
    -------
    FrequencyResponse
        ``S`` on the same grid, same ``sample_period``, ``open_loop=False``, named ``"<name> S"``;
        ``1/max|S|`` is the modulus margin.
    """
    resp = np.asarray(frf.response, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        S = 1.0 / (1.0 + resp)
    return FrequencyResponse(np.asarray(frf.omega, dtype=float), S, _derived_name(frf.name, "S"),
                             frf.sample_period, open_loop=False,
                             info={**frf.info, "transfer": "S = 1/(1+L)", "loop": frf.name})


# ---------------------------------------------------------------------------------------- helpers
def _derived_name(name: str, what: str) -> str:
    return f"{name} {what}" if name else what


def _validated(frf: FrequencyResponse, *, finite: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The grid and the response, checked; ``finite=False`` lets infinite values through (a closed
    loop at a grid point where ``1 + L = 0``), not NaN."""
    omega = np.asarray(frf.omega, dtype=float)
    resp = np.asarray(frf.response, dtype=complex)
    if omega.ndim != 1 or omega.size < 2:
        raise ModelError(f"expected a 1-D grid of at least 2 frequencies, got shape {omega.shape}",
                         path="frf.omega")
    if resp.shape != omega.shape:
        raise ModelError(f"expected {omega.size} response values (one per frequency), got shape "
                         f"{resp.shape}", path="frf.response")
    if not np.all(np.isfinite(omega)) or omega[0] <= 0 or np.any(np.diff(omega) <= 0):
        raise ModelError("frequencies must be finite, positive and strictly ascending (rad/s)",
                         path="frf.omega")
    bad = np.flatnonzero(~np.isfinite(resp) if finite else np.isnan(resp))
    if bad.size:
        raise ModelError(f"the response is not finite at ω = {omega[bad[0]]:.6g} rad/s "
                         f"({bad.size} point(s)); remove the grid points on poles", path="frf.response")
    return omega, resp


def _nyquist_reach(omega: np.ndarray, period: float | None) -> float | None:
    """π/T when the grid of a sampled loop ends close below it, else None."""
    if not period:
        return None
    nyquist = np.pi / period
    if _NYQUIST_REACH * nyquist <= omega[-1] <= nyquist * (1 + 1e-12):
        return float(nyquist)
    return None


def _crossings(y: np.ndarray, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Intervals ``[i, i+1]`` where ``y`` crosses ``levels[i]`` (``y ≥ level`` counts as above),
    with the linear fraction ``t ∈ [0, 1]`` of the crossing inside the interval."""
    above0 = y[:-1] >= levels
    above1 = y[1:] >= levels
    idx = np.flatnonzero(above0 != above1)
    lo, hi = y[idx] - levels[idx], y[idx + 1] - levels[idx]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = -lo / (hi - lo)
    return idx, np.clip(np.nan_to_num(t, nan=0.5), 0.0, 1.0)


def _stencil(n: int, i: int) -> slice | None:
    """Four consecutive grid points around the interval ``[i, i+1]``."""
    if n < 4:
        return None
    j0 = min(max(i - 1, 0), n - 4)
    return slice(j0, j0 + 4)


def _cubic(x: np.ndarray, y: np.ndarray, i: int) -> np.ndarray | None:
    """Coefficients of the cubic through the stencil of interval ``i`` in ``u = (x − x_i)/h``."""
    st = _stencil(x.size, i)
    if st is None or not np.all(np.isfinite(y[st])):
        return None
    h = x[i + 1] - x[i]
    return np.polyfit((x[st] - x[i]) / h, y[st], 3)


def _root(x: np.ndarray, y: np.ndarray, i: int, t: float, level: float) -> float:
    """``ln ω`` where ``y`` crosses ``level`` inside ``[x_i, x_{i+1}]``: the root of the local cubic
    nearest the linear estimate ``t`` (the linear one when the cubic has no root in the interval)."""
    h = x[i + 1] - x[i]
    coeffs = _cubic(x, y, i)
    if coeffs is not None:
        coeffs = coeffs.copy()
        coeffs[-1] -= level
        roots = np.roots(coeffs)
        real = roots[np.abs(roots.imag) <= 1e-9].real
        inside = real[(real >= -1e-12) & (real <= 1.0 + 1e-12)]
        if inside.size:
            t = float(np.clip(inside[np.argmin(np.abs(inside - t))], 0.0, 1.0))
    return float(x[i] + t * h)


def _value(x: np.ndarray, y: np.ndarray, i: int, xc: float) -> float:
    """``y`` at ``xc ∈ [x_i, x_{i+1}]``: the local cubic, unless it departs from the linear value by
    more than half the interval's change (an unresolved resonance or phase jump): then linear."""
    h = x[i + 1] - x[i]
    u = (xc - x[i]) / h
    with np.errstate(invalid="ignore"):
        linear = y[i] + u * (y[i + 1] - y[i])
    coeffs = _cubic(x, y, i)
    if coeffs is None:
        return float(linear)
    cubic = float(np.polyval(coeffs, u))
    if abs(cubic - linear) <= 0.5 * abs(y[i + 1] - y[i]) + 1e-12 * (1.0 + abs(linear)):
        return cubic
    return float(linear)


def _dedupe(xs: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort crossovers and merge those found twice (a grid point exactly on the level)."""
    if not xs.size:
        return np.zeros(0), np.zeros(0)
    order = np.argsort(xs, kind="stable")
    xs, values = xs[order], values[order]
    keep = np.concatenate([[True], np.diff(xs) > 1e-10])
    return xs[keep], values[keep]


def _closest_to_zero(values: np.ndarray) -> int:
    """Index of the smallest ``|value|``; ties (within rounding) go to the negative one, then to the
    lowest frequency (``values`` are in ascending frequency)."""
    size = np.abs(values)
    tied = np.flatnonzero(size <= size.min() + 1e-9 * (1.0 + size.min()))
    return int(tied[np.argmin(values[tied] >= 0)]) if np.isfinite(size.min()) else int(np.argmin(size))


def _wrap180(angle_deg: np.ndarray) -> np.ndarray:
    """Wrap into ``(−180°, 180°]``."""
    return angle_deg - 360.0 * np.ceil((angle_deg - 180.0) / 360.0)


def _even_extrapolation(w2: np.ndarray, y2: np.ndarray, w_n: float) -> float:
    """Value at ``w_n`` of ``a + b (ω − w_n)²`` through two points (a function even about ``w_n``)."""
    u = (w2 - w_n) ** 2
    if not np.all(np.isfinite(y2)) or u[0] == u[1]:
        return float(y2[-1])
    b = (y2[1] - y2[0]) / (u[1] - u[0])
    return float(y2[1] - b * u[1])


def _odd_extrapolation(w2: np.ndarray, y2: np.ndarray, w_n: float) -> float:
    """Value at ``w_n`` of the line through two points (exact to third order for a function odd
    about ``w_n``, as the phase of a sampled response about the Nyquist frequency)."""
    slope = (y2[1] - y2[0]) / (w2[1] - w2[0])
    return float(y2[1] + slope * (w_n - w2[1]))


def _modulus_margin(x: np.ndarray, omega: np.ndarray, resp: np.ndarray,
                    nyquist: float | None) -> tuple[float, float]:
    """``min |1 + L|`` and where: the grid minimum, refined on its two neighbouring intervals by the
    local cubics (in ln ω) of Re L and Im L sampled finely; at π/T for a sampled loop when lower."""
    distance = np.abs(1.0 + resp)
    j = int(np.argmin(distance))
    best, where = float(distance[j]), float(omega[j])
    u = np.linspace(0.0, 1.0, 201)
    for i in (j - 1, j):
        if not 0 <= i < distance.size - 1:
            continue
        re, im = _cubic(x, resp.real, i), _cubic(x, resp.imag, i)
        if re is None or im is None:
            continue
        d = np.abs(1.0 + np.polyval(re, u) + 1j * np.polyval(im, u))
        k = int(np.argmin(d))
        # an unresolved curve (cubic far below the grid values around it) is not trusted
        around = distance[_stencil(distance.size, i)]
        if d[k] < best and d[k] >= best - (around.max() - around.min()):
            best, where = float(d[k]), float(np.exp(x[i] + u[k] * (x[i + 1] - x[i])))
    if j == distance.size - 1 and nyquist is not None:
        at_nyquist = _even_extrapolation(omega[-2:], distance[-2:], nyquist)
        if 0.0 <= at_nyquist < best:
            best, where = at_nyquist, nyquist
    return best, where


def _frozen(values: np.ndarray) -> np.ndarray:
    arr = np.array(values, dtype=float)
    arr.setflags(write=False)
    return arr


def _json_float(value: float) -> float | None:
    value = float(value)
    return value if np.isfinite(value) else None


def margins_warnings(margins: Margins, loop: str, stable: bool | None, *,
                     open_loop_unstable: bool = False) -> list[str]:
    """The margins' own verdict (GM < 0 dB, PM < 0°) as sentences, reconciled with the poles'
    verdict ``stable``: negative margins on a stable closed loop mean a conditionally stable loop;
    positive ones on an unstable closed loop mean the grid missed a crossover or the open loop
    itself is unstable (``open_loop_unstable``: the position loop around an unstable velocity loop,
    whose margins mean nothing)."""
    if open_loop_unstable:
        return [f"{loop} loop: its open loop contains the unstable velocity loop: its margins mean nothing"]
    gm, pm = margins.gain_margin_db, margins.phase_margin_deg
    negative = []
    if np.isfinite(gm) and gm < 0:
        negative.append(f"gain margin {gm:.1f} dB < 0")
    if np.isfinite(pm) and pm < 0:
        negative.append(f"phase margin {pm:.1f}° < 0")
    if negative and stable is not False:
        what = " and ".join(negative)
        return [f"{loop} loop: {what}, yet the closed loop's poles are stable: the loop is conditionally "
                f"stable (a lower gain destabilises it)" if stable else f"{loop} loop: {what}"]
    if negative:
        return [f"{loop} loop: {' and '.join(negative)}"]
    if stable is False:
        return [f"{loop} loop: the margins read off the frequency grid are positive, but the closed loop "
                f"has unstable poles (a crossover outside the grid, or an unstable open loop)"]
    return []
