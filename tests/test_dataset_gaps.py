"""IMU gaps and gate lockouts on the real CPET run 3 (first 90 s), scored against its ground truth.

A gap is cut out of the IMU file's samples; a lockout is forced by moving every fix after
t = 60 s by 15 m east (as a receiver switching datum or a multipath jump would). The
reference for the lockout case is the ground truth moved the same way after the jump.
"""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.dataset import load, resets, runner, scoring, spec
from leonav_runtime.gen import state_layout as L
from tests.conftest import shared_file

T_END_S = 90.0
MODE = "fix+imu+nhc+zupt"


@pytest.fixture(scope="module")
def cpet():
    shared_file("gnss_ins/cpet_run3_navego/imu_planetary_200hz.csv")
    s = spec.load_spec("cpet_run3")
    s["gnss"]["sigma_scale"] = 0.35        # about what "auto" finds; one pass keeps the test short
    return s, load.load(s)


def _cut(ds: load.Dataset, start_s: float, length_s: float) -> load.Dataset:
    """The dataset without the IMU samples inside (start, start + length) s of the run axis."""
    t = ds.imu_on_axis(0.36).t
    keep = ~((t > start_s) & (t < start_s + length_s))
    out = load.Dataset(ds.spec, ds.t0_unix, ds.origin, ds.imu_raw_t[keep],
                       load.ImuSamples(ds.imu.t[keep], ds.imu.w_b_radps[keep], ds.imu.f_b_mps2[keep]),
                       ds.fixes, ds.reference, dict(ds.counts), list(ds.notes))
    return out


def _horizontal(res, ref) -> np.ndarray:
    _, x, _ = scoring.states_at(res, ref.t)
    e = x[:, L.X_P_ENU_SLICE] - ref.p_enu_m
    return np.where(ref.t <= T_END_S, np.hypot(e[:, 0], e[:, 1]), np.nan)


@pytest.fixture(scope="module")
def no_gap(cpet):
    _, ds = cpet
    prep = runner.prepare(ds, t_end_s=T_END_S)
    return _horizontal(runner.run_mode(prep, MODE)[1], ds.reference)


@pytest.mark.parametrize("start_s, length_s", [(30.0, 0.5), (50.0, 5.0)])
def test_imu_gap_is_bridged_with_bounded_error_and_counted(cpet, no_gap, start_s, length_s):
    """Both cuts sent the one-IMU-step bridge of old off: 13 m and 19 m after the gap."""
    _, ds = cpet
    cut = _cut(ds, start_s, length_s)
    prep = runner.prepare(cut, t_end_s=T_END_S)
    _, res, _, report = runner.run_mode(prep, MODE)
    assert prep.report["imu_gaps"]["long"] == 1
    assert prep.report["imu_gaps"]["long_seconds"] == pytest.approx(length_s, abs=0.011)
    assert report["resets"] == {"imu_gap": 1, "gate_lockout": 0}
    t_fix = prep.streams["fix"]["t"]
    fixes_inside = np.sum((t_fix > start_s) & (t_fix < start_s + length_s))
    assert report["measurements_dropped_in_imu_gaps"] == fixes_inside
    assert res.n_failed == 0
    err = _horizontal(res, ds.reference)
    ok = np.isfinite(err) & np.isfinite(no_gap)
    rmse, rmse0 = np.sqrt(np.mean(err[ok] ** 2)), np.sqrt(np.mean(no_gap[ok] ** 2))
    assert rmse < rmse0 + 0.25 and rmse < 0.9
    after = ds.reference.t > start_s + length_s
    assert np.nanmax(err[after]) < 3.0


def test_gate_lockout_recovers_and_is_counted(cpet):
    _, ds = cpet
    jump = np.array([15.0, 0.0, 0.0])
    fx = ds.fixes
    moved = fx.p_enu_m + np.where((fx.t >= 60.0)[:, None], jump, 0.0)
    ds2 = load.Dataset(ds.spec, ds.t0_unix, ds.origin, ds.imu_raw_t, ds.imu,
                       type(fx)(fx.t, moved, fx.sigma_enu_m, fx.v_en_mps), ds.reference, ds.counts, ds.notes)
    prep = runner.prepare(ds2, t_end_s=T_END_S)
    ref_moved = load.Reference(ds.reference.t, ds.reference.p_enu_m + np.where(
        (ds.reference.t >= 60.0)[:, None], jump, 0.0), None)
    late = (ds.reference.t > 75.0) & (ds.reference.t <= T_END_S)
    prep.lockout_fixes = 0                    # without the recovery: every later fix gated
    _, res, _, rep = runner.run_mode(prep, MODE)
    fix_late = (res.kind == L.MEAS_POS_E) & (res.t > 61.0)
    assert rep["resets"]["gate_lockout"] == 0
    assert np.mean(res.status[fix_late] == 1) > 0.9
    assert np.nanmin(_horizontal(res, ref_moved)[late]) > 5.0
    prep.lockout_fixes = 5
    _, res, _, rep = runner.run_mode(prep, MODE)
    assert rep["resets"]["gate_lockout"] >= 1 and res.n_failed == 0
    fix_late = (res.kind == L.MEAS_POS_E) & (res.t > 70.0)
    assert np.mean(res.status[fix_late] == 1) < 0.05
    assert np.nanmax(_horizontal(res, ref_moved)[late]) < 2.0


def test_covariance_reset_keeps_p_symmetric_positive():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(L.NDX, L.NDX))
    P = a @ a.T * 1e-4
    P0 = np.diag(np.full(L.NDX, 0.5))
    out = resets.reset_covariance(P, P0, L)
    np.testing.assert_allclose(out, out.T)
    assert np.linalg.eigvalsh(out).min() > -1e-12
    dp = L.DX_DP_SLICE
    np.testing.assert_allclose(out[dp, dp], P0[dp, dp])
    assert np.all(out[dp, L.DX_DB_A_SLICE] == 0)
    th = np.arange(L.DX_DTHETA_SLICE.start, L.DX_DTHETA_SLICE.stop)
    assert np.all(np.diag(out)[th] >= 0.5 - 1e-12)
    np.testing.assert_allclose(out[L.DX_DB_G_SLICE, L.DX_DB_G_SLICE], P[L.DX_DB_G_SLICE, L.DX_DB_G_SLICE])


def test_auto_sigma_scale_is_clamped_and_not_taken_from_a_diverged_pass(cpet):
    s, ds = cpet
    s["gnss"]["sigma_scale"] = "auto"
    try:
        prep = runner.prepare(ds, t_end_s=T_END_S)
        rep = prep.report["fix_sigma_scale"]
        raw, used = rep["first_pass_factors"], rep["value"]
        assert rep["first_pass_lockout_resets"] == 0 and "NOT applied" not in rep["source"]
        for k in runner.FIX_KINDS:
            assert used[k] == pytest.approx(min(max(raw[k], 0.2), 5.0))
        # the same run with every fix after 60 s moved 15 m: the first pass locks out -> no scale
        fx = ds.fixes
        moved = fx.p_enu_m + np.where((fx.t >= 60.0)[:, None], [15.0, 0.0, 0.0], 0.0)
        ds2 = load.Dataset(ds.spec, ds.t0_unix, ds.origin, ds.imu_raw_t, ds.imu,
                           type(fx)(fx.t, moved, fx.sigma_enu_m, fx.v_en_mps), ds.reference, ds.counts, ds.notes)
        rep2 = runner.prepare(ds2, t_end_s=T_END_S).report["fix_sigma_scale"]
        assert rep2["first_pass_lockout_resets"] >= 1 and "NOT applied" in rep2["source"]
        assert rep2["value"] == {k: 1.0 for k in runner.FIX_KINDS}
        assert max(rep2["first_pass_factors"].values()) > 1.5 * max(raw.values())
    finally:
        s["gnss"]["sigma_scale"] = 0.35
