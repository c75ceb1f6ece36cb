"""The base station's orbit fit (base/orbit_fit.py): per-satellite radial/along/cross offsets
from the base's own rows, causal, with each epoch's common term eliminated; and, in the
simulation, served offsets that move the rover's satellites towards their true orbits."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.base.orbit_fit import fit_orbit_offsets

PRIOR = np.array([200.0, 1000.0, 150.0])


def _rows(rng, n_sat=6, n_epoch=120, curvature=0.0):
    """Synthetic rows: every satellite at every epoch (0.5 s apart), a smooth random geometry
    per satellite, an epoch term common to all rows, a constant receiver state c read through
    B; the model's change is A d plus `curvature` times the along-track offset squared."""
    d_true = rng.standard_normal((n_sat, 3)) * PRIOR
    t = np.repeat(np.arange(1, n_epoch + 1) * 0.5, n_sat)
    sat = np.tile(np.arange(100, 100 + n_sat), n_epoch)
    phase = rng.uniform(0, 2 * np.pi, (n_sat, 3))
    A = np.sin(np.array([0.05, 0.11, 0.23]) * t[:, None] + phase[sat - 100]) * np.array([0.5, 0.05, 0.3])
    B = np.stack([np.cos(0.01 * t + sat), np.ones_like(t)], axis=1)   # column 1: the epoch's own term
    sigma = np.full(t.size, 0.02)
    c_true = np.array([0.3, 5.0])

    def change(index, d):
        return np.einsum("ni,ni->n", A[index], d) + curvature * d[:, 1] ** 2

    def linearize(index, d):
        J = A[index].copy()
        J[:, 1] += 2.0 * curvature * d[:, 1]
        return change(index, d), J
    all_rows = np.arange(t.size)
    common = rng.standard_normal(n_epoch).repeat(n_sat) * 3.0
    residual = change(all_rows, d_true[sat - 100]) + B @ c_true + common + sigma * rng.standard_normal(t.size)
    group = np.rint(t * 1e3).astype(np.int64)
    return dict(sat_id=sat, t=t, group=group, residual=residual, sigma=sigma, B=B, linearize=linearize), d_true


def _fit(rows, **kw):
    return fit_orbit_offsets(**rows, prior_sigma_rac_m=PRIOR, prior_sigma_common=np.array([1.0, 10.0]),
                             t_serve=np.arange(5.0, 60.5, 5.0), **kw)


def test_the_fit_recovers_the_offsets_within_its_covariance():
    z = []
    for seed in range(8):
        rows, d_true = _rows(np.random.default_rng(seed))
        fit = _fit(rows)
        err = fit.offsets_rac_m[-1] - d_true
        z.append(np.linalg.solve(np.linalg.cholesky(fit.cov_rac_m2[-1]), err[:, :, None])[:, :, 0])
        assert np.all(np.sqrt(np.einsum("nii->ni", fit.cov_rac_m2[-1])) < 0.2 * PRIOR)   # informative
    z = np.concatenate(z).ravel()
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.3          # the covariance is the error's (144 normalised errors)


def test_the_epoch_term_and_a_column_it_holds_are_eliminated():
    rows, d_true = _rows(np.random.default_rng(1))
    fit = _fit(rows)
    shifted = dict(rows, residual=rows["residual"] + 1e3 * np.sin(rows["group"].astype(float)))   # epoch terms
    np.testing.assert_allclose(_fit(shifted).offsets_rac_m, fit.offsets_rac_m, atol=1e-6)


def test_the_fit_is_causal():
    rows, _ = _rows(np.random.default_rng(2))
    fit = _fit(rows)
    later = dict(rows, residual=np.where(rows["t"] > 30.0, rows["residual"] + 50.0 * rows["B"][:, 0], rows["residual"]))
    other = _fit(later)
    k = np.searchsorted(fit.t_serve, 30.0)
    np.testing.assert_allclose(other.offsets_rac_m[:k + 1], fit.offsets_rac_m[:k + 1], atol=1e-9)
    assert not np.allclose(other.offsets_rac_m[-1], fit.offsets_rac_m[-1])
    before, cov = fit.at(np.array([100, 101]), np.array([4.9, 5.0]))
    assert np.all(before[0] == 0) and np.allclose(cov[0], np.diag(PRIOR**2))   # nothing served yet: the prior
    np.testing.assert_allclose(before[1], fit.offsets_rac_m[0, 1])


def test_relinearizing_follows_a_model_that_curves():
    """A quadratic term in the along-track offset: one linearization about zero is biased by it;
    the iterated fit is not."""
    rows, d_true = _rows(np.random.default_rng(3), curvature=2e-5)
    once = _fit(rows, iterations=1)
    iterated = _fit(rows)
    sd = np.sqrt(np.einsum("nii->ni", iterated.cov_rac_m2[-1]))
    z_once = np.abs(once.offsets_rac_m[-1] - d_true) / sd
    z_iter = np.abs(iterated.offsets_rac_m[-1] - d_true) / sd
    assert np.max(z_iter) < 4.0 < np.max(z_once)


def test_bad_input_is_named():
    rows, _ = _rows(np.random.default_rng(4))
    with pytest.raises(ValueError, match="must agree"):
        _fit(dict(rows, sigma=rows["sigma"][:-1]))
    with pytest.raises(ValueError, match="finite"):
        _fit(dict(rows, residual=np.where(rows["t"] == 1.0, np.nan, rows["residual"])))
    with pytest.raises(ValueError, match="never measured"):
        _fit(rows).at(np.array([7]), np.array([10.0]))


def test_satellites_out_of_view_leave_the_solve_without_losing_what_they_said():
    """Half the satellites set at 30 s, the others rise then: retiring the first half after 5 s
    without rows (their information about the common states kept, marginalized) serves the
    satellites in view exactly what a fit that keeps every satellite in the solve serves; a
    retired satellite's offsets stay as last fitted (a rover no longer sees it)."""
    rows, _ = _rows(np.random.default_rng(5))
    first = rows["sat_id"] < 103
    keep = np.where(first, rows["t"] <= 30.0, rows["t"] > 30.0)
    index = np.flatnonzero(keep)
    linearize = rows["linearize"]
    pass_rows = {k: (v[keep] if isinstance(v, np.ndarray) else v) for k, v in rows.items()}
    pass_rows["linearize"] = lambda i, d: linearize(index[i], d)
    kept = _fit(pass_rows, retire_after_s=1e9)
    retired = _fit(pass_rows, retire_after_s=5.0)
    np.testing.assert_allclose(retired.offsets_rac_m[:, 3:], kept.offsets_rac_m[:, 3:], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(retired.cov_rac_m2[:, 3:], kept.cov_rac_m2[:, 3:], rtol=1e-6, atol=1e-6)
    # the set satellites: the same until they leave the solve (5 s after their last row), then frozen
    before = retired.t_serve <= 35.0
    np.testing.assert_allclose(retired.offsets_rac_m[before], kept.offsets_rac_m[before], rtol=1e-6, atol=1e-6)
    k30 = np.searchsorted(retired.t_serve, 30.0)
    np.testing.assert_array_equal(retired.offsets_rac_m[-1, :3], retired.offsets_rac_m[k30 + 2, :3])
