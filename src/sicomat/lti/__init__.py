"""Linear time-invariant systems: the named state space (`Plant`), the one frequency-response
evaluator (at s = jω and z = e^{jωT}), ZOH, exact static gains, and the one rigid/flexible spectral
split."""

from .plant import Plant
from .spectral import (RIGID_TOL, SpectralSplit, StateBlock, nilpotent, schur_eigenvalues, schur_triplet,
                       select_positions, spectral_split, split_block, split_state_space)
from .response import (DIAGONAL_MAX_COND, DIRECT_MAX_STATES, FLEXIBLE_MAX_COND, Evaluator, FrequencyResponse,
                       SplitResponse, static_gain, transfer_at, zoh_matrices)

__all__ = [
    "Plant",
    "RIGID_TOL", "SpectralSplit", "StateBlock", "nilpotent", "schur_eigenvalues", "schur_triplet",
    "select_positions", "spectral_split", "split_block", "split_state_space",
    "DIAGONAL_MAX_COND", "DIRECT_MAX_STATES", "FLEXIBLE_MAX_COND", "Evaluator", "FrequencyResponse",
    "SplitResponse", "static_gain", "transfer_at", "zoh_matrices",
]
