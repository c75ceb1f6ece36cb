"""Benchmark: a 5 x 5 study, 20 trials per cell, on the paper's real 20 s window.

sigma_alpha (0.1 .. 1.2 Hz/s) x alpha rate (1 .. 10 Hz), LEO(alpha)+IMU at 45 Starlink
satellites: 25 cells, each its own truth and satellite geometry (setup), 500 trials in all.
Goal (issue 14): <= 60 s wall on this machine's 2 cores.

    python benchmarks/bench_study.py [--workers N] [--trials N] [--out DIR]
"""
from __future__ import annotations

import argparse
import tempfile
import time

from leonav_runtime.study.run import run_study
from leonav_runtime.study.spec import study_from_dict

STUDY = {
    "name": "bench-5x5", "scenario": "paper", "modes": ["leo-alpha+imu"], "count": 45,
    "vary": [{"key": "starlink.doppler_rate_sigma_hz_s", "values": [0.1, 0.15, 0.3, 0.5, 1.2]},
             {"key": "starlink.rate_hz", "values": [1, 2, 4, 5, 10]}],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    out = args.out or tempfile.mkdtemp(prefix="bench-study-")
    t0 = time.perf_counter()
    study = study_from_dict({**STUDY, "trials": args.trials}, "<bench_study>", tempfile.gettempdir())
    t_load = time.perf_counter() - t0
    res = run_study(study, out, workers=args.workers, progress=False, figures=True)
    wall = time.perf_counter() - t0
    t = res.timing
    print(f"study 5 x 5 cells, {args.trials} trials per cell ({t['trials_run']} trials), 20 s window, N = 45")
    print(f"  wall, whole study (load + cells + files + figure): {wall:6.1f} s   (goal <= 60 s)")
    print(f"  load and validate the 25 cells:                    {t_load:6.1f} s")
    print(f"  CPU per trial, setup of its cell included:         {t['trial_cpu_ms']:6.1f} ms ({t['executor']})")
    print(f"  results: {out}")


if __name__ == "__main__":
    main()
