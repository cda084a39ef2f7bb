"""Files in and out: the model file (read, overrides, save), its text-preserving edit, the output
policy with atomic writes, CSV tables."""

from .atomic import FORMATS, atomic_write, check_output, check_outputs
from .csv import write_frame_csv
from .modelfile import (load_model, machine_from_dict, save_model, model_text, dump_model, parse_override, with_overrides)
from .modeltext import edited_model_text, comment_lines

__all__ = [
    "FORMATS",
    "atomic_write",
    "check_output",
    "check_outputs",
    "write_frame_csv",
    "load_model",
    "machine_from_dict",
    "save_model",
    "model_text",
    "dump_model",
    "parse_override",
    "with_overrides",
    "edited_model_text",
    "comment_lines",
]
