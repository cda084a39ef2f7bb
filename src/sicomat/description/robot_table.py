"""The rules of a modified Denavit–Hartenberg table (SYMORO's field names), row by row: what the
robotics formalism's frames may hold. Pure checks on plain numbers, shared by the model file's
``[robot]`` section (:mod:`.robot`) and :meth:`sicomat.robotics.MDHRobot.from_table`."""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Mapping

import numpy as np

from ..errors import ModelError

__all__ = ["FRAME_FIELDS", "PARAMETER_FIELDS", "GEOMETRY_FIELDS", "REVOLUTE", "PRISMATIC", "FIXED",
           "FIELD_UNITS", "field_unit", "check_frame", "check_gravity", "check_links", "check_loops"]

GEOMETRY_FIELDS = ("gamma", "b", "alpha", "d", "theta", "r")
PARAMETER_FIELDS = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M", "IA", "FV", "FS")
"""The 13 standard parameters of a frame's link, in the order of :meth:`MDHRobot.standard_parameters`."""
FRAME_FIELDS = ("ant", "sigma", "mu", *GEOMETRY_FIELDS, "eta", "k", *PARAMETER_FIELDS)
"""Every key a row of the table may hold (``ant`` and ``sigma`` are required, the rest default to 0)."""

REVOLUTE, PRISMATIC, FIXED = 0, 1, 2

FIELD_UNITS: dict[str, str | tuple[str, str]] = {
    "gamma": "angle", "alpha": "angle", "b": "length", "d": "length",
    "theta": "angle", "r": "length",
    "k": ("torsional_stiffness", "linear_stiffness"),
    **{name: "inertia" for name in ("XX", "XY", "XZ", "YY", "YZ", "ZZ")},
    "MX": "first_moment", "MY": "first_moment", "MZ": "first_moment", "M": "mass",
    "IA": ("inertia", "mass"), "FV": ("torsional_damping", "linear_damping"), "FS": ("torque", "force"),
}
"""The dimension (a key of :data:`sicomat.description.units.UNITS`) of each numeric field; a pair is
(revolute, prismatic): a joint's stiffness, rotor inertia and frictions are in its own coordinate."""


def field_unit(name: str, sigma: int) -> str:
    """The dimension of field ``name`` in a frame of type ``sigma`` (a fixed frame's joint fields are
    plain numbers: they must be 0)."""
    unit = FIELD_UNITS[name]
    if isinstance(unit, tuple):
        return unit[1] if sigma == PRISMATIC else unit[0] if sigma == REVOLUTE else "dimensionless"
    return unit

# Relative tolerance of the inertia check: the tensor about the centre of mass is computed as a
# difference J_O - (|MS|^2 I - MS MS^T)/M whose rounding is a few ulps of its terms; 1e-12 of the
# largest term accepts a point mass (exact zero tensor) written with rounded decimals and rejects
# any tensor that is wrong by a physically meaningful amount.
_INERTIA_RTOL = 1e-12


def _where(row: int, name: str) -> str:
    return f"frames[{row}].{name}"


def _error(row: int, name: str, message: str, value: object = None) -> ModelError:
    return ModelError(f"frame {row + 1}: {message}", path=_where(row, name), value=value,
                      has_value=value is not None)


def _integer(row: int, name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral):
        if isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value)) \
                and float(value).is_integer():
            return int(float(value))
        raise _error(row, name, f"{name} must be an integer", value)
    return int(value)


def _number(row: int, name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise _error(row, name, f"{name} must be a number", value)
    number = float(value)
    if not math.isfinite(number):
        raise _error(row, name, f"{name} must be finite", value)
    return number


def _check_inertia(row: int, chi: np.ndarray) -> None:
    """The link's inertia tensor about its centre of mass must be positive semi-definite.

    The triangle inequality of the principal moments (I1 + I2 >= I3, true of any real body) is not
    required: planar models commonly give only ``ZZ``, which is harmless for their dynamics."""
    xx, xy, xz, yy, yz, zz, mx, my, mz, mass = chi[:10]
    j_origin = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    ms = np.array([mx, my, mz])
    if mass == 0.0:
        for name, value in zip(("MX", "MY", "MZ"), ms):
            if value != 0.0:
                raise _error(row, name, f"a massless link (M = 0) has no first moment, but {name} != 0",
                             float(value))
        j_com = j_origin
        scale = float(np.max(np.abs(j_origin)))
    else:
        shift = (ms @ ms * np.eye(3) - np.outer(ms, ms)) / mass
        j_com = j_origin - shift
        scale = max(float(np.max(np.abs(j_origin))), float(np.max(np.abs(shift))))
    moments = np.linalg.eigvalsh(j_com)
    tol = _INERTIA_RTOL * scale
    if moments[0] < -tol:
        raise _error(row, "XX..ZZ", "the inertia tensor XX..ZZ about the centre of mass (J_O - M(c^2 I - c c^T), "
                     f"c = MS/M) is not positive semi-definite: principal moments {moments.tolist()}")


def check_gravity(gravity: object) -> np.ndarray:
    try:
        g = np.asarray(gravity, dtype=float)
    except (TypeError, ValueError):
        raise ModelError("gravity must be 3 numbers (m/s^2, base frame)", path="gravity", value=gravity) from None
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ModelError("gravity must be 3 finite numbers (m/s^2, base frame)", path="gravity", value=gravity)
    return g


def check_frame(row: int, frame: object) -> dict[str, float]:
    """One row checked: every key known, every value of its kind, the flags consistent."""
    j = row + 1
    if not isinstance(frame, Mapping):
        raise ModelError(f"frame {j}: each frame is a table of fields", path=f"frames[{row}]", value=frame)
    for key in frame:
        if key not in FRAME_FIELDS:
            raise _error(row, str(key), f"unknown field {key!r}; expected one of {', '.join(FRAME_FIELDS)}")
    for key in ("ant", "sigma"):
        if key not in frame:
            raise _error(row, key, f"the field {key!r} is required")
    values: dict[str, float] = {}
    ant = _integer(row, "ant", frame["ant"])
    if not 0 <= ant < j:
        raise _error(row, "ant", f"the antecedent must be a frame before frame {j} (0 = base .. {j - 1})", ant)
    sigma = _integer(row, "sigma", frame["sigma"])
    if sigma not in (REVOLUTE, PRISMATIC, FIXED):
        raise _error(row, "sigma", "sigma must be 0 (revolute), 1 (prismatic) or 2 (fixed)", sigma)
    values.update(ant=ant, sigma=sigma)
    for key in ("mu", "eta"):
        flag = _integer(row, key, frame.get(key, 0))
        if flag not in (0, 1):
            raise _error(row, key, f"{key} must be 0 or 1", flag)
        values[key] = flag
    if values["eta"] == 1 and values["mu"] == 1:
        raise _error(row, "mu", "an elastic joint (eta = 1) cannot be motorised (mu = 1): "
                     "put the motor on its own frame before the elastic one", 1)
    if sigma == FIXED and values["mu"] == 1:
        raise _error(row, "mu", "a fixed frame (sigma = 2) has no joint to motorise", 1)
    if sigma == FIXED and values["eta"] == 1:
        raise _error(row, "eta", "a fixed frame (sigma = 2) has no joint to be elastic", 1)
    for key in (*GEOMETRY_FIELDS, "k", *PARAMETER_FIELDS):
        values[key] = _number(row, key, frame.get(key, 0.0))
    for key in ("M", "k", "IA", "FV", "FS"):
        if values[key] < 0.0:
            raise _error(row, key, f"{key} must not be negative", values[key])
    if sigma == FIXED:
        for key in ("IA", "FV", "FS", "k"):
            if values[key] != 0.0:
                raise _error(row, key, f"a fixed frame (sigma = 2) has no joint: {key} must be 0", values[key])
    _check_inertia(row, np.array([values[name] for name in PARAMETER_FIELDS]))
    return values


def check_links(links: object, nf: int) -> int | None:
    if links is None:
        return None
    if isinstance(links, bool) or not isinstance(links, Integral) or not 1 <= int(links) <= nf:
        raise ModelError(f"links (NL) must be an integer 1..{nf} (the number of frames)", path="links", value=links)
    return int(links)


def _link_of(columns: Mapping[str, list[float]], frame: int) -> int:
    """The frame whose link carries ``frame``: up the fixed frames (``sigma = 2``) to a joint or the base."""
    while frame > 0 and columns["sigma"][frame - 1] == FIXED:
        frame = int(columns["ant"][frame - 1])
    return frame


def check_loops(columns: Mapping[str, list[float]], nl: int) -> None:
    """SYMORO's closed loops (notes §1.3): frames NL+1..NL+B cut joints, NL+B+1..NF their closing frames."""
    nf = len(columns["ant"])
    if (nf - nl) % 2:
        raise _error(nf - 1, "ant", f"with links = {nl}, the {nf - nl} frames after the links must be cut frames "
                     "and their closing frames in pairs (NF - NL = 2B), not an odd number")
    loops = (nf - nl) // 2
    for row in range(nl, nf):
        for name in PARAMETER_FIELDS[:10]:
            if columns[name][row] != 0.0:
                raise _error(row, name, f"a cut or closing frame (after frame {nl} = NL) carries no link: "
                             f"{name} must be 0", columns[name][row])
        if columns["ant"][row] > nl:
            raise _error(row, "ant", f"a cut or closing frame hangs from a link (a frame 0..{nl} = NL)",
                         int(columns["ant"][row]))
    for cut in range(nl, nl + loops):
        closing = cut + loops
        loop = f"loop {cut - nl + 1} (cut frame {cut + 1}, closing frame {closing + 1})"
        if columns["sigma"][cut] == FIXED:
            raise _error(cut, "sigma", f"{loop} has no cut joint: frame {cut + 1} must be a joint (sigma 0 or 1)", 2)
        for key in ("mu", "eta"):
            if columns[key][cut] != 0:
                raise _error(cut, key, f"{loop}: a cut joint is passive, {key} must be 0", 1)
        if columns["sigma"][closing] != FIXED:
            raise _error(closing, "sigma", f"{loop}: a closing frame is fixed on its link (sigma = 2)",
                         int(columns["sigma"][closing]))
        if _link_of(columns, int(columns["ant"][cut])) == _link_of(columns, int(columns["ant"][closing])):
            raise _error(closing, "ant", f"{loop}: the closing frame sits on the same link as the cut joint "
                         f"(frame {int(columns['ant'][cut])}): the loop closes nothing", int(columns["ant"][closing]))
