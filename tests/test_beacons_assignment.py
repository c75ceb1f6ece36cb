"""beacons/assignment.py against SciPy's linear_sum_assignment (the reference it replaces on the
command's path): the same assignment, ties included, on square and rectangular matrices."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment as scipy_lsa

from leonav_runtime.beacons.assignment import linear_sum_assignment


def _matrices(rng, count: int):
    for k in range(count):
        nr, nc = int(rng.integers(0, 9)), int(rng.integers(0, 13))
        kind = k % 4
        if kind == 0:
            yield rng.random((nr, nc)) * 100.0
        elif kind == 1:                                 # many ties
            yield rng.integers(0, 3, (nr, nc)).astype(float)
        elif kind == 2:                                 # as associate._assign: forbidden pairs set to 1e6
            c = rng.random((nr, nc)) * 10.0
            yield np.where(c <= 5.0, c, 1e6)
        else:                                           # ties among forbidden and allowed pairs
            yield rng.integers(0, 2, (nr, nc)) * 1e6 + rng.integers(0, 2, (nr, nc))


def test_same_assignment_as_scipy_ties_included():
    rng = np.random.default_rng(25)
    for c in _matrices(rng, 4000):
        rows, cols = linear_sum_assignment(c)
        ref_rows, ref_cols = scipy_lsa(c)
        assert rows.tolist() == ref_rows.tolist() and cols.tolist() == ref_cols.tolist(), c


def test_the_total_is_the_brute_force_minimum():
    rng = np.random.default_rng(7)
    for _ in range(300):
        nr, nc = int(rng.integers(1, 5)), int(rng.integers(1, 6))
        c = rng.integers(0, 20, (nr, nc)).astype(float)
        rows, cols = linear_sum_assignment(c)
        k = min(nr, nc)
        assert len(rows) == len(cols) == k and len(set(rows)) == len(set(cols)) == k
        if nr <= nc:
            best = min(sum(c[i, p[i]] for i in range(nr)) for p in itertools.permutations(range(nc), nr))
        else:
            best = min(sum(c[p[j], j] for j in range(nc)) for p in itertools.permutations(range(nr), nc))
        assert c[rows, cols].sum() == best


def test_forbidden_pairs_and_bad_input():
    inf = np.inf
    rows, cols = linear_sum_assignment(np.array([[inf, 1.0], [2.0, inf]]))
    assert rows.tolist() == [0, 1] and cols.tolist() == [1, 0]
    with pytest.raises(ValueError, match="infeasible"):
        linear_sum_assignment(np.array([[inf, inf], [1.0, 2.0]]))
    for bad in (np.array([[np.nan, 1.0]]), np.array([[-inf, 1.0]])):
        with pytest.raises(ValueError, match="NaN or -inf"):
            linear_sum_assignment(bad)
    with pytest.raises(ValueError, match="matrix"):
        linear_sum_assignment(np.zeros(3))
    rows, cols = linear_sum_assignment(np.zeros((0, 4)))
    assert rows.size == cols.size == 0
