"""The Pareto front of a study's results (`sicomat.studies.pareto`): both engines (sort and sweep for two
objectives, every row against all for more) against the definition written out here row by row, on random
sets with many ties, NaN rows and infinities, in every combination of senses; and bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from sicomat.errors import ModelError
from sicomat.studies.pareto import _front_2d, _front_general, pareto_front


def brute_front(values, senses):
    """The definition: row i is on the front unless some row j is at least as good in every objective and
    better in one; a row with a NaN is never on it (nor does it dominate anything)."""
    rows = [list(r) for r in np.asarray(values, dtype=float)]
    better = {"min": lambda a, b: a < b, "max": lambda a, b: a > b}

    def dominates(a, b):
        no_worse = all(a[c] == b[c] or better[s](a[c], b[c]) for c, s in enumerate(senses))
        return no_worse and any(better[s](a[c], b[c]) for c, s in enumerate(senses))

    def valid(r):
        return not any(np.isnan(x) for x in r)

    return np.array([i for i, a in enumerate(rows)
                     if valid(a) and not any(valid(b) and dominates(b, a) for j, b in enumerate(rows) if j != i)],
                    dtype=int)


def random_set(rng, n, k, *, levels=6, nan_share=0.1, inf_share=0.05):
    """Integers on a few levels (many exact ties and equal rows), some NaN and ±inf entries."""
    v = rng.integers(0, levels, size=(n, k)).astype(float)
    v[rng.random((n, k)) < nan_share] = np.nan
    v[rng.random((n, k)) < inf_share] = np.inf
    v[rng.random((n, k)) < inf_share] = -np.inf
    if n > 3:
        v[n - 1] = v[0]                                 # an equal pair on purpose
    return v


@pytest.mark.parametrize("k", [1, 2, 3, 4])
@pytest.mark.parametrize("seed", range(12))
def test_front_matches_the_definition(k, seed):
    rng = np.random.default_rng(1000 * k + seed)
    n = int(rng.integers(0, 60))
    v = random_set(rng, n, k, levels=int(rng.integers(2, 9)))
    for senses in itertools.product(("min", "max"), repeat=k):
        assert_array_equal(pareto_front(v, senses), brute_front(v, senses), err_msg=f"{senses}\n{v}")


@pytest.mark.parametrize("seed", range(20))
def test_both_engines_agree_on_two_objectives(seed):
    """The sweep and the general engine, called directly (no NaN: the public function removes those rows)."""
    rng = np.random.default_rng(seed)
    v = random_set(rng, int(rng.integers(1, 80)), 2, levels=int(rng.integers(1, 10)), nan_share=0.0)
    expected = brute_front(v, ("min", "min"))
    assert_array_equal(np.flatnonzero(_front_2d(v)), expected)
    assert_array_equal(np.flatnonzero(_front_general(v)), expected)


@given(st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.5, np.inf, -np.inf, np.nan]),
                          st.sampled_from([-1.0, 0.0, 3.0, np.nan, np.inf])), max_size=25),
       st.sampled_from(list(itertools.product(("min", "max"), repeat=2))))
def test_two_objectives_property(rows, senses):
    v = np.array(rows, dtype=float).reshape(-1, 2)
    assert_array_equal(pareto_front(v, senses), brute_front(v, senses))


def test_hand_cases():
    # min x, max y: (1, 5) and (2, 6) trade off; (2, 4) is beaten by (1, 5); NaN is never on the front
    assert_array_equal(pareto_front([[1, 5], [2, 6], [2, 4], [np.nan, 9]], ["min", "max"]), [0, 1])
    # equal rows are all on the front, or all off it
    assert_array_equal(pareto_front([[1, 1], [1, 1], [2, 2], [2, 2]], ["min", "min"]), [0, 1])
    assert_array_equal(pareto_front([[1, 1], [1, 1], [0, 1]], ["min", "min"]), [2])
    # one objective: every row at the best value
    assert_array_equal(pareto_front([[3], [1], [1], [2]], ["min"]), [1, 2])
    # a lone point with an infinite objective is not dominated
    assert_array_equal(pareto_front([[0.0, np.inf]], ["min", "min"]), [0])
    assert_array_equal(pareto_front([[0.0, np.inf], [1.0, np.inf]], ["min", "min"]), [0])
    # nothing, or nothing but NaN
    assert pareto_front(np.empty((0, 2)), ["min", "max"]).size == 0
    assert pareto_front([[np.nan, 1.0]], ["min", "max"]).size == 0


@pytest.mark.parametrize("values, senses, match", [
    ([[1.0, 2.0]], ["min"], "one sense per objective"),
    ([[1.0, 2.0]], "mm", "one sense per objective"),
    ([[1.0, 2.0]], ["min", "largest"], "'min' or 'max', not 'largest'"),
    ([1.0, 2.0], ["min", "max"], "2-D array"),
    ([["a", "b"]], ["min", "max"], "must be numbers"),
])
def test_bad_input(values, senses, match):
    with pytest.raises(ModelError, match=match):
        pareto_front(values, senses)
