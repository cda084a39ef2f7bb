"""Linear time-invariant systems: the named state space (`Plant`) and the frequency-response engine
(at s = jω and z = e^{jωT}, ZOH, the rigid/flexible spectral split, exact static gains)."""

from .plant import Plant
from .response import (FrequencyResponse, ModalForm, modal_form, continuous_response, sampled_response, response_at, zoh_matrices, static_gain)

__all__ = [
    "Plant",
    "FrequencyResponse",
    "ModalForm",
    "modal_form",
    "continuous_response",
    "sampled_response",
    "response_at",
    "zoh_matrices",
    "static_gain",
]
