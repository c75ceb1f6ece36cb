"""Benchmark: the full paper.toml sweep (100 trials per point, all six modes, 100 Hz IMU).

Prints, from one run: wall time (whole sweep and the trials alone), CPU time per trial, the
share of trial time spent in the C filter loop versus Python, and peak memory of the main
process and of the worker processes. Goal (issue 6): <= 60 s wall on 2 cores, < 2 GB.

    python benchmarks/bench_sweep.py [--workers N] [--trials N] [--out DIR]
"""
from __future__ import annotations

import argparse
import resource
import tempfile
import time

from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.sweep.run import run_sweep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--scenario", default="paper")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    scn = load_scenario(args.scenario)
    out = args.out or tempfile.mkdtemp(prefix="bench-sweep-")
    t0 = time.perf_counter()
    res = run_sweep(scn, out, trials=args.trials, workers=args.workers, progress=False, figures=False)
    wall = time.perf_counter() - t0
    t = res.timing
    self_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    n_points = len(scn.modes) * len(scn.starlink["counts"])
    print(f"sweep {scn.name}: {len(scn.modes)} modes x {len(scn.starlink['counts'])} counts = {n_points} points, "
          f"{args.trials} trials each ({t['trials_run']} trials run: count-independent modes run once)")
    print(f"  wall, whole sweep (setup + trials + files, no figures): {wall:7.1f} s   (goal <= 60 s)")
    print(f"  wall, trials only:                                      {t['trials_wall_s']:7.1f} s   ({t['executor']})")
    print(f"  setup (truth, satellites) in the main process:          {t['setup_s']:7.1f} s")
    print(f"  CPU per trial:                                          {t['trial_cpu_ms']:7.1f} ms")
    print(f"  share in the C filter loop / in Python:                 {100 * t['c_share']:5.0f} % / "
          f"{100 * (1 - t['c_share']):.0f} %")
    print(f"  peak RSS: main {self_mb:.0f} MB, largest worker {child_mb:.0f} MB   (goal < 2 GB)")


if __name__ == "__main__":
    main()
