"""The benchmark's four variants compute the same filter (agreement, not speed)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.core import compiled
from leonav_runtime.core import filter as lf
from leonav_runtime.gen import state_layout as L

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_filter.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_filter_under_test", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bench_variants_agree_on_a_short_stream(bench, tmp_path):
    lib = compiled.load()
    recs, x_true, x0, P0, params = bench.build_stream(lib, 1.0)
    gate = lf.CHI2_1DOF_999
    kinds = {name: lib.kind_id(name) for name in ("pseudorange", "doppler_rate")}
    _, _, a = bench.time_c_loop(lib, recs, x0, P0, params, 1)
    n_meas = np.count_nonzero(recs["kind"] >= 0)
    assert a["res"].n_failed == 0 and a["res"].n_gated <= 0.01 * n_meas  # a sane stream: nearly all applied
    _, d_x = bench.time_bare_c(lib.build, recs, x0, P0, params, gate, 1, tmp_path)
    np.testing.assert_allclose(d_x, a["x"], rtol=0, atol=1e-9)
    _, _, b = bench.time_casadi(recs, x0, P0, params, gate, kinds, 1)
    ekf = lf.EKF(x0, P0, params, library=lib)
    ekf.run(recs)
    np.testing.assert_allclose(b["x"], ekf.x, rtol=0, atol=1e-9)
    # the NumPy reference (finite-difference Jacobians) follows the same filter closely
    _, _, c = bench.time_numpy(recs, x0, P0, params, gate, {v: k for k, v in kinds.items()}, 1)
    pos, vel = L.X_P_ENU_SLICE, L.X_V_ENU_SLICE
    assert np.max(np.abs(c["x"][pos] - a["x"][pos])) < 0.05
    assert np.max(np.abs(c["x"][vel] - a["x"][vel])) < 0.01
    assert np.linalg.norm(a["x"][pos] - x_true[pos]) < np.linalg.norm(x0[pos] - x_true[pos])


def test_the_covariance_interval_variant_follows_the_per_sample_filter(bench):
    lib = compiled.load()
    recs, x_true, x0, P0, params = bench.build_stream(lib, 2.0)
    _, _, a = bench.time_c_loop(lib, recs, x0, P0, params, 1)
    _, _, i = bench.time_c_loop(lib, recs, x0, P0, params, 1, bench.COV_INTERVAL_S)
    assert np.isnan(i["res"].P_diag).any()           # the interval took effect
    pos = L.X_P_ENU_SLICE
    assert np.max(np.abs(i["x"][pos] - a["x"][pos])) < 1e-4
    np.testing.assert_allclose(np.diag(i["P"]), np.diag(a["P"]), rtol=1e-4)


def test_rmse_agreement_names_the_largest_relative_difference(tmp_path):
    import sys

    sys.path.insert(0, str(BENCH.parent))
    from bench_sweep import rmse_agreement

    head = "mode,count,trials,pos_rmse_m,vel_rmse_mps\n"
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "rmse.csv").write_text(head + "gps+imu,5,100,2.0,0.5\nleo-alpha+imu,5,100,10.0,1.0\n")
    (tmp_path / "b" / "rmse.csv").write_text(head + "gps+imu,5,100,2.0,0.5\nleo-alpha+imu,5,100,10.0,1.1\n")
    worst = rmse_agreement(str(tmp_path / "a"), str(tmp_path / "b"))
    assert worst["column"] == "vel_rmse_mps" and worst["mode"] == "leo-alpha+imu"
    assert abs(worst["max_rel_diff"] - 0.1) < 1e-12
    (tmp_path / "b" / "rmse.csv").write_text(head + "gps+imu,10,100,2.0,0.5\nleo-alpha+imu,5,100,10.0,1.0\n")
    with pytest.raises(ValueError, match="points differ"):
        rmse_agreement(str(tmp_path / "a"), str(tmp_path / "b"))


def test_the_wall_budget_solves_for_the_c_loop_that_meets_the_goal():
    import sys

    sys.path.insert(0, str(BENCH.parent))
    from bench_sweep import wall_budget

    # 1,000 trials x 2,000 steps at 4 us: a 8 s floor; 2 s of Python in the trials, 0.5 s in the
    # workers besides, 1 s of set-up and 3 s of results outside the pool, 2 worker processes
    r = {"sweep_wall_s": 7.0, "trials_wall_s": 6.0, "results_wall_s": 3.0, "trials_other_cpu_s": 2.0,
         "workers_outside_trials_cpu_s": 0.5, "trials_run": 1000, "imu_steps_per_trial": 2000,
         "floor_cpu_s": 8.0, "sweep_cpu_s": 11.5, "cores": 4, "processes": 2}
    b = wall_budget(r, goal_s=10.0)
    assert b["serial_s"] == pytest.approx(4.0) and b["bound_s"] == pytest.approx(8.0)
    steps = r["trials_run"] * r["imu_steps_per_trial"]
    # at the C loop it names, the serial parts plus the pool's CPU over its processes give the goal
    c_s = 1e-6 * b["c_us_for_goal"] * steps
    assert b["serial_s"] + (c_s + 2.5) / 2 == pytest.approx(10.0)
    assert b["cpu_over_floor_at_goal"] == pytest.approx((c_s + 3.5) / c_s)
    # a goal below the serial parts leaves no C loop fast enough
    none = wall_budget(r, goal_s=3.0)
    assert none["c_us_for_goal"] < 0 and none["cpu_over_floor_at_goal"] is None
