"""The observability analysis beyond the rank: measurement weighting by R, the index, sigma,
condition, time to target and the weakest directions against a direct computation from the
information matrix (inverse and eigen-decomposition instead of the SVD of the square root), the
linearisation points and the noise-free parameters, and the CSV rows."""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from leonav.codegen import observability as ob

from leonav_runtime import observability as ro
from leonav_runtime.core import compiled


@functools.cache
def _case(mode: str = "gps+leo-alpha+imu", motion: str = "accelerating") -> ob.CaseResult:
    return ob.analyze_case(mode, ro.analysis_modes()[mode], motion, n_sats=ob.N_SATS, n_draws=1)


def _records(c: ob.CaseResult, lib, r_scale: float = 1.0):
    tr = c.trajectory
    kinds = [lib.kind_id(m[1]) for m in tr.measurements]
    steps = [m[0] for m in tr.measurements]
    aux = np.array([m[2] for m in tr.measurements])
    return ro.trajectory_records(tr.t_s, tr.x, tr.u, tr.dt_s, kinds, steps, aux, r_scale * c.row_scale**2)


def _reference(acc: ro.Accumulated, scales: np.ndarray, vague: float = ro.VAGUE) -> dict:
    """Index, sigma and eigenvalues from the scaled current-state information M = S Phi^-T W Phi^-1 S
    by inverses and eigh (no SVD of the square root)."""
    out = {"index": [], "sigma": [], "eig": []}
    n = scales.size
    for R, Phi in zip(acc.R, acc.Phi):
        Pinv = np.linalg.inv(Phi)
        M = np.diag(scales) @ Pinv.T @ (R.T @ R) @ Pinv @ np.diag(scales)
        out["index"].append(1.0 - np.diag(np.linalg.inv(np.eye(n) + M)))      # unit prior in scaled units
        out["sigma"].append(scales * np.sqrt(np.diag(np.linalg.inv(M + np.eye(n) / vague**2))))
        out["eig"].append(np.sort(np.linalg.eigvalsh((M + M.T) / 2))[::-1])
    return {k: np.array(v) for k, v in out.items()}


def test_measurements_are_weighted_by_one_over_their_variance():
    """W = sum (H Phi)^T (H Phi) / R: every R times 4 is the information over 4, nothing else changes."""
    lib = compiled.load()
    c = _case()
    recs, x_lin = _records(c, lib)
    recs4, _ = _records(c, lib, 4.0)
    a1 = ro.accumulate(recs, x_lin, c.trajectory.params, library=lib)
    a4 = ro.accumulate(recs4, x_lin, c.trajectory.params, library=lib)
    W1, W4 = a1.R[-1].T @ a1.R[-1], a4.R[-1].T @ a4.R[-1]
    np.testing.assert_allclose(W4, W1 / 4.0, rtol=1e-9, atol=1e-12 * np.abs(W1).max())
    assert a1.n_meas[-1] == a4.n_meas[-1] == len(c.trajectory.measurements)


def test_measurements_without_a_variance_or_with_non_finite_aux_are_skipped():
    lib = compiled.load()
    c = _case()
    recs, x_lin = _records(c, lib)
    base = ro.accumulate(recs, x_lin, c.trajectory.params, library=lib)
    meas = np.flatnonzero(recs["kind"] >= 0)
    bad = recs.copy()
    bad["R"][meas[0]] = 0.0
    bad["aux"][meas[1], 0] = np.nan
    got = ro.accumulate(bad, x_lin, c.trajectory.params, library=lib)
    assert got.n_meas[-1] == base.n_meas[-1] - 2
    assert np.all(np.isfinite(got.R[-1]))
    # as if the two records were not in the stream at all
    keep = np.ones(recs.size, bool)
    keep[meas[:2]] = False
    ref = ro.accumulate(recs[keep], x_lin[keep], c.trajectory.params, library=lib)
    W, W_ref = got.R[-1].T @ got.R[-1], ref.R[-1].T @ ref.R[-1]
    np.testing.assert_allclose(W, W_ref, rtol=1e-9, atol=1e-12 * np.abs(W_ref).max())
    assert not np.allclose(W, base.R[-1].T @ base.R[-1], rtol=1e-9)   # and they did carry information


def test_analysis_matches_the_information_matrix_in_physical_units():
    """Scales != 1 (a prior sigma per component): index, sigma, rank, condition and the weakest
    directions' information agree with the direct computation."""
    lib = compiled.load()
    c = _case()
    recs, x_lin = _records(c, lib)
    acc = ro.accumulate(recs, x_lin, c.trajectory.params, library=lib)
    ndx = acc.R.shape[1]
    scales = np.geomspace(0.05, 20.0, ndx)
    names = [f"c{i}" for i in range(ndx)]
    out = ro.analyze_information(acc, scales, names)
    ref = _reference(acc, scales)
    np.testing.assert_allclose(out["index"], ref["index"], atol=1e-7)
    np.testing.assert_allclose(out["singular_values"] ** 2, ref["eig"], rtol=1e-6, atol=1e-9 * ref["eig"].max())
    fin = out["sigma_info"] <= 10 * scales   # well-determined components (the rest: ill-conditioned inverse)
    assert fin[-1].sum() >= 6
    # two inverses of one ill-conditioned matrix (the SVD of its root against eigh): ~1e-5 apart
    np.testing.assert_allclose(out["sigma_info"][fin], ref["sigma"][fin], rtol=1e-4)
    r = int(out["rank"][-1])
    sv = np.sqrt(np.clip(ref["eig"][-1], 0, None))
    assert out["condition_observable"][-1] == pytest.approx(sv[0] / sv[r - 1], rel=1e-3)
    weakest = [w for w in out["weakest_final"] if not w["unobservable"]]
    assert weakest[0]["information"] == pytest.approx(ref["eig"][-1][r - 1], rel=1e-3)   # eigh of W vs the SVD of its root: 1e-5 apart here


def test_rank_and_condition_do_not_depend_on_the_unit_of_the_information():
    """A full-rank history and the same history in units 1e14 times larger (information 1e-28 times
    smaller, every singular value below 1e-12): same rank, condition = largest / smallest singular value."""
    t = np.arange(1.0, 4.0)
    sv = np.array([3.0, 1.0, 0.01])
    for unit in (1.0, 1e-14):
        R = np.array([np.diag(sv * math.sqrt(k) * unit) for k in t])
        acc = ro.Accumulated(t, R, np.repeat(np.eye(3)[None], t.size, 0), np.arange(t.size))
        out = ro.analyze_information(acc, np.ones(3), ["a", "b", "c"])
        assert np.all(out["rank"] == 3), unit
        np.testing.assert_allclose(out["condition"], 300.0, rtol=1e-9)


def test_a_target_met_at_the_first_output_time_and_a_target_on_a_block():
    t = np.arange(1.0, 4.0)
    R = np.array([np.diag([10.0 * math.sqrt(k), 0.1 * math.sqrt(k)]) for k in t])   # sigma 0.1 / sqrt(k), 10 / sqrt(k)
    acc = ro.Accumulated(t, R, np.repeat(np.eye(2)[None], t.size, 0), np.arange(t.size))
    out = ro.analyze_information(acc, np.ones(2), ["a", "b"], targets=np.array([0.5, 1.0]))
    assert out["time_to_target_s"][0] == 1.0          # 0.1 <= 0.5 from the first output on
    assert out["time_to_target_s"][1] == math.inf      # 10/sqrt(3) > 1 to the end

    lib = compiled.load()
    c = _case()
    recs, x_lin = _records(c, lib)
    ndx = int(lib.layout.NDX)
    run = ro.run_information(recs, x_lin, c.trajectory.params, np.ones(ndx), targets={"dp": 0.25}, library=lib)
    dp = [i for i, n in enumerate(run["components"]) if n.startswith("dp_")]
    assert len(dp) == 3 and np.all(run["targets"][dp] == 0.25)
    assert np.sum(run["targets"] == 0.25) == 3


def test_imu_records_are_linearised_at_the_start_of_their_interval():
    from leonav_runtime.core import records

    rate = 100.0
    t_imu = np.arange(0, 11) / rate
    x_true = np.arange(11, dtype=float)[:, None] * np.ones((1, 4))
    imu = records.imu_records(t_imu[1:], np.zeros((10, 3)), np.zeros((10, 3)), dt_s=1 / rate)
    meas = records.measurement_records(t_imu[[3, 7]], 1, 0.0, np.ones(2), np.zeros((2, records.NAUX)))
    recs = records.merge_records(imu, meas)
    x_lin = ro.linearisation_states(recs, t_imu, x_true, rate)
    k = np.rint(recs["t"] * rate).astype(int)
    is_imu = recs["kind"] < 0
    np.testing.assert_array_equal(x_lin[is_imu, 0], k[is_imu] - 1)   # interval (t_k-1, t_k]: its start
    np.testing.assert_array_equal(x_lin[~is_imu, 0], k[~is_imu])     # a measurement: its own time


def test_without_process_noise_zeroes_every_noise_density_and_only_those():
    L = compiled.load_layout(compiled.GEN_DIR)
    p = np.arange(1.0, len(L.P_NAMES) + 1.0)
    q = ro.without_process_noise(p, L)
    for i, name in enumerate(L.P_NAMES):
        noise = name in ("vrw", "arw") or name.endswith("_rw") or name.startswith("q_")
        assert (q[i] == 0.0) == noise, name
    assert {"acc_bias_rw", "gyro_bias_rw", "q_cdt", "q_blo"} <= {n for n, v in zip(L.P_NAMES, q) if v == 0}


def test_structural_csv_rows_follow_the_header():
    from leonav_runtime.observability.report import STRUCTURAL_HEADER, structural_rows

    s = {"mode": "fix+imu", "motion": "static", "rank": 12, "n_states": 22, "weak": 1, "nullity": 10,
         "steps_to_saturate": 4, "gap": 1e9, "gap_clear": True, "draws_agree": True,
         "unobservable_directions": [{"text": "dtheta_z"}], "weak_directions": [],
         "weakest_observable": {"text": "db_g_z", "sigma": 0.01, "sigma_unit": "rad/s"}}
    row = dict(zip(STRUCTURAL_HEADER, structural_rows([s])[0]))
    assert (row["rank"], row["n_states"], row["nullity"], row["weak"]) == (12, 22, 10, 1)
    assert row["unobservable_directions"] == "dtheta_z" and row["weakest_sigma"] == 0.01
