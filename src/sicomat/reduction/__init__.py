"""Model reduction (paper III.C): modal truncation, balanced (Gramian) reduction, physical regrouping.

:func:`reduce` is the one entry point for every method (``reduce(machine_or_plant, "balanced", 4)``).

Each reductor takes the model it reduces (a :class:`~sicomat.lti.plant.Plant`, or a mechanics
description for the physical method) and returns a :class:`ReductionResult`: the reduced model (a
``Plant``; for the physical method also a ``Mechanics`` and a ``LumpedSpec`` for a model file) and
what it cost (frequency errors on a pole-aware grid, Hankel singular values, error bound).
"""

from .balanced import (band_gramian_operator, balanced_truncation, frequency_limited_truncation, hankel_norm_approximation, hankel_singular_values, schur_truncation)
from .error import (ErrorMetrics, ReductionResult, error_metrics, frequency_grid, frequency_response, natural_frequencies_hz)
from .modal import SpectralSplit, modal_truncation, spectral_split
from .physical import physical_reduction, reduced_machine, technological_dofs
from .methods import METHODS, reduce, default_band, default_transfer

__all__ = [
    "ReductionResult", "ErrorMetrics", "error_metrics", "frequency_grid", "frequency_response",
    "natural_frequencies_hz",
    "modal_truncation", "spectral_split", "SpectralSplit",
    "balanced_truncation", "schur_truncation", "frequency_limited_truncation", "hankel_norm_approximation",
    "hankel_singular_values", "band_gramian_operator",
    "physical_reduction", "technological_dofs", "reduced_machine",
    "reduce", "METHODS", "default_band", "default_transfer",
]
