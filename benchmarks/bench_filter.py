"""Filter speed, side by side: C loop vs CasADi-from-Python vs NumPy vs bare generated C.

Scenario: receiver at rest, 100 Hz IMU, 10 Hz GPS epochs of 8 pseudoranges, 1 Hz
Starlink epochs of 10 Doppler-rates, over `--seconds` (default 20 s). The figure of merit
is process CPU time per IMU step (CPU rather than wall time, so other load on the machine
does not count; best of several repeats): the whole stream's time divided by the number of IMU records,
so each IMU step carries its share of the update epochs.

  (a) C loop:  leonav_run over the whole stream (one ctypes call, outputs per record)
  (b) CasADi:  the same casadi.Functions (codegen.functions.build_functions) called per
               record from Python, gating in Python
  (c) NumPy:   benchmarks/numpy_ekf.py, the same filter in plain NumPy
  (d) bare C:  benchmarks/bench_bare_loop.c, the generated functions in a minimal C
               loop without the driver, compiled here with the same flags

Then the paper sweep's CPU against its C floor (benchmarks/bench_sweep.py, `--sweep-trials`).

Run: `leonav bench [--out DIR]` or `python benchmarks/bench_filter.py [--out DIR]`.
"""
from __future__ import annotations

import math
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BENCH_DIR = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH_DIR))

from numpy_ekf import NumpyEKF, ecef_from_geodetic, enu_axes  # noqa: E402

from leonav_runtime.core import compiled, records  # noqa: E402
from leonav_runtime.core import filter as lf  # noqa: E402
from leonav_runtime.gen import constants as K  # noqa: E402
from leonav_runtime.gen import state_layout as L  # noqa: E402
from leonav_runtime.common.output import results_dir, write_json  # noqa: E402
from leonav_runtime.core.params import build_params  # noqa: E402

LAT, LON, H = math.radians(40.0), math.radians(-83.0), 200.0
IMU_HZ, GPS_HZ, LEO_HZ = 100.0, 10.0, 1.0
COV_INTERVAL_S = 0.1   # (a'): the covariance propagated once per 0.1 s (leonav_run's covariance interval)
N_GPS, N_LEO = 8, 10
PR_SIGMA_M, DR_SIGMA_HZPS = 3.0, 0.5


def _sky(n: int, range_m: float, el_min_deg: float, seed: int) -> list[np.ndarray]:
    """Line-of-sight unit vectors (ENU) spread in azimuth, elevations el_min..80 deg."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        az = 2 * math.pi * (i + rng.uniform(0, 0.5)) / n
        el = math.radians(rng.uniform(el_min_deg, 80.0))
        out.append(range_m * np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)]))
    return out


def build_stream(lib: compiled.Library, seconds: float, seed: int = 1):
    """(records, x_true, x0, P0, params) of the benchmark scenario."""
    rng = np.random.default_rng(seed)
    params = np.array(build_params(LAT, LON, H))
    x_true = np.zeros(L.NX)
    x_true[L.X_Q_NB] = 1.0  # body axes aligned with ENU
    dt = 1.0 / IMU_HZ
    u0 = lf.stationary_imu(x_true, dt, params, lib)
    n = int(round(seconds * IMU_HZ))
    t = np.arange(1, n + 1) * dt
    dth, dv = L.U_DTHETA_B_SLICE, L.U_DVEL_B_SLICE
    parts = [records.imu_records(t, u0[dth] + rng.normal(0, params[L.P_ARW] * math.sqrt(dt), (n, L.U_DTHETA_B_SIZE)),
                                 u0[dv] + rng.normal(0, params[L.P_VRW] * math.sqrt(dt), (n, L.U_DVEL_B_SIZE)))]
    r0, C = ecef_from_geodetic(LAT, LON, H), enu_axes(LAT, LON)
    truth = lf.EKF(x_true, np.eye(L.NDX), params, library=lib)
    t_gps = np.arange(1, int(seconds * GPS_HZ) + 1) / GPS_HZ
    for sat, los in enumerate(_sky(N_GPS, 2.2e7, 10.0, seed)):
        aux = np.zeros(records.NAUX)
        aux[L.AUX_R_S_ECEF_SLICE] = r0 + C @ los
        z = truth.h("pseudorange", aux)[0] + rng.normal(0, PR_SIGMA_M, t_gps.size)
        parts.append(records.measurement_records(t_gps, lib.kind_id("pseudorange"), z, PR_SIGMA_M**2, aux, sat))
    t_leo = np.arange(1, int(seconds * LEO_HZ) + 1) / LEO_HZ
    for sat, los in enumerate(_sky(N_LEO, 1.0e6, 25.0, seed + 1)):
        aux = np.zeros(records.NAUX)
        r_S = r0 + C @ los
        along = np.cross(r_S, [0.0, 0.0, 1.0]) + 0.3 * np.cross(r_S, C[:, 0])
        aux[L.AUX_R_S_ECEF_SLICE] = r_S
        aux[L.AUX_V_S_ECEF_SLICE] = 7.6e3 * along / np.linalg.norm(along)
        aux[L.AUX_A_S_ECEF_SLICE] = -K.WGS84_GM_M3PS2 * r_S / np.linalg.norm(r_S) ** 3
        aux[L.AUX_F_B_SLICE] = u0[dv] / dt  # specific force of the receiver at rest, body
        z = truth.h("doppler_rate", aux)[0] + rng.normal(0, DR_SIGMA_HZPS, t_leo.size)
        parts.append(records.measurement_records(t_leo, lib.kind_id("doppler_rate"), z, DR_SIGMA_HZPS**2, aux,
                                                 100 + sat))
    sd = {"dp": 10.0, "dv": 0.5, "dtheta": 0.01, "db_a": 0.05, "db_g": 1e-4, "dc_dt": 100.0, "dc_ddt": 1.0,
          "db_lo": 10.0}  # prior standard deviations per error-state block (SI)
    P0 = np.zeros((L.NDX, L.NDX))
    for name, s in sd.items():
        block = getattr(L, f"DX_{name.upper()}_SLICE")
        P0[block, block] = np.eye(block.stop - block.start) * s**2
    x0 = x_true.copy()
    x0[L.X_P_ENU_SLICE] = [3.0, -2.0, 1.0]
    return records.merge_records(*parts), x_true, x0, P0, params


def _best(fn, repeats: int) -> tuple[float, list[float]]:
    times = []
    for _ in range(repeats):
        start = time.process_time()  # CPU time: robust to other processes on a shared machine
        fn()
        times.append(time.process_time() - start)
    return min(times), times


def time_c_loop(lib, recs, x0, P0, params, repeats, covariance_interval_s: float = 0.0):
    final = {}

    def once():
        ekf = lf.EKF(x0, P0, params, library=lib)
        final["res"] = ekf.run(recs, covariance_interval_s=covariance_interval_s)
        final["x"], final["P"] = ekf.x, ekf.P
    best, times = _best(once, repeats)
    return best, times, final


def time_casadi(recs, x0, P0, params, gate, kinds: dict[str, int], repeats):
    import casadi as ca
    from leonav.codegen.functions import build_functions

    fns = {f.name(): f for f in build_functions()}
    kind_fn = {k: fns[f"leonav_update_{name}"] for name, k in kinds.items()}
    predict = fns["leonav_predict"]
    final = {}

    def once():
        x, P, p = ca.DM(x0), ca.DM(P0), ca.DM(params)
        for r in recs:
            if r["kind"] == records.KIND_IMU:
                x, P, _, _ = predict(x, P, r["u"], r["dt"], p)
            else:
                x_post, P_post, _, S, nis = kind_fn[int(r["kind"])](x, P, r["z"], r["R"], r["aux"], p)
                if float(S) > 0 and not float(nis) > gate:
                    x, P = x_post, P_post
        final["x"] = np.array(x).ravel()
    best, times = _best(once, repeats)
    return best, times, final


def time_numpy(recs, x0, P0, params, gate, suffix_of, repeats):
    final = {}

    def once():
        ekf = NumpyEKF(x0, P0, params, gate)
        for r in recs:
            if r["kind"] == records.KIND_IMU:
                ekf.predict(r["u"], float(r["dt"]))
            else:
                ekf.update(suffix_of[int(r["kind"])], float(r["z"]), float(r["R"]), r["aux"])
        final["x"] = ekf.x
    best, times = _best(once, repeats)
    return best, times, final


def time_bare_c(build: compiled.BuildInfo, recs, x0, P0, params, gate, repeats, tmp: Path):
    src = BENCH_DIR / "bench_bare_loop.c"
    exe = tmp / "bench_bare_loop"
    gen_c = {s.stem for s in compiled.sources() if s.parent.name == "c"}   # the generated functions' objects
    gen_objects = [o for o in build.objects if o.name.rsplit("-", 1)[0] in gen_c]
    argv = (shlex.split(build.compiler) + build.cflags + [f"-I{compiled.GEN_DIR}", f"-I{compiled.CSRC_DIR}",
            str(src)] + [str(o) for o in gen_objects] + ["-o", str(exe), "-lm"])
    subprocess.run(argv, check=True, capture_output=True, text=True)
    (tmp / "records.bin").write_bytes(np.ascontiguousarray(recs).tobytes())
    (tmp / "init.bin").write_bytes(np.concatenate([x0, np.asfortranarray(P0).ravel(order="F"), params]).tobytes())
    out = subprocess.run([str(exe), str(tmp / "records.bin"), str(tmp / "init.bin"), str(repeats), repr(gate)],
                         check=True, capture_output=True, text=True).stdout
    lines = dict(line.split(" ", 1) for line in out.strip().splitlines())
    return float(lines["best_s"]), np.array([float(v) for v in lines["x"].split()])


def code_size(paths: list[Path]) -> dict:
    return {p.name: {"bytes": p.stat().st_size, "lines": p.read_text().count("\n")} for p in paths}


def run_benchmark(seconds: float = 20.0, repeats: int = 20, py_repeats: int = 2, out: str | None = None,
                  sweep_trials: int = 100) -> dict:
    """Run all four variants, print the table, then (sweep_trials > 0) the paper sweep with that
    many trials per point against its C floor (bench_sweep.py); write bench.json into the results
    folder."""
    folder = results_dir(out, "bench")
    lib = compiled.load()
    kinds = {name: lib.kind_id(name) for name in ("pseudorange", "doppler_rate")}
    recs, x_true, x0, P0, params = build_stream(lib, seconds)
    n_imu = int(np.count_nonzero(recs["kind"] == records.KIND_IMU))
    gate = lf.CHI2_1DOF_999
    print(f"stream: {seconds:g} s, {recs.size} records: {n_imu} IMU ({IMU_HZ:g} Hz), "
          f"{np.count_nonzero(recs['kind'] == lib.kind_id('pseudorange'))} pseudoranges ({N_GPS} @ {GPS_HZ:g} Hz), "
          f"{np.count_nonzero(recs['kind'] == lib.kind_id('doppler_rate'))} Doppler-rates ({N_LEO} @ {LEO_HZ:g} Hz)")

    with tempfile.TemporaryDirectory(prefix="leonav-bench-") as tmp:
        print("compiling generated C + driver from scratch (cold build, for the compile time) ...", flush=True)
        cold = compiled.build(out_dir=Path(tmp) / "cold")
        a_s = d_s = i_s = math.inf
        a_all: list[float] = []
        for round_ in range(1, 4):  # alternate (a), (a') and (d) so machine load hits them alike
            print(f"(a) C loop, (a') with a covariance interval, (d) bare generated functions in a C loop: "
                  f"round {round_}/3 ...", flush=True)
            best, times, a_fin = time_c_loop(lib, recs, x0, P0, params, repeats)
            a_s, a_all = min(a_s, best), a_all + times
            best, _, i_fin = time_c_loop(lib, recs, x0, P0, params, repeats, COV_INTERVAL_S)
            i_s = min(i_s, best)
            best, d_x = time_bare_c(lib.build, recs, x0, P0, params, gate, repeats, Path(tmp))
            d_s = min(d_s, best)
    print("(b) CasADi Functions called from Python ...", flush=True)
    b_s, b_all, b_fin = time_casadi(recs, x0, P0, params, gate, kinds, py_repeats)
    print("(c) plain NumPy filter ...", flush=True)
    suffix_of = {v: k for k, v in kinds.items()}
    c_s, c_all, c_fin = time_numpy(recs, x0, P0, params, gate, suffix_of, py_repeats)

    per = {k: v / n_imu * 1e6 for k, v in (("a", a_s), ("b", b_s), ("c", c_s), ("d", d_s))}
    pos = L.X_P_ENU_SLICE
    x_a = a_fin["x"]
    res = a_fin["res"]
    gen_files = sorted((compiled.GEN_DIR / "c").glob("*.[ch]")) + sorted(compiled.GEN_DIR.glob("*.h"))
    driver_files = sorted(compiled.CSRC_DIR.glob("*.[ch]"))
    result = {
        "scenario": {"seconds": seconds, "records": int(recs.size), "imu_steps": n_imu, "imu_hz": IMU_HZ,
                     "gps_hz": GPS_HZ, "pseudoranges_per_epoch": N_GPS, "starlink_hz": LEO_HZ,
                     "doppler_rates_per_epoch": N_LEO, "gate_nis": gate},
        "us_per_imu_step": {"a_c_loop": per["a"], "b_casadi_python": per["b"], "c_numpy": per["c"],
                            "d_bare_c_loop": per["d"], "a_cov_interval": i_s / n_imu * 1e6},
        "cov_interval": {"seconds": COV_INTERVAL_S, "a_over_a_cov_interval": a_s / i_s,
                         "pos_minus_a_m": float(np.max(np.abs(i_fin["x"][L.X_P_ENU_SLICE] - a_fin["x"][L.X_P_ENU_SLICE]))),
                         "sigma_pos_over_a": float(np.max(np.sqrt(np.diag(i_fin["P"])[L.DX_DP_SLICE]
                                                                  / np.diag(a_fin["P"])[L.DX_DP_SLICE])))},
        "ratios": {"b_over_a": per["b"] / per["a"], "c_over_a": per["c"] / per["a"], "a_over_d": per["a"] / per["d"]},
        "goals": {"a_50x_faster_than_b_and_c": per["b"] / per["a"] >= 50 and per["c"] / per["a"] >= 50,
                  "a_within_1p5x_of_d": per["a"] / per["d"] <= 1.5},
        "repeats": {"c_paths": repeats, "python_paths": py_repeats,
                    "a_median_us_per_imu_step": statistics.median(a_all) / n_imu * 1e6},
        "agreement_final_state": {
            "b_minus_a_pos_m": float(np.max(np.abs(b_fin["x"][pos] - x_a[pos]))),
            "c_minus_a_pos_m": float(np.max(np.abs(c_fin["x"][pos] - x_a[pos]))),
            "d_minus_a_pos_m": float(np.max(np.abs(d_x[pos] - x_a[pos]))),
            "a_pos_error_m": float(np.linalg.norm(x_a[pos] - x_true[pos])),
            "a_counts": {"applied": res.n_applied, "gated": res.n_gated, "failed": res.n_failed},
        },
        "code": {"generated": code_size(gen_files), "driver": code_size(driver_files),
                 "library_bytes": lib.build.library.stat().st_size},
        "build": {"compiler": cold.compiler, "compiler_version": cold.compiler_version, "cflags": cold.cflags,
                  "ldflags": cold.ldflags, "cold_compile_s": cold.compile_time_s},
    }
    _print_table(result)
    if sweep_trials:
        from bench_sweep import measure_sweep, print_sweep, rmse_agreement

        print(f"\npaper sweep, {sweep_trials} trials per point, against its C floor ...", flush=True)
        result["sweep"] = measure_sweep("paper", sweep_trials, figures=True, out=str(folder / "sweep"))
        print_sweep(result["sweep"])
        print(f"\nthe same sweep with the covariance propagated every {COV_INTERVAL_S:g} s ...", flush=True)
        result["sweep_cov_interval"] = measure_sweep("paper", sweep_trials, figures=True, out=str(folder / "sweep-cov-interval"),
                                                     sets=(f"filter.covariance_interval_s={COV_INTERVAL_S!r}",))
        print_sweep(result["sweep_cov_interval"])
        agree = rmse_agreement(str(folder / "sweep"), str(folder / "sweep-cov-interval"))
        result["sweep_cov_interval"]["rmse_agreement"] = agree
        s0, s1 = result["sweep"], result["sweep_cov_interval"]
        print(f"  against the per-sample sweep: CPU {s1['sweep_cpu_s'] / s0['sweep_cpu_s']:.2f}x, wall "
              f"{s1['sweep_wall_s'] / s0['sweep_wall_s']:.2f}x, C per IMU step {s1['c_us_per_imu_step']:.2f} vs "
              f"{s0['c_us_per_imu_step']:.2f} us; rmse.csv differs by at most {agree['max_rel_diff']:.1e} relative "
              f"({agree['column']}, {agree['mode']} at {agree['count']})")
    path = write_json(folder / "bench.json", result)
    print(f"wrote {path}")
    return result


def _print_table(r: dict) -> None:
    us, ra, ag = r["us_per_imu_step"], r["ratios"], r["agreement_final_state"]
    print()
    print("CPU time per IMU step (predict + its share of 0.8 pseudorange and 0.1 Doppler-rate updates):")
    print(f"  (a) C loop (leonav_run)           {us['a_c_loop']:10.2f} us   1.0x")
    print(f"  (b) CasADi Functions from Python  {us['b_casadi_python']:10.2f} us   {ra['b_over_a']:.0f}x slower than (a)")
    print(f"  (c) plain NumPy filter            {us['c_numpy']:10.2f} us   {ra['c_over_a']:.0f}x slower than (a)")
    print(f"  (d) bare generated C loop         {us['d_bare_c_loop']:10.2f} us   (a)/(d) = {ra['a_over_d']:.2f}")
    ci = r["cov_interval"]
    print(f"  (a') C loop, P every {ci['seconds']:g} s     {us['a_cov_interval']:10.2f} us   (a)/(a') = "
          f"{ci['a_over_a_cov_interval']:.2f}; final position vs (a) {ci['pos_minus_a_m']:.1e} m, position sigma "
          f"x{ci['sigma_pos_over_a']:.7f}")
    print(f"goals: (a) >= 50x faster than (b) and (c): {r['goals']['a_50x_faster_than_b_and_c']}; "
          f"(a) within 1.5x of (d): {r['goals']['a_within_1p5x_of_d']}")
    print(f"final position vs (a): (b) {ag['b_minus_a_pos_m']:.1e} m, (c) {ag['c_minus_a_pos_m']:.1e} m, "
          f"(d) {ag['d_minus_a_pos_m']:.1e} m; (a) error vs truth {ag['a_pos_error_m']:.2f} m, "
          f"updates applied/gated/failed {ag['a_counts']['applied']}/{ag['a_counts']['gated']}/{ag['a_counts']['failed']}")
    gen = r["code"]["generated"]
    total_b = sum(v["bytes"] for v in gen.values())
    total_l = sum(v["lines"] for v in gen.values())
    drv_l = sum(v["lines"] for v in r["code"]["driver"].values())
    b = r["build"]
    print(f"generated code: {total_b} bytes, {total_l} lines (gen/c/*.[ch], gen/*.h); driver {drv_l} lines; "
          f"library {r['code']['library_bytes']} bytes")
    print(f"cold compile: {b['cold_compile_s']:.1f} s with {b['compiler_version']} {' '.join(b['cflags'])}")


def main(argv: list[str] | None = None) -> int:
    """Same options as `leonav bench` (defined once, in leonav_runtime/commands/bench.py)."""
    from leonav_runtime.cli import main as cli_main

    return cli_main(["bench"] + list(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
