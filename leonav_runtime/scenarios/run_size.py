"""How much memory a scenario run needs, estimated and checked before anything is allocated.

A run holds, in every process that prepares the scenario (the caller's, plus each worker of a
pool): the truth on the IMU grid and every satellite's state at every measurement epoch (the
simulator propagates the whole constellation so that risers over a long run are seen); then
one trial per running worker (its records, the filter's outputs, the full covariance on the
10 Hz output grid); and in the caller, every trial's 9D error and NEES on that grid.

`memory_estimate` adds those up with per-item costs (COST, bytes) taken from the peak RSS
growth of the simulator and one trial on the built-in scenarios (static and manoeuvring,
20-360 s, 100-1000 Hz); tests/test_hostile_scenario.py checks the estimate stays above a
fresh measurement. `check_run_size` refuses a run above LEONAV_MAX_MEMORY_MB megabytes
(default: 80 % of the physical memory), naming what dominates and how to raise the limit.
"""
from __future__ import annotations

import os
from typing import Any, Callable

from leonav_runtime.common.errors import UserInputError

MEMORY_ENV = "LEONAV_MAX_MEMORY_MB"
DEFAULT_FRACTION = 0.8          # of the physical memory, when MEMORY_ENV is not set
FALLBACK_LIMIT_MB = 4096.0      # when the physical memory cannot be read
COST = {
    "process": 100e6,           # a Python process with NumPy, SciPy and the compiled filter
    "imu_sample": 550,          # truth: target and mechanized state, increments, specific force
    "maneuver_sample": 1600,    # + the fine position grid of a manoeuvring trajectory
    "satellite_epoch": 180,     # SGP4 state (r, v, a) and elevation/range of one satellite at one epoch
    "measurement_row": 1000,    # one noise-free measurement of the prepared series (aux, z, H)
    "record": 900,              # one record of a trial, with the filter's outputs for it
    "output_sample": 2800,      # the full covariance and errors of a trial at one 10 Hz output time
    "result_sample": 200,       # one trial's 9D error and NEES at one output time, kept for the summary
}
BUILTIN_SATELLITES = {"gps": 32, "starlink": 9700}  # the generated Walker sets hold 31 and 9,616
BYTES_PER_ELEMENT_SET = 140     # the smallest element-set text (a TLE without a name line)
OUTPUT_RATE_HZ = 10.0


def memory_estimate(scn: Any, mode_of: Callable, trials: int = 0, workers: int = 1) -> dict[str, float]:
    """Bytes a run of scenario `scn` needs at its peak: "setup" (per preparing process),
    "trial" (per running worker), "results" (`trials` per mode and count) and "total".
    `mode_of(name)`: the parsed mode (its constellations)."""
    used = {c for m in scn.modes for c in mode_of(m).constellations}
    n_imu = scn.duration_s * scn.imu_rate_hz
    gps_ep = scn.duration_s * scn.gps["rate_hz"] * ("gps" in used)
    sl_ep = scn.duration_s * scn.starlink["rate_hz"] * ("starlink" in used)
    sats = dict(BUILTIN_SATELLITES)
    if scn.element_source == "files":   # all the files' sets, propagated at the densest epochs used
        size = sum(os.path.getsize(f) for f in scn.element_files if os.path.isfile(f))
        sats["starlink" if sl_ep else "gps"] = size / BYTES_PER_ELEMENT_SET
    gps_rows, sl_rows = gps_ep * scn.gps["max_satellites"], sl_ep * max(scn.starlink["counts"])
    per_imu = COST["imu_sample"] + COST["maneuver_sample"] * (scn.trajectory["kind"] == "maneuvers")
    setup = (n_imu * per_imu + (gps_ep * sats["gps"] + sl_ep * sats["starlink"]) * COST["satellite_epoch"]
             + (gps_rows + 3 * sl_rows) * COST["measurement_row"])
    n_out = scn.duration_s * OUTPUT_RATE_HZ
    trial = (n_imu + gps_rows + 2 * sl_rows) * COST["record"] + n_out * COST["output_sample"]
    pairs = sum(len(scn.starlink["counts"]) if mode_of(m).uses("starlink") else 1 for m in scn.modes)
    results = trials * pairs * n_out * COST["result_sample"]
    processes = 1 + (workers if workers > 1 else 0)   # one worker runs in the caller's process
    total = processes * (COST["process"] + setup) + max(workers, 1) * trial + results
    return {"setup": setup, "trial": trial, "results": results, "total": total}


def memory_limit_mb() -> float:
    """LEONAV_MAX_MEMORY_MB, else 80 % of the physical memory (UserInputError if not a positive number)."""
    text = os.environ.get(MEMORY_ENV, "").strip()
    if not text:
        try:
            return DEFAULT_FRACTION * os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 1e6
        except (ValueError, OSError, AttributeError):
            return FALLBACK_LIMIT_MB
    try:
        limit = float(text)
    except ValueError:
        limit = float("nan")
    if not (limit > 0 and limit != float("inf")):
        raise UserInputError(f"{MEMORY_ENV}={text!r}: expected a positive number of megabytes")
    return limit


def check_run_size(scn: Any, mode_of: Callable, max_trials: float,
                   trials: int | None = None, workers: int | None = None) -> None:
    """Refuse `trials` outside 0..max_trials, `workers` < 1, and a run whose estimate is above
    the limit. trials None: the scenario's own; workers None: one per core."""
    trials = scn.trials if trials is None else trials
    if not 0 <= trials <= max_trials:
        raise UserInputError(f"--trials {trials}: expected 1..{max_trials:g} (the scenario schema's range)")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise UserInputError(f"--workers {workers}: expected an integer >= 1")
    est, limit = memory_estimate(scn, mode_of, trials, workers), memory_limit_mb()
    if est["total"] > limit * 1e6:
        mb = {k: v / 1e6 for k, v in est.items()}
        raise UserInputError(
            f"{scn.source}: this run needs about {mb['total']:,.0f} MB ({mb['setup']:,.0f} MB of satellite "
            f"states and truth per process, {mb['trial']:,.0f} MB per running trial, {mb['results']:,.0f} MB of "
            f"results for {trials} trials, {workers} worker(s)), more than the limit of {limit:,.0f} MB; shorten "
            f"[time] duration_s, lower the rates or counts, --trials or --workers, or raise {MEMORY_ENV}=<megabytes>")
