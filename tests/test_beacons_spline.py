"""beacons/spline.py against SciPy's CubicSpline (not-a-knot, the interpolant it replaces on the
command's path): the same values to the last bit, on the prediction grid and on odd grids."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from leonav_runtime.beacons.spline import NotAKnotSpline, _tridiagonal_solve


def test_bit_for_bit_the_values_of_scipys_not_a_knot_spline():
    rng = np.random.default_rng(25)
    for k in range(600):
        n, m = int(rng.integers(4, 80)), int(rng.integers(1, 7))
        if k % 3 == 0:            # the prediction grid: 0.5 s from -2 s
            x = -2.0 + 0.5 * np.arange(n)
        elif k % 3 == 1:          # uneven spacing over several scales (the pivoting branch is taken)
            x = np.cumsum(rng.random(n) + 1e-3) * rng.choice([1e-3, 1.0, 1e3])
        else:
            x = np.unique(np.round(rng.random(n) * 10.0, 6))
            if x.size < 4:
                continue
        y = rng.standard_normal((m, x.size)) * rng.choice([1.0, 1e3]) + rng.standard_normal((m, 1)) * 1e5
        t = np.concatenate([rng.uniform(x[0] - 1.0, x[-1] + 1.0, 40), x])   # knots and extrapolation too
        assert np.array_equal(NotAKnotSpline(x, y)(t), CubicSpline(x, y, axis=1)(t))


def test_a_cubic_is_reproduced_and_shapes_follow_t():
    x = np.array([0.0, 0.7, 1.5, 2.0, 3.2])
    y = np.vstack([2 * x**3 - x + 1, -x**2])
    t = np.linspace(-0.5, 3.5, 9)
    got = NotAKnotSpline(x, y)(t)
    assert np.allclose(got, np.vstack([2 * t**3 - t + 1, -t**2]), rtol=0, atol=1e-12)
    assert NotAKnotSpline(x, y)(1.0).shape == (2,) and NotAKnotSpline(x, y)(np.ones((3, 4))).shape == (2, 3, 4)


def test_the_tridiagonal_solve_and_bad_input():
    rng = np.random.default_rng(1)
    n = 12
    dl, d, du = rng.standard_normal(n - 1), rng.standard_normal(n) * 0.1, rng.standard_normal(n - 1)
    a = np.diag(d) + np.diag(dl, -1) + np.diag(du, 1)
    b = rng.standard_normal((n, 3))
    s = _tridiagonal_solve(dl.tolist(), d.tolist(), du.tolist(), b)
    assert np.allclose(a @ s, b, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="increasing"):
        NotAKnotSpline(np.array([0.0, 2.0, 1.0, 3.0]), np.zeros((1, 4)))
    with pytest.raises(ValueError, match="expected"):
        NotAKnotSpline(np.arange(3.0), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="finite"):
        NotAKnotSpline(np.arange(4.0), np.array([[0.0, np.nan, 1.0, 2.0]]))
