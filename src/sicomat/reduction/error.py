"""What a reduction cost: frequency errors on a pole-aware grid, and the :class:`ReductionResult`.

Frequency responses are evaluated from the additive split ``G = rigid + flexible`` of
:func:`~sicomat.lti.spectral.spectral_split` by the engine's
:class:`~sicomat.lti.response.SplitResponse` (rigid parts that both models keep exactly then cancel
in the error). The grid is log-spaced and also holds every pole's damped and natural frequency (and
its half-power points) of both models, so no lightly damped peak falls between two points.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..errors import ModelError
from ..lti.plant import Plant
from ..lti.response import SplitResponse
from ..lti.spectral import RIGID_TOL, spectral_split

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..mechanics.lumped import Mechanics
    from ..description.mechanics import LumpedSpec
    from ..description.machine import Machine

__all__ = ["ErrorMetrics", "ReductionResult", "error_metrics", "frequency_grid", "frequency_response",
           "natural_frequencies_hz", "check_band", "select_transfer"]

_TWO_PI = 2.0 * np.pi


def check_band(band_hz: Sequence[float] | None) -> tuple[float, float] | None:
    """Validate a band of interest ``(low_hz, high_hz)``: ``0 ≤ low < high``, finite."""
    if band_hz is None:
        return None
    try:
        low, high = (float(v) for v in band_hz)
    except (TypeError, ValueError):
        raise ModelError("expected a band (low_hz, high_hz) of two numbers", path="band_hz",
                         value=band_hz) from None
    if not (np.isfinite(low) and np.isfinite(high)):
        raise ModelError("expected finite band limits in Hz", path="band_hz", value=(low, high))
    if low < 0:
        raise ModelError("expected a band starting at 0 Hz or above", path="band_hz", value=(low, high))
    if low >= high:
        raise ModelError("expected a band with low < high (Hz)", path="band_hz", value=(low, high))
    return (low, high)


def select_transfer(plant: Plant, inputs: Sequence[str] | str | None = None,
                    outputs: Sequence[str] | str | None = None) -> Plant:
    """The sub-plant a reduction works on: from the named inputs to the named outputs.

    The Gramians and error norms weigh every channel of the plant in its raw SI units, so a
    velocity output (m/s) next to a position output (m) dominates by the frequencies squared:
    reduce the transfer that matters, e.g. the actuator to the controller's position sensor.

    Parameters
    ----------
    plant : Plant
        The full plant.
    inputs, outputs : sequence of str, str or None
        Signal names (a string is one name); ``None`` keeps them all.

    Raises
    ------
    ModelError
        An empty selection, a repeated name or an unknown one (``path`` is ``"inputs"`` or
        ``"outputs"``; the message lists the plant's signals).

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[1, 1], stiffnesses=[100])).state_space()
    >>> select_transfer(plant, outputs=["last"]).outputs
    ('last',)
    """
    chosen: dict[str, list[str] | None] = {}
    for kind, names, known in (("input", inputs, plant.inputs), ("output", outputs, plant.outputs)):
        if names is None:
            chosen[kind] = None
            continue
        names = [names] if isinstance(names, str) else list(names)
        if not names:
            raise ModelError(f"no {kind} chosen; expected names among {', '.join(known)}", path=f"{kind}s",
                             value="")
        for name in names:
            if name not in known:
                raise ModelError(f"unknown {kind} signal; expected names among {', '.join(known)}",
                                 path=f"{kind}s", value=name)
        if len(set(names)) != len(names):
            raise ModelError(f"an {kind} is named twice", path=f"{kind}s", value=",".join(names))
        chosen[kind] = names
    if chosen["input"] is None and chosen["output"] is None:
        return plant
    return plant.select(chosen["input"], chosen["output"])


# --------------------------------------------------------------------------- frequency responses
class _Response(SplitResponse):
    """The engine's split response of a plant, evaluated at ``s = jω`` (ω arrays in rad/s)."""

    def __init__(self, plant: Plant, rigid_tol: float) -> None:
        super().__init__(spectral_split(plant, rigid_tol=rigid_tol))
        self.n_rigid = self.split.rigid.n

    def rigid(self, omega: np.ndarray) -> np.ndarray:
        """Response of the rigid block ``(n_ω, ny, nu)`` (ω > 0)."""
        return super().rigid(1j * np.asarray(omega, float))

    def flexible(self, omega: np.ndarray) -> np.ndarray:
        """Response of the flexible block plus the feedthrough ``(n_ω, ny, nu)``."""
        return super().flexible(1j * np.asarray(omega, float))


def frequency_response(plant: Plant, omega: np.ndarray, *, rigid_tol: float | None = None) -> np.ndarray:
    """``G(jω)`` for many frequencies at once, shape ``(len(omega), ny, nu)``.

    Parameters
    ----------
    plant : Plant
        Any continuous plant.
    omega : array_like
        Angular frequencies (rad/s), ``> 0`` when the plant has poles at 0.
    rigid_tol : float, optional
        Relative tolerance for poles at 0 (default :data:`~sicomat.lti.spectral.RIGID_TOL`).

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[2.0])).state_space()
    >>> complex(frequency_response(plant, [10.0])[0, 0, 0].round(12))  # 1 / (m (j10)²)
    (-0.005+0j)
    """
    return _Response(plant, RIGID_TOL if rigid_tol is None else rigid_tol)(np.atleast_1d(omega))


def natural_frequencies_hz(poles: np.ndarray, rigid_states: int = 0) -> np.ndarray:
    """Natural frequencies ``|λ|/2π`` (Hz), ascending: one 0 per rigid-body mode (two rigid states),
    then one per complex pole pair and one per real pole of the other ``poles``.

    Examples
    --------
    >>> natural_frequencies_hz(np.array([-1 + 2j * np.pi, -1 - 2j * np.pi]), rigid_states=2).round(4).tolist()
    [0.0, 1.0126]
    """
    poles = np.asarray(poles, complex)
    scale = max(float(np.max(np.abs(poles))) if poles.size else 0.0, 1.0)
    keep = poles.imag >= -1e-12 * scale  # one pole of each conjugate pair
    values = np.concatenate([np.zeros((rigid_states + 1) // 2), np.abs(poles[keep]) / _TWO_PI])
    return np.sort(values)


def frequency_grid(*poles: np.ndarray, band_hz: tuple[float, float] | None = None,
                   points_per_decade: int = 40) -> np.ndarray:
    """A log-spaced grid (rad/s) that also holds each pole's damped and natural frequencies.

    For a pole ``λ = σ + jω_d`` the grid gets ``ω_d``, ``|λ|`` and the half-power points
    ``ω_d ± |σ|``: a lightly damped peak (width ``2|σ|``) cannot fall between two points. The
    log-spaced part spans from a hundredth of the slowest non-zero pole to ten times the fastest,
    and covers the band if one is given.
    """
    allp = np.concatenate([np.asarray(p, complex).ravel() for p in poles]) if poles else np.zeros(0, complex)
    mags = np.abs(allp[allp != 0])
    lo = float(mags.min()) / 100.0 if mags.size else 0.1
    hi = float(mags.max()) * 10.0 if mags.size else 10.0
    if band_hz is not None:
        hi = max(hi, _TWO_PI * band_hz[1] * 1.01)
        lo = min(lo, _TWO_PI * (band_hz[0] if band_hz[0] > 0 else band_hz[1] * 1e-3))
    count = int(np.ceil(np.log10(hi / lo) * points_per_decade)) + 1
    parts = [np.logspace(np.log10(lo), np.log10(hi), count)]
    osc = allp[np.abs(allp.imag) > 0]
    if osc.size:
        wd, sigma = np.abs(osc.imag), np.abs(osc.real)
        parts += [wd, np.abs(osc), wd + sigma, np.maximum(wd - sigma, 0.0)]
    real = allp[(allp.imag == 0) & (allp != 0)]
    if real.size:
        parts.append(np.abs(real))
    if band_hz is not None:
        parts.append(_TWO_PI * np.array([b for b in band_hz if b > 0]))
    omega = np.unique(np.concatenate(parts))
    return omega[omega > 0]


# --------------------------------------------------------------------------- error metrics
def _gain(G: np.ndarray) -> np.ndarray:
    """Largest singular value of each ``(ny, nu)`` matrix of a response."""
    if G.shape[1] == 1 or G.shape[2] == 1:
        return np.sqrt(np.sum(np.abs(G) ** 2, axis=(1, 2)))
    return np.linalg.norm(G, ord=2, axis=(1, 2))


def _refine_peak(omega: np.ndarray, gain: np.ndarray, evaluate, candidates: int = 6,
                 rounds: int = 4, points: int = 17) -> tuple[float, float]:
    """The largest gain, refined around the grid's highest local maxima.

    Two close lightly damped poles (one of each model) can put the error's peak between their
    frequencies; each candidate interval between the neighbours of a local maximum is re-sampled
    ``points`` times, ``rounds`` times, shrinking to the new maximum's neighbours each time.
    """
    best_w, best = float(omega[int(np.argmax(gain))]), float(np.max(gain))
    if omega.size < 3:
        return best_w, best
    interior = np.flatnonzero((gain[1:-1] >= gain[:-2]) & (gain[1:-1] >= gain[2:])) + 1
    for i in interior[np.argsort(gain[interior])[::-1][:candidates]]:
        lo, hi = omega[i - 1], omega[i + 1]
        for _ in range(rounds):
            w = np.linspace(lo, hi, points)
            g = evaluate(w)
            j = int(np.argmax(g))
            if g[j] > best:
                best_w, best = float(w[j]), float(g[j])
            lo, hi = w[max(j - 1, 0)], w[min(j + 1, points - 1)]
    return best_w, best


def _ratio(num: float, den: float) -> float | None:
    return float(num / den) if den > 0 and np.isfinite(num / den) else None


@dataclass(frozen=True, eq=False)
class ErrorMetrics:
    """Frequency-domain cost of a reduction (result of :func:`error_metrics`).

    Gains are largest singular values of the ``(ny, nu)`` response matrices, in the plant's units
    (e.g. m/N). The error system is ``E = G − G_r``; rigid-body parts (poles at 0) that the method
    keeps exactly cancel in it.

    Attributes
    ----------
    omega : ndarray
        The pole-aware grid (rad/s), see :func:`frequency_grid`.
    full_response, reduced_response : ndarray
        ``G(jω)`` and ``G_r(jω)``, shape ``(n_ω, ny, nu)``.
    error_gain : ndarray
        ``σ̄(E(jω))`` on the grid.
    hinf_error : float
        ``max σ̄(E(jω))``: the H∞ norm of the error system, from the grid refined around its
        highest local maxima.
    hinf_frequency_hz : float
        Where that maximum is.
    hinf_relative_error : float or None
        ``hinf_error`` over the H∞ norm of the full model's flexible part (rigid-body part removed,
        see :func:`~sicomat.lti.spectral.spectral_split`).
    dc_gain_error, dc_gain_relative_error : float, float or None
        ``σ̄(G_f(0) − G_{r,f}(0))`` of the flexible parts (the whole plants when there is no rigid
        mode), absolute and relative to ``σ̄(G_f(0))``.
    band_hz, band_max_error, band_rms_error, band_max_relative_error
        Over the band of interest (if one is given): the largest error, the RMS of ``σ̄(E)`` over
        log-spaced frequencies, and the largest error over the full model's largest gain there.
    frequencies_hz_full, frequencies_hz_reduced : ndarray
        Natural frequencies from the poles (:func:`natural_frequencies_hz`).
    frequency_pairs : tuple of (float, float)
        Each retained frequency of the reduced model with the full model's frequency it matches.
    """

    omega: np.ndarray
    full_response: np.ndarray
    reduced_response: np.ndarray
    error_gain: np.ndarray
    hinf_error: float
    hinf_frequency_hz: float
    hinf_relative_error: float | None
    dc_gain_error: float
    dc_gain_relative_error: float | None
    band_hz: tuple[float, float] | None
    band_max_error: float | None
    band_rms_error: float | None
    band_max_relative_error: float | None
    frequencies_hz_full: np.ndarray
    frequencies_hz_reduced: np.ndarray
    frequency_pairs: tuple[tuple[float, float], ...]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (no arrays of responses)."""
        return {
            "hinf_error": self.hinf_error, "hinf_frequency_hz": self.hinf_frequency_hz,
            "hinf_relative_error": self.hinf_relative_error,
            "dc_gain_error": self.dc_gain_error, "dc_gain_relative_error": self.dc_gain_relative_error,
            "band_hz": list(self.band_hz) if self.band_hz else None,
            "band_max_error": self.band_max_error, "band_rms_error": self.band_rms_error,
            "band_max_relative_error": self.band_max_relative_error,
            "frequencies_hz": [float(f) for f in self.frequencies_hz_reduced],
            "frequencies_hz_full": [float(f) for f in self.frequencies_hz_full],
            "retained_frequencies": [{"reduced_hz": r, "full_hz": f,
                                      "relative_error": (abs(r - f) / f) if f > 0 else abs(r - f)}
                                     for r, f in self.frequency_pairs],
        }


def _pairs(reduced: np.ndarray, full: np.ndarray) -> tuple[tuple[float, float], ...]:
    if reduced.size == 0 or full.size == 0:
        return ()
    from scipy.optimize import linear_sum_assignment

    eps = 1e-9 * max(float(full.max()), 1e-300)
    cost = np.abs(np.log((reduced[:, None] + eps) / (full[None, :] + eps)))
    rows, cols = linear_sum_assignment(cost)
    return tuple(sorted((float(reduced[i]), float(full[j])) for i, j in zip(rows, cols)))


def error_metrics(full: Plant, reduced: Plant, *, band_hz: tuple[float, float] | None = None,
                  rigid_tol: float | None = None, points_per_decade: int = 40) -> ErrorMetrics:
    """The frequency errors of a reduced model against the full one.

    Parameters
    ----------
    full, reduced : Plant
        Same inputs and outputs.
    band_hz : (float, float), optional
        Band of interest (Hz) for the band errors.
    rigid_tol : float, optional
        Relative tolerance for poles at 0 (default :data:`~sicomat.lti.spectral.RIGID_TOL`).
    points_per_decade : int, optional
        Density of the log-spaced part of the grid (the pole frequencies are always added).

    Returns
    -------
    ErrorMetrics

    Examples
    --------
    >>> from sicomat.description import ChainSpec
    >>> from sicomat.mechanics import build_mechanics
    >>> plant = build_mechanics(ChainSpec(type="chain", masses=[1, 1], stiffnesses=[100],
    ...                                   dampings=[0.1])).state_space()
    >>> error_metrics(plant, plant).hinf_error
    0.0
    """
    band_hz = check_band(band_hz)
    if full.inputs != reduced.inputs or full.outputs != reduced.outputs:
        raise ModelError("the reduced plant must have the full plant's inputs and outputs",
                         value={"inputs": reduced.inputs, "outputs": reduced.outputs})
    tol = RIGID_TOL if rigid_tol is None else rigid_tol
    rf, rr = _Response(full, tol), _Response(reduced, tol)
    omega = frequency_grid(rf.poles, rr.poles, band_hz=band_hz, points_per_decade=points_per_decade)
    same_rigid = (rf.split.rigid.n == rr.split.rigid.n and rf.split.rigid.n > 0
                  and np.allclose(rf.rigid(omega[:3]), rr.rigid(omega[:3]), rtol=1e-10, atol=0.0))
    Gf_rigid, Gr_rigid = rf.rigid(omega), rr.rigid(omega)
    Gf_flex, Gr_flex = rf.flexible(omega), rr.flexible(omega)
    G, Gr = Gf_rigid + Gf_flex, Gr_rigid + Gr_flex
    E = (Gf_flex - Gr_flex) if same_rigid else (Gf_rigid - Gr_rigid) + (Gf_flex - Gr_flex)
    err = _gain(E)

    def e_at(w: np.ndarray) -> np.ndarray:
        ef = rf.flexible(w) - rr.flexible(w)
        return _gain(ef if same_rigid else ef + rf.rigid(w) - rr.rigid(w))

    peak_w, peak = _refine_peak(omega, err, e_at)
    dc_full, dc_red = rf.split.dc_gain(), rr.split.dc_gain()
    dc_err = float(np.linalg.norm(dc_full - dc_red, 2)) if dc_full.size else 0.0
    dc_ref = float(np.linalg.norm(dc_full, 2)) if dc_full.size else 0.0
    flex_peak = max(float(np.max(_gain(Gf_flex))), dc_ref)

    band_max = band_rms = band_rel = None
    if band_hz is not None:
        lo_w, hi_w = _TWO_PI * band_hz[0], _TWO_PI * band_hz[1]
        start = lo_w if lo_w > 0 else hi_w * 1e-3
        even = np.logspace(np.log10(start), np.log10(hi_w), 200)
        inside = omega[(omega >= lo_w) & (omega <= hi_w)]
        pts = np.unique(np.concatenate([even, inside]))
        e_pts = e_at(pts)
        band_max = float(e_pts.max())
        if lo_w == 0.0:
            band_max = max(band_max, dc_err)
        band_rms = float(np.sqrt(np.mean(e_at(even) ** 2)))
        band_rel = _ratio(band_max, float(np.max(_gain(rf(pts)))))

    f_full = natural_frequencies_hz(rf.split.flexible.poles(), rf.split.rigid.n)
    f_red = natural_frequencies_hz(rr.split.flexible.poles(), rr.split.rigid.n)
    return ErrorMetrics(
        omega=omega, full_response=G, reduced_response=Gr, error_gain=err,
        hinf_error=peak, hinf_frequency_hz=float(peak_w / _TWO_PI),
        hinf_relative_error=_ratio(peak, flex_peak),
        dc_gain_error=dc_err, dc_gain_relative_error=_ratio(dc_err, dc_ref) if dc_ref > 0 else None,
        band_hz=band_hz, band_max_error=band_max, band_rms_error=band_rms, band_max_relative_error=band_rel,
        frequencies_hz_full=f_full, frequencies_hz_reduced=f_red, frequency_pairs=_pairs(f_red, f_full))


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class ReductionResult:
    """A reduced model and what it cost.

    Attributes
    ----------
    method : str
        ``"modal"``, ``"balanced"`` or ``"physical"``.
    variant : str
        The algorithm: ``"truncation-dc-matched"`` (modal), ``"square-root"``,
        ``"singular-perturbation"``, ``"frequency-limited"``, ``"schur"``, ``"hankel-norm"``
        (balanced), ``"regrouping"`` (physical).
    full, reduced : Plant
        The full and the reduced plant (same inputs and outputs).
    hankel_singular_values : ndarray or None
        Of the stable part, descending (balanced methods).
    error_bound : float or None
        A-priori bound on the H∞ norm of the error (``2 Σ`` of the discarded Hankel singular
        values for balanced truncation and its singular-perturbation variant, ``Σ`` for the
        Hankel-norm approximation); ``None`` when the method has none.
    band_hz : (float, float) or None
        Band of interest (Hz).
    kept : tuple of str
        The kept degrees of freedom (physical method).
    merged_into : dict
        Each removed body and the kept body that carries most of it (or ``"ground"``).
    mechanics, spec : Mechanics, LumpedSpec or None
        The reduced lumped model (physical method).
    machine : Machine or None
        The machine with the reduced axis, ready for :func:`sicomat.io.modelfile.save_model`
        (physical method through :func:`~sicomat.tasks.reduce.reduce_command`).
    notes : tuple of str
        Things the user should know (the transfer chosen by default, a friction dropped, ...).
    warnings : tuple of str
        What differs from the request (an order that would split a complex pole pair, rounded
        down; fewer states than asked).

    The error figures (:attr:`metrics`, :attr:`hinf_error`, ...) are computed on first access.
    """

    method: str
    variant: str
    full: Plant
    reduced: Plant
    hankel_singular_values: np.ndarray | None = None
    error_bound: float | None = None
    band_hz: tuple[float, float] | None = None
    kept: tuple[str, ...] = ()
    mechanics: "Mechanics | None" = None
    spec: "LumpedSpec | None" = None
    machine: "Machine | None" = None
    notes: tuple[str, ...] = ()
    merged_into: dict[str, str] = field(default_factory=dict)
    rigid_tol: float | None = field(default=None, repr=False)
    warnings: tuple[str, ...] = ()

    @property
    def order_before(self) -> int:
        """Number of states of the full model."""
        return self.full.n_states

    @property
    def order_after(self) -> int:
        """Number of states of the reduced model."""
        return self.reduced.n_states

    @cached_property
    def metrics(self) -> ErrorMetrics:
        """Frequency errors on the pole-aware grid (computed once, on first access)."""
        return error_metrics(self.full, self.reduced, band_hz=self.band_hz, rigid_tol=self.rigid_tol)

    @property
    def hinf_error(self) -> float:
        """H∞ norm of the error system on the pole-aware grid (plant units)."""
        return self.metrics.hinf_error

    @property
    def dc_gain_error(self) -> float:
        """Static-gain error of the flexible part (plant units)."""
        return self.metrics.dc_gain_error

    @property
    def band_max_error(self) -> float | None:
        """Largest error over the band of interest."""
        return self.metrics.band_max_error

    @property
    def band_rms_error(self) -> float | None:
        """RMS error over the band of interest (log-spaced frequencies)."""
        return self.metrics.band_rms_error

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies of the reduced model (Hz)."""
        return self.metrics.frequencies_hz_reduced

    @property
    def frequencies_hz_full(self) -> np.ndarray:
        """Natural frequencies of the full model (Hz)."""
        return self.metrics.frequencies_hz_full

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (the ``sicomat reduce --json`` contract)."""
        hsv = self.hankel_singular_values
        out = {
            "method": self.method, "variant": self.variant,
            "order_before": self.order_before, "order_after": self.order_after,
            "inputs": list(self.full.inputs), "outputs": list(self.full.outputs),
        }
        out.update(self.metrics.to_dict())
        out.update({
            "error_bound": self.error_bound,
            "hankel_singular_values": None if hsv is None else [float(v) for v in hsv],
            "kept": list(self.kept) if self.kept else None,
            "merged_into": dict(self.merged_into) if self.merged_into else None,
            "notes": list(self.notes),
            "warnings": list(self.warnings),
        })
        if self.spec is not None:
            out["reduced_model"] = self.spec.model_dump(mode="json", exclude_none=True)
        return out

    def plot(self, *, max_channels: int = 4) -> "Figure":
        """Bode magnitude and phase of the full (solid) and reduced (dashed) models on one figure.

        One line pair per input/output channel (at most ``max_channels``); the band of interest is
        shaded. Returns the matplotlib ``Figure``.
        """
        from ..plots.reduction import plot_reduction

        return plot_reduction(self, max_channels=max_channels)
