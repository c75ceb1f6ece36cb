"""Chi-square upper quantiles for residual tests, without SciPy on the import path.

`chi2_upper(dof, alpha)` is the x with P(X > x) = alpha for X ~ chi-square(dof): the
regularized incomplete gamma function (series below a + 1, Lentz continued fraction above,
as in Abramowitz & Stegun 6.5.29 / 6.5.31) inverted by bisection. Matches
scipy.stats.chi2.isf to 1e-10 relative (tests/test_spp.py). Cached per (dof, alpha).
"""
from __future__ import annotations

import math
from functools import lru_cache

_EPS = 1e-15
_TINY = 1e-300


def _upper_regularized_gamma(a: float, x: float) -> float:
    """Q(a, x) = Gamma(a, x) / Gamma(a)."""
    if x <= 0.0:
        return 1.0
    log_front = -x + a * math.log(x) - math.lgamma(a)
    if x < a + 1.0:  # series for P(a, x)
        term = total = 1.0 / a
        n = a
        for _ in range(10000):
            n += 1.0
            term *= x / n
            total += term
            if abs(term) < abs(total) * _EPS:
                break
        return 1.0 - total * math.exp(log_front)
    b = x + 1.0 - a  # continued fraction for Q(a, x) (modified Lentz)
    c = 1.0 / _TINY
    d = 1.0 / b
    h = d
    for i in range(1, 10000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = _TINY if abs(d) < _TINY else d
        c = b + an / c
        c = _TINY if abs(c) < _TINY else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < _EPS:
            break
    return h * math.exp(log_front)


def chi2_sf(x: float, dof: int) -> float:
    """P(X > x) for a chi-square variable with `dof` degrees of freedom."""
    return _upper_regularized_gamma(dof / 2.0, x / 2.0)


@lru_cache(maxsize=None)
def chi2_upper(dof: int, alpha: float) -> float:
    """x with P(X > x) = alpha, X ~ chi-square(dof) (dof >= 1)."""
    if dof < 1 or not 0.0 < alpha < 1.0:
        raise ValueError(f"chi2_upper: dof {dof} must be >= 1 and alpha {alpha} in (0, 1)")
    lo, hi = 0.0, max(10.0, 2.0 * dof)
    while chi2_sf(hi, dof) > alpha:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_sf(mid, dof) > alpha:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12 * hi:
            break
    return 0.5 * (lo + hi)
