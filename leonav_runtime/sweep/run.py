"""The Monte Carlo sweep of a scenario: every mode x Starlink count, trials on an executor.

`run_sweep(scn, out_dir, ...)` returns a `SweepResult` and, given `out_dir`, writes the
results folder (`sweep_report.py`: metrics.json, rmse.csv, rmse_vs_time.csv, findings.csv,
figures, report.html). The summaries hold SI values; their `pcrb` keys are sqrt(PCRB).

Modes that use no Starlink observable (GPS+IMU) do not depend on the count: they run once
and are reported at every count.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import resource
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from leonav_runtime.simulation import trial_block
from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.sweep.executors import make_executor, map_in_order
from leonav_runtime.gen import state_layout as L
from leonav_runtime.sweep.paper_values import PAPER_FINDINGS
from leonav_runtime.scenarios.load import Scenario, mode_of

log = logging.getLogger("leonav.sweep")

BLOCK_TRIALS = 20  # trials per executor task: enough work per task to hide its set-up and scheduling



def _cpu_clocks() -> tuple[float, float]:
    """CPU seconds (user + system) of this process and of its waited-for children (pool workers)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time(), children.ru_utime + children.ru_stime


def sweep_timing(blocks: list, steps: int, t_start: float, t_setup: float, cpu_setup: float, t_trials: float,
                 cpu_start: tuple[float, float], cpu_trials: tuple[float, float], remote: bool) -> dict:
    """metrics.json's timing: CPU from CPU clocks, wall times named *wall*.

    The floor is trials x IMU steps x the C loop's CPU per IMU step, all measured in this run
    (the worker threads' clocks around each C loop). total_cpu_s: this process (set-up, tasks,
    summaries) plus its workers (the pool's processes, reaped when it closes; on Dask the
    workers' clocks around their blocks), before the results folder is written.
    """
    n_trials = sum(len(b.results) for b in blocks)
    c_time = sum(b.c_seconds for b in blocks)
    cpu_blocks = sum(b.seconds for b in blocks)
    process = cpu_trials[0] - cpu_start[0]
    workers = cpu_blocks if remote else cpu_trials[1] - cpu_start[1]
    c_step = c_time / max(n_trials * steps, 1)
    floor = n_trials * steps * c_step
    total = process + workers
    return {
        "wall_s": time.perf_counter() - t_start, "setup_wall_s": t_setup, "setup_cpu_s": cpu_setup,
        "trials_wall_s": t_trials, "trials_run": n_trials, "imu_steps_per_trial": steps,
        "trial_cpu_ms": 1e3 * cpu_blocks / max(n_trials, 1),
        "trial_wall_ms": 1e3 * sum(b.wall_seconds for b in blocks) / max(n_trials, 1),
        "c_us_per_imu_step": 1e6 * c_step, "floor_cpu_s": floor,
        "process_cpu_s": process, "workers_cpu_s": workers, "total_cpu_s": total,
        "cpu_over_floor": total / floor if floor > 0 else math.nan,
        "c_share": c_time / cpu_blocks if cpu_blocks > 0 else math.nan,
        "clock": "*_cpu_*, c_us_per_imu_step, c_share: CPU clocks (trials: the worker thread's; process and "
                 "workers: process_time and getrusage of the pool's processes); *_wall_*: wall time",
    }


def uses_starlink(mode: str) -> bool:
    return mode_of(mode).uses("starlink")


@dataclass
class SweepResult:
    summaries: dict[tuple[str, int], dict]
    findings: list[dict]
    timing: dict
    trajectories: dict[str, np.ndarray]
    truth_p_enu: np.ndarray
    t_eval: np.ndarray
    scenario: Scenario
    notes: list[str]


def _tasks(scn: Scenario, trials: int) -> list[tuple]:
    counts = scn.starlink["counts"]
    tasks = []
    for mode in scn.modes:
        for count in (counts if uses_starlink(mode) else counts[:1]):
            for start in range(0, trials, BLOCK_TRIALS):
                idx = list(range(start, min(trials, start + BLOCK_TRIALS)))
                tasks.append((scn.raw, scn.source, str(Path(scn.source).parent), mode, count, idx))
    return tasks


def build_templates(scn: Scenario, setup, nav, tasks: list[tuple]) -> int:
    """Build the block template of every (mode, count) of `tasks` on `setup` (trial_block.py), before
    the workers start; returns how many. It builds none (0) with a realism switch active: its trials
    take the road one by one, and a template (61 MB and ~0.35 s of CPU per point in passive-phase-static)
    would be made for nothing."""
    if not trial_block.uses_template(scn):
        return 0
    points = list(dict.fromkeys((t[3], t[4]) for t in tasks))
    for mode, count in points:
        trial_block.template(setup, nav, mode, count)
    return len(points)


def outage_end_error(summary: dict, end_s: float, t_eval: np.ndarray) -> float:
    """Position RMSE (m) on the output grid at the last time before GPS returns at `end_s`;
    an outage reaching the run's end covers its last epoch (`simulate.selected_rows`)."""
    i = t_eval.size - 1 if end_s >= t_eval[-1] - 1e-9 else int(np.searchsorted(t_eval, end_s - 1e-9)) - 1
    return float(summary["position"]["rmse_t"][max(i, 0)])


def check_findings(scn: Scenario, summaries: dict[tuple[str, int], dict], t_eval: np.ndarray) -> list[dict]:
    """The paper's simulation findings (kind "paper"; only for a scenario that declares
    `[monte_carlo] paper_findings = true`, as the paper's own do) and this scenario's own checks
    (kind "scenario", e.g. the GPS outage), evaluated on our results.

    Each entry: finding, kind, holds, detail (text), and `values`: per (mode, count) the
    position RMSE averaged over time and at the final epoch (m); the paper's band if any.
    """
    counts = scn.starlink["counts"]
    lo_c, hi_c = counts[0], counts[-1]

    def pos(mode, count):
        s = summaries.get((mode, count))
        return None if s is None else s["position"]["rmse"]

    def values(pairs):
        return [{"mode": m, "count": c, "position_rmse_time_avg_m": summaries[(m, c)]["position"]["rmse"],
                 "position_rmse_final_m": summaries[(m, c)]["position"]["final_rmse"]} for m, c in pairs]

    def both(m, c):
        p = summaries[(m, c)]["position"]
        return f"{p['rmse']:.2f} m (final epoch {p['final_rmse']:.2f} m)"

    out = []

    paper = bool(scn.raw.get("monte_carlo", {}).get("paper_findings", False))

    def add(name, ok, detail, pairs=(), band=None, kind="paper"):
        if ok is not None and (kind != "paper" or paper):
            out.append({"finding": name, "kind": kind, "holds": bool(ok), "detail": detail,
                        "values": values(pairs), "paper_band_m": list(band) if band else None})

    leo = [m for m in scn.modes if uses_starlink(m)]
    if leo and len(counts) > 1:
        falls = {m: (pos(m, lo_c), pos(m, hi_c)) for m in leo}
        add("position RMSE falls as Starlink satellites are added",
            all(b < a for a, b in falls.values()),
            {m: f"{a:.2f} m at {lo_c} -> {b:.2f} m at {hi_c}" for m, (a, b) in falls.items()},
            [(m, c) for m in leo for c in (lo_c, hi_c)])
    gps_modes = [m for m in scn.modes if mode_of(m).uses("gps")]
    static_paper_like = not scn.gps["outages"]  # the paper's 1-2 m / 6-9 m are for its static run
    if gps_modes and static_paper_like:
        vals = {m: pos(m, hi_c) for m in gps_modes}
        lo, hi = PAPER_FINDINGS["gps_aided_position_m"]
        add(f"GPS-aided modes reach {lo:g}-{hi:g} m", all(v <= hi for v in vals.values()),
            {m: both(m, hi_c) for m in gps_modes}, [(m, hi_c) for m in gps_modes], (lo, hi))
    if "leo-alpha+imu" in scn.modes and static_paper_like:
        lo, hi = PAPER_FINDINGS["leo_alpha_position_m"]
        v = pos("leo-alpha+imu", hi_c)
        add(f"LEO(alpha)+IMU lands in {lo:g}-{hi:g} m", lo <= v <= hi,
            f"{both('leo-alpha+imu', hi_c)} at {hi_c} satellites", [("leo-alpha+imu", hi_c)], (lo, hi))
    if {"leo-ofdm+imu", "leo-alpha+imu"} <= set(scn.modes):
        pairs = {c: (pos("leo-ofdm+imu", c), pos("leo-alpha+imu", c)) for c in counts}
        add("range-type OFDM beats alpha", all(o < a for o, a in pairs.values()),
            {c: f"OFDM {o:.2f} m vs alpha {a:.2f} m" for c, (o, a) in pairs.items()},
            [(m, c) for c in counts for m in ("leo-ofdm+imu", "leo-alpha+imu")])
    if "leo-alpha+ofdm+imu" in scn.modes:
        others = [m for m in ("leo-alpha+imu", "leo-ofdm+imu") if m in scn.modes]
        best = pos("leo-alpha+ofdm+imu", hi_c)
        add("alpha+OFDM is the best LEO mode (paper's modes)",
            all(best <= pos(m, hi_c) for m in others),
            {m: f"{pos(m, hi_c):.2f} m" for m in others + ["leo-alpha+ofdm+imu"]},
            [(m, hi_c) for m in others + ["leo-alpha+ofdm+imu"]])
    for a, b in scn.gps["outages"]:
        end = {m: outage_end_error(summaries[(m, hi_c)], b, t_eval) for m in gps_modes}
        if "gps+imu" in end and "gps+leo-alpha+imu" in end:
            add(f"GPS+LEO(alpha)+IMU stays bounded through the GPS outage {a:g}-{b:g} s while GPS+IMU drifts",
                end["gps+leo-alpha+imu"] < end["gps+imu"],
                {m: f"{e:.2f} m at the outage end" for m, e in end.items()}, [(m, hi_c) for m in gps_modes],
                kind="scenario")
    # Judged on the bound (no sampling noise): how much the attitude PCRB moves across modes.
    att = {m: summaries[(m, hi_c if uses_starlink(m) else counts[0])]["attitude"]["pcrb"] for m in scn.modes}
    spread = (max(att.values()) - min(att.values())) / max(att.values())
    add("attitude is mostly IMU-driven (attitude sqrt(PCRB) within 35 % across modes)", spread < 0.35,
        {m: f"{math.degrees(v):.3f} deg" for m, v in att.items()})
    return out


def run_sweep(scn: Scenario, out_dir: Path | None = None, *, trials: int | None = None, workers: int | None = None,
              dask_address: str | None = None, progress: bool = True, figures: bool = True) -> SweepResult:
    """Run every (mode, count) of `scn`; write the results folder (see module doc) unless
    `out_dir` is None."""
    trials = trials or scn.trials
    if trials != scn.trials:
        scn = dataclasses.replace(scn, trials=trials)
    t_start, cpu_start = time.perf_counter(), _cpu_clocks()
    setup, nav = mc.setup_for(scn)  # validates visibility before any work is sent out
    t_setup, cpu_setup = time.perf_counter() - t_start, time.process_time() - cpu_start[0]
    tasks = _tasks(scn, trials)
    build_templates(scn, setup, nav, tasks)   # forked workers inherit them
    log.info("sweep %s: %d modes x %d counts, %d trials each, %d tasks; setup %.2f s", scn.name, len(scn.modes),
             len(scn.starlink["counts"]), trials, len(tasks), t_setup)
    bar = None
    if progress:
        from leonav_runtime.common.progress import progress as make_progress

        bar = make_progress(len(tasks), f"sweep {scn.name}", "task", smoothing=0.05)
    t0 = time.perf_counter()
    with make_executor(workers, dask_address) as ex:
        blocks = map_in_order(ex, mc.run_block, tasks, on_done=(bar.update if bar else None))
    t_trials = time.perf_counter() - t0
    cpu_trials = _cpu_clocks()
    if bar:
        bar.close()

    by_key: dict[tuple[str, int], list] = {}
    bounds: dict[tuple[str, int], dict] = {}
    for task, block in zip(tasks, blocks):
        key = (task[3], task[4])
        by_key.setdefault(key, []).extend(block.results)
        if block.pcrb is not None:
            bounds[key] = block.pcrb
    summaries = {}
    for (mode, count), results in by_key.items():
        s = mc.summarize(results, bounds[(mode, count)])
        if uses_starlink(mode):
            summaries[(mode, count)] = s
        else:
            for c in scn.starlink["counts"]:
                summaries[(mode, c)] = s
    timing = sweep_timing(blocks, setup.u_true.shape[0], t_start, t_setup, cpu_setup, t_trials, cpu_start,
                          cpu_trials, dask_address is not None)
    timing["executor"] = f"dask {dask_address}" if dask_address else f"process pool ({workers or 'all cores'})"
    trajectories = {}
    for task, block in zip(tasks, blocks):
        if block.p_est_trial0 is not None and (task[3] not in trajectories or task[4] == scn.starlink["counts"][-1]):
            trajectories[task[3]] = block.p_est_trial0
    k = mc.eval_grid(setup.t_imu, scn.imu_rate_hz)
    result = SweepResult(summaries, check_findings(scn, summaries, setup.t_imu[k]), timing, trajectories,
                         setup.x_true[k, L.X_P_ENU_SLICE], setup.t_imu[k], scn, list(setup.notes))
    if out_dir is not None:
        from leonav_runtime.sweep.report import write_results

        write_results(scn, out_dir, result, figures=figures)
    return result


def summary_table(scn: Scenario, res: SweepResult) -> str:
    """The console summary (kept here for callers; see sweep_report.summary_table)."""
    from leonav_runtime.sweep.report import summary_table as table

    return table(res)
