"""Time per IMU step of the generated filter on a whole real dataset run (issue 11).

    python benchmarks/bench_dataset.py                  # cpet_run3, 5 repeats
    python benchmarks/bench_dataset.py DATASET.toml --repeats 10 --json out.json

The records of each mode are built once (`dataset.runner.prepare`: files read, alignment,
records); each repeat times one `EKF.run` over the whole record stream (IMU intervals, fixes,
NHC/ZUPT pseudo-measurements; the C loop, results written back to NumPy) and divides by the
IMU intervals. Reported: min and median over the repeats; reading the files and building the
records are timed apart (once). `leonav run` also writes each run's `us_per_imu_step` into
metrics.json (one run, so noisier). The peer
figure is KF-GINS's 14.6 us per IMU step (9.5 us for its filter alone) on the same data as
quoted in issue 11 (its repository is not built here).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

KF_GINS_US = 14.6


def main(argv: list[str] | None = None) -> int:
    from leonav_runtime.dataset import load, load_spec, runner

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", nargs="?", default="cpet_run3")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    ds = load.load(load_spec(args.dataset))
    t_read = time.perf_counter() - t0
    prep = runner.prepare(ds)
    t_prep = time.perf_counter() - t0 - t_read
    out = {"dataset": args.dataset, "read_s": t_read, "prepare_s": t_prep, "kf_gins_us_per_imu_step": KF_GINS_US,
           "modes": {}}
    for mode in ds.spec["filter"]["modes"]:
        times = []
        for _ in range(args.repeats):
            recs, res, seconds, _ = runner.run_mode(prep, mode)
            times.append(seconds / res.n_imu * 1e6)
        out["modes"][mode] = {"records": int(recs.size), "imu_steps": int(res.n_imu),
                              "us_per_imu_step_min": float(np.min(times)),
                              "us_per_imu_step_median": float(np.median(times))}
        print(f"{mode:<20} {recs.size:7d} records, {res.n_imu} IMU steps: {np.min(times):6.2f} us/IMU step (min), "
              f"{np.median(times):6.2f} (median), CPU time  [KF-GINS {KF_GINS_US} us]")
    print(f"read files {t_read:.2f} s, alignment + records {t_prep:.2f} s (wall)")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
