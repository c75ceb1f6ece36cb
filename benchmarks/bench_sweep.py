"""Benchmark: the paper sweep's CPU against its C floor, measured side by side in one run.

The floor is what the sweep cannot go below with this filter: trials x IMU steps x the C
loop's CPU per IMU step, all three measured in this run's own trials (each worker thread's
CPU clock around each C loop). Against it: the sweep's total CPU (this process, set-up
included, plus the pool's worker processes, from CPU clocks) and, separately, the CPU of
writing the results folder. Wall times are named as wall times; the machine's load average
is printed before and after, since other jobs slow the C loop and Python alike. Goals
(issue 25, quiet machine): total CPU <= 1.25x the floor; wall <= 10 s on 2 cores. The last lines
give the run's wall budget (`wall_budget`): the wall even with no Python in the trials, and the C
loop per IMU step that 10 s would need with the rest as measured.

    python benchmarks/bench_sweep.py [--workers N] [--trials N] [--scenario NAME] [--figures] [--out DIR]

`leonav bench` prints the same figures after the filter's (`--sweep-trials`, 0 to skip).
"""
from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time

from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.scenarios.overrides import apply_overrides
from leonav_runtime.sweep.run import run_sweep


def _cpu() -> tuple[float, float]:
    """CPU seconds of this process and of its reaped children (the pool's workers)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time(), children.ru_utime + children.ru_stime


def measure_sweep(scenario: str = "paper", trials: int | None = None, workers: int | None = None,
                  figures: bool = False, out: str | None = None, sets: tuple[str, ...] = ()) -> dict:
    """Run the sweep once and return its timing figures (CPU s, wall s, ratios; see module doc);
    sets: `section.key=value` overrides, as `leonav sweep --set`."""
    scn, _ = apply_overrides(load_scenario(scenario), sets=sets)
    out = out or tempfile.mkdtemp(prefix="bench-sweep-")
    load_before, cores = os.getloadavg(), os.cpu_count() or 1
    w0, c0 = time.perf_counter(), _cpu()
    res = run_sweep(scn, None, trials=trials, workers=workers, progress=False, figures=False)
    w1, c1 = time.perf_counter(), _cpu()
    from leonav_runtime.sweep.report import write_results

    write_results(res.scenario, out, res, figures=figures)
    w2, c2 = time.perf_counter(), _cpu()
    t = res.timing
    trials_cpu = 1e-3 * t["trial_cpu_ms"] * t["trials_run"]
    processes = min(workers or cores, cores)
    # the trials ran in worker processes only with more than one (--workers 1 runs them inline)
    in_workers = processes > 1 and t["workers_cpu_s"]
    r = {
        "scenario": scn.name, "sets": list(sets), "out": out, "trials_per_point": trials or scn.trials, "trials_run": t["trials_run"],
        "imu_steps_per_trial": t["imu_steps_per_trial"], "c_us_per_imu_step": t["c_us_per_imu_step"],
        "floor_cpu_s": t["floor_cpu_s"], "sweep_cpu_s": t["total_cpu_s"], "cpu_over_floor": t["cpu_over_floor"],
        "measured_cpu_s": (c1[0] - c0[0]) + (c1[1] - c0[1]),
        "trials_other_cpu_s": trials_cpu - t["floor_cpu_s"],
        "workers_outside_trials_cpu_s": t["workers_cpu_s"] - trials_cpu if in_workers else 0.0,
        "main_process_cpu_s": t["process_cpu_s"], "setup_cpu_s": t["setup_cpu_s"],
        "results_cpu_s": (c2[0] - c1[0]) + (c2[1] - c1[1]), "figures": figures,
        "sweep_wall_s": w1 - w0, "trials_wall_s": t["trials_wall_s"], "results_wall_s": w2 - w1,
        "executor": t["executor"], "cores": cores, "processes": processes,
        "load_average_before": load_before[0], "load_average_after": os.getloadavg()[0],
        "peak_rss_main_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "peak_rss_worker_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    }
    r["wall_budget"] = wall_budget(r)
    return r


WALL_GOAL_S = 10.0   # issue 25: the paper sweep on 2 cores, quiet machine


def wall_budget(r: dict, goal_s: float = WALL_GOAL_S) -> dict:
    """What the measured parts allow of the wall time, the pool's `r["processes"]` sharing the trials perfectly.

    serial_s: the wall outside the pool (set-up before the trials, the results folder);
    bound_s: serial_s + the C floor spread over the processes, the wall if every bit of Python in
    the trials cost nothing; c_us_for_goal: the C loop's CPU per IMU step at which the sweep,
    with everything else as measured, would take goal_s (<= 0: no C loop is fast enough);
    cpu_over_floor_at_goal: the sweep's CPU over its C floor at that C loop, the rest as measured.
    """
    serial_s = (r["sweep_wall_s"] - r["trials_wall_s"]) + r["results_wall_s"]
    other_parallel_s = r["trials_other_cpu_s"] + r["workers_outside_trials_cpu_s"]
    steps = r["trials_run"] * r["imu_steps_per_trial"]
    floor_for_goal_s = (goal_s - serial_s) * r["processes"] - other_parallel_s
    outside_floor_s = r["sweep_cpu_s"] - r["floor_cpu_s"]
    return {"goal_s": goal_s, "processes": r["processes"], "serial_s": serial_s,
            "bound_s": serial_s + r["floor_cpu_s"] / r["processes"],
            "c_us_for_goal": 1e6 * floor_for_goal_s / steps,
            "cpu_over_floor_at_goal": (1.0 + outside_floor_s / floor_for_goal_s) if floor_for_goal_s > 0 else None}


def print_sweep(r: dict) -> None:
    """The figures of `measure_sweep`, floor and sweep side by side."""
    sets = f" with {', '.join(r['sets'])}" if r.get("sets") else ""
    print(f"sweep {r['scenario']}{sets}: {r['trials_run']} trials ({r['trials_per_point']} per point; count-independent "
          f"modes run once), {r['imu_steps_per_trial']} IMU steps each, {r['executor']} on {r['cores']} cores, "
          f"load average {r['load_average_before']:.1f} -> {r['load_average_after']:.1f}")
    print(f"  C floor: {r['trials_run']} trials x {r['imu_steps_per_trial']} steps x {r['c_us_per_imu_step']:.2f} us "
          f"(C loop CPU per IMU step, these trials) = {r['floor_cpu_s']:7.2f} s CPU")
    print(f"  sweep total CPU (process + workers):              {r['sweep_cpu_s']:7.2f} s = "
          f"{r['cpu_over_floor']:.2f}x the floor   (goal <= 1.25x; measured around the call: "
          f"{r['measured_cpu_s']:.2f} s)")
    print(f"    trials outside the C loop (draws, records, errors, PCRB): {r['trials_other_cpu_s']:6.2f} s; "
          f"workers outside trials: {r['workers_outside_trials_cpu_s']:.2f} s; main process "
          f"{r['main_process_cpu_s']:.2f} s (set-up {r['setup_cpu_s']:.2f} s)")
    print(f"  results folder ({'with' if r['figures'] else 'without'} figures):          "
          f"{r['results_cpu_s']:7.2f} s CPU, {r['results_wall_s']:.1f} s wall")
    print(f"  wall: set-up and trials {r['sweep_wall_s']:.1f} s (trials {r['trials_wall_s']:.1f} s) + results folder "
          f"{r['results_wall_s']:.1f} s = {r['sweep_wall_s'] + r['results_wall_s']:.1f} s   (goal <= {WALL_GOAL_S:g} s on 2 cores, "
          f"quiet machine; `leonav sweep` also starts Python and imports, ~1 s)")
    b = r["wall_budget"]
    print(f"  wall budget with {b['processes']} processes: serial parts {b['serial_s']:.1f} s + the C floor over them "
          f"= {b['bound_s']:.1f} s even with no Python in the trials; {b['goal_s']:g} s would need the C loop at "
          f"{b['c_us_for_goal']:.2f} us per IMU step with the rest as measured (now {r['c_us_per_imu_step']:.2f} us)"
          + (f", and the CPU would then be {b['cpu_over_floor_at_goal']:.1f}x its floor"
             if b["cpu_over_floor_at_goal"] else ""))
    print(f"  peak RSS main {r['peak_rss_main_mb']:.0f} MB, largest worker {r['peak_rss_worker_mb']:.0f} MB")


def rmse_agreement(a_dir: str, b_dir: str) -> dict:
    """Largest relative difference between two sweeps' rmse.csv, over every RMSE and bound column."""
    import csv

    def rows(d):
        with open(os.path.join(d, "rmse.csv"), newline="") as fh:
            return list(csv.DictReader(fh))

    a, b = rows(a_dir), rows(b_dir)
    if [(r["mode"], r["count"]) for r in a] != [(r["mode"], r["count"]) for r in b]:
        raise ValueError(f"{a_dir} and {b_dir}: the sweeps' points differ")
    worst = {"max_rel_diff": 0.0, "column": "", "mode": "", "count": ""}
    for ra, rb in zip(a, b):
        for col in ra:
            if col in ("mode", "count", "trials"):
                continue
            x, y = float(ra[col]), float(rb[col])
            d = abs(y - x) / abs(x) if x else abs(y)
            if d > worst["max_rel_diff"]:
                worst = {"max_rel_diff": d, "column": col, "mode": ra["mode"], "count": ra["count"]}
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    ap.add_argument("--trials", type=int, default=None, help="trials per point (default: the scenario's)")
    ap.add_argument("--scenario", default="paper")
    ap.add_argument("--figures", action="store_true", help="also draw the figures when writing the results")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    print_sweep(measure_sweep(args.scenario, args.trials, args.workers, args.figures, args.out))


if __name__ == "__main__":
    main()
