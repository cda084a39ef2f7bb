"""The Pareto front of a study's results: the indices of the non-dominated variants (pure numpy)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["pareto_front", "SENSES"]

SENSES = ("min", "max")
"""The two senses of an objective: smaller is better, larger is better."""


def pareto_front(values: "np.typing.ArrayLike", senses: Sequence[str]) -> np.ndarray:
    """The rows of ``values`` that no other row dominates.

    Row ``a`` dominates row ``b`` when ``a`` is at least as good as ``b`` in every column and better
    in one (``"min"``: smaller is better, ``"max"``: larger). Equal rows do not dominate each other:
    they are all on the front or all off it. A row with a NaN is never on the front (a failed or
    undefined variant); ±inf are ordinary values (an infinite gain margin is the best there is).

    Parameters
    ----------
    values : array_like, shape (n, k)
        One row per variant, one column per objective (floats).
    senses : sequence of str, length k
        ``"min"`` or ``"max"`` per column.

    Returns
    -------
    numpy.ndarray of int, shape (m,)
        The row indices of the front, ascending.

    Raises
    ------
    ModelError
        ``values`` not a 2-D array of numbers, or ``senses`` not one ``"min"``/``"max"`` per column.

    Notes
    -----
    Two objectives: sort and sweep, O(n log n). More: every row against all others, O(n² k) time
    and O(n k) memory per row.

    Examples
    --------
    >>> pareto_front([[1.0, 5.0], [2.0, 6.0], [2.0, 4.0], [float("nan"), 9.0]], ["min", "max"])
    array([0, 1])
    """
    v = _as_matrix(values)
    signs = _signs(senses, v.shape[1])
    v = v * signs                                       # every column now "smaller is better"
    rows = np.flatnonzero(~np.isnan(v).any(axis=1))
    if rows.size == 0:
        return np.empty(0, dtype=np.intp)
    w = v[rows]
    if w.shape[1] == 1:
        keep = w[:, 0] == w[:, 0].min()
    elif w.shape[1] == 2:
        keep = _front_2d(w)
    else:
        keep = _front_general(w)
    return np.sort(rows[keep])


def _as_matrix(values: "np.typing.ArrayLike") -> np.ndarray:
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"the objectives must be numbers ({exc})", path="pareto") from None
    if v.ndim != 2 or v.shape[1] == 0:
        raise ModelError(f"the objectives must be a 2-D array (one row per variant, one column per objective), "
                         f"got shape {v.shape}", path="pareto")
    return v


def _signs(senses: Sequence[str], k: int) -> np.ndarray:
    if isinstance(senses, str) or len(senses) != k:
        raise ModelError(f"expected one sense per objective ({k}), each 'min' or 'max'", path="pareto.senses",
                         value=senses)
    bad = [s for s in senses if s not in SENSES]
    if bad:
        raise ModelError(f"a sense is 'min' or 'max', not {bad[0]!r}", path="pareto.senses", value=list(senses))
    return np.array([1.0 if s == "min" else -1.0 for s in senses])


def _front_2d(w: np.ndarray) -> np.ndarray:
    """Mask of the non-dominated rows of ``w`` (n, 2), both minimised, no NaN: sort by (x, y), then a
    row is on the front when its y is the smallest of its x group and smaller than every y of the
    groups before (a row of the same x and a smaller y, or of a smaller x and a y not larger,
    dominates it)."""
    order = np.lexsort((w[:, 1], w[:, 0]))
    x, y = w[order, 0], w[order, 1]
    start = np.r_[True, x[1:] != x[:-1]]                # first row of each group of equal x
    group = np.cumsum(start) - 1
    gmin = y[start]                                     # the group's smallest y (sorted by y inside)
    # the smallest y of the groups before each group; the first group has none before it
    before = np.r_[np.inf, np.minimum.accumulate(gmin)[:-1]]
    first = np.arange(gmin.size) == 0
    group_ok = first | (gmin < before)
    on = (y == gmin[group]) & group_ok[group]
    keep = np.zeros(w.shape[0], dtype=bool)
    keep[order[on]] = True
    return keep


def _front_general(w: np.ndarray) -> np.ndarray:
    """Mask of the non-dominated rows of ``w`` (n, k), all minimised, no NaN: each row against all."""
    keep = np.ones(w.shape[0], dtype=bool)
    for i in range(w.shape[0]):
        no_worse = np.all(w <= w[i], axis=1)
        if np.any(no_worse & np.any(w < w[i], axis=1)):
            keep[i] = False
    return keep
